"""Independent reader check of an hbcontact output directory with meshio.

usage: meshio_check.py OUTPUT_DIR [--expect EXPECT.json] [--probe NAME=I,J,... ...]
                        [--contact TOLERANCE]

Every *.vtu must read, with points and cells; every array named in EXPECT.json
({"point": {name: components}, "cell": {name: components}}) must be present in every
frame_*.vtu with that many components, one tuple per point/cell, and finite. Every *.pvd
must reference existing files (each read by meshio) with strictly increasing times.
Each --probe prints, for every frame of the first .pvd in time order, the mean displacement of
the listed points (0-based point indices, = mesh node indices) as
"meshio_check: probe NAME TIME UX UY", for the caller to compare with its own records.
Probes are read from series.pvd (else the first .pvd).

--contact TOLERANCE (contact scenes): in every frame, contact_force and contact_pressure are
>= 0; contact_status is 1 exactly where the force is > 0 and contact_opening <= TOLERANCE,
0 elsewhere on the contact nodes, -1 off them (where every contact array is 0). Prints
"meshio_check: contact CLOSED NODE_FRAMES MIN_SERIES MAX_CLOSED_OPENING MIN_OPEN_OPENING" and
obstacle.vtu's points as "meshio_check: obstacle_point X Y"; obstacle.vtu must hold line cells
only and obstacle.pvd must reference it (a scene without a rigid obstacle has neither).
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


def check_contact(out, tolerance):
    closed, total, min_series = 0, 0, math.inf
    max_closed_opening, min_open_opening = -math.inf, math.inf
    for path in sorted(out.glob("frame_*.vtu")):
        d = meshio.read(path).point_data
        for name in ["contact_opening", "contact_force", "contact_pressure", "contact_status",
                     "contact_force_series"]:
            if name not in d:
                fail(f"{path.name}: point array {name} missing (have {sorted(d)})")
        opening, force = np.asarray(d["contact_opening"]), np.asarray(d["contact_force"])
        pressure, status = np.asarray(d["contact_pressure"]), np.asarray(d["contact_status"])
        series = np.asarray(d["contact_force_series"])
        if np.any(force < 0) or np.any(pressure < 0):
            fail(f"{path.name}: negative contact force {force.min()} or pressure {pressure.min()}")
        node = status >= 0
        off = ~node
        if np.any(force[off] != 0) or np.any(opening[off] != 0) or np.any(series[off] != 0):
            fail(f"{path.name}: contact arrays nonzero off the contact nodes")
        should = node & (force > 0) & (opening <= tolerance)
        if np.any((status == 1) != should) or np.any(~np.isin(status, [-1, 0, 1])):
            bad = np.nonzero((status == 1) != should)[0][:5]
            fail(f"{path.name}: status {status[bad]} at points {bad}: force {force[bad]}, opening {opening[bad]}, tolerance {tolerance}")
        closed += int(np.sum(status == 1))
        total += int(np.sum(node))
        min_series = min(min_series, float(series[node].min()))
        if np.any(status == 1):
            max_closed_opening = max(max_closed_opening, float(opening[status == 1].max()))
        if np.any(status == 0):
            min_open_opening = min(min_open_opening, float(opening[status == 0].min()))
    print(f"meshio_check: contact {closed} {total} {min_series!r} {max_closed_opening!r} {min_open_opening!r}")
    if not (out / "obstacle.vtu").exists():
        return  # contact with another body: no rigid obstacle to draw
    m = meshio.read(out / "obstacle.vtu")
    if not m.cells or any(c.type != "line" for c in m.cells):
        fail(f"obstacle.vtu: cells {[c.type for c in m.cells]}, expected line cells only")
    root = ET.parse(out / "obstacle.pvd").getroot()
    if [ds.attrib["file"] for ds in root.iter("DataSet")] != ["obstacle.vtu"]:
        fail("obstacle.pvd does not reference obstacle.vtu alone")
    for x, y, _ in m.points:
        print(f"meshio_check: obstacle_point {float(x)!r} {float(y)!r}")


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
    tolerance = None
    if "--contact" in args:
        tolerance = float(args[args.index("--contact") + 1])
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
    if tolerance is not None:
        check_contact(out, tolerance)
    pvds = sorted(out.glob("*.pvd"), key=lambda p: (p.name != "series.pvd", p.name))
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
