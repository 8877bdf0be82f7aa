"""Independent reader check of an hbcontact output directory with meshio.

usage: meshio_check.py OUTPUT_DIR [--expect EXPECT.json] [--probe NAME=I,J,... ...]

Every *.vtu must read, with points and cells; every array named in EXPECT.json
({"point": {name: components}, "cell": {name: components}}) must be present in every
frame_*.vtu with that many components, one tuple per point/cell, and finite. Every *.pvd
must reference existing files (each read by meshio) with strictly increasing times.
Each --probe prints, for every frame of the first .pvd in time order, the mean displacement of
the listed points (0-based point indices, = mesh node indices) as
"meshio_check: probe NAME TIME UX UY", for the caller to compare with its own records.
"""
import json
import math
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

import meshio
import numpy as np


def fail(msg):
    print(f"meshio_check: FAIL: {msg}", file=sys.stderr)
    sys.exit(1)


def components(a):
    return 1 if a.ndim == 1 else a.shape[1]


def main():
    args = sys.argv[1:]
    if not args:
        fail("usage: meshio_check.py OUTPUT_DIR [--expect EXPECT.json]")
    out = Path(args[0])
    expect = {"point": {}, "cell": {}}
    if "--expect" in args:
        expect = json.loads(Path(args[args.index("--expect") + 1]).read_text())
    probes = []
    for i, a in enumerate(args):
        if a == "--probe":
            name, ids = args[i + 1].split("=", 1)
            probes.append((name, [int(v) for v in ids.split(",")]))
    vtus = sorted(out.glob("*.vtu"))
    if not vtus:
        fail(f"no .vtu files in {out}")
    for path in vtus:
        m = meshio.read(path)
        if len(m.points) == 0 or sum(len(c.data) for c in m.cells) == 0:
            fail(f"{path.name}: no points or no cells")
        if not path.name.startswith("frame_"):
            continue
        ncells = sum(len(c.data) for c in m.cells)
        for name, ncomp in expect.get("point", {}).items():
            if name not in m.point_data:
                fail(f"{path.name}: point array {name} missing (have {sorted(m.point_data)})")
            a = np.asarray(m.point_data[name])
            if a.shape[0] != len(m.points) or components(a) != ncomp:
                fail(f"{path.name}: point array {name} has shape {a.shape}, expected ({len(m.points)}, {ncomp})")
            if not np.all(np.isfinite(a)):
                fail(f"{path.name}: point array {name} is not finite")
        for name, ncomp in expect.get("cell", {}).items():
            if name not in m.cell_data:
                fail(f"{path.name}: cell array {name} missing (have {sorted(m.cell_data)})")
            a = np.concatenate([np.asarray(b) for b in m.cell_data[name]])
            if a.shape[0] != ncells or components(a) != ncomp:
                fail(f"{path.name}: cell array {name} has shape {a.shape}, expected ({ncells}, {ncomp})")
            if not np.all(np.isfinite(a)):
                fail(f"{path.name}: cell array {name} is not finite")
    pvds = sorted(out.glob("*.pvd"))
    if not pvds:
        fail(f"no .pvd in {out}")
    for pvd in pvds:
        root = ET.parse(pvd).getroot()
        times = []
        for ds in root.iter("DataSet"):
            f = out / ds.attrib["file"]
            if not f.exists():
                fail(f"{pvd.name} references missing {f.name}")
            m = meshio.read(f)
            times.append(float(ds.attrib["timestep"]))
            if pvd == pvds[0]:
                for name, ids in probes:
                    u = np.asarray(m.point_data["displacement"])[ids]
                    ux, uy = u[:, 0].mean(), u[:, 1].mean()
                    print(f"meshio_check: probe {name} {times[-1]!r} {float(ux)!r} {float(uy)!r}")
        if not times or any(b <= a for a, b in zip(times, times[1:])) or not all(math.isfinite(t) for t in times):
            fail(f"{pvd.name}: times not strictly increasing: {times[:5]}...")
        print(f"meshio_check: {pvd.name}: {len(times)} steps, t in [{times[0]:.6g}, {times[-1]:.6g}]")
    print(f"meshio_check: OK: {len(vtus)} vtu files in {out}")


if __name__ == "__main__":
    main()
