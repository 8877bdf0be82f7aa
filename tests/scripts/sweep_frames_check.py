"""Independent reader check of a sweep's frames with meshio.

usage: sweep_frames_check.py SWEEP_DIR

Reads frames.pvd; every DataSet must name an existing VTU that meshio reads, with the point
arrays `displacement` and `first_harmonic_amplitude` (3 components, one tuple per point,
finite) and the cell array `frequency_hz` (1 component, one value). Timesteps must increase.
Prints, per frame, "sweep_frames: frame TIMESTEP FREQUENCY_HZ MAX_AMPLITUDE_X" (the largest
first-harmonic x amplitude over the nodes). For every points/*/amplitudes.vtu prints
"sweep_frames: point FOLDER MAX_AMPLITUDE_X" from its harmonic_1_cos and harmonic_1_sin, for
the caller to compare a point's full output with its frame.
"""
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

import meshio
import numpy as np


def fail(msg):
    print(f"sweep_frames: FAIL: {msg}", file=sys.stderr)
    sys.exit(1)


def main():
    out = Path(sys.argv[1])
    root = ET.parse(out / "frames.pvd").getroot()
    last = -1.0
    for ds in root.iter("DataSet"):
        t = float(ds.attrib["timestep"])
        if t <= last:
            fail(f"timestep {t} after {last}")
        last = t
        path = out / ds.attrib["file"]
        if not path.exists():
            fail(f"frames.pvd references missing {path}")
        m = meshio.read(path)
        n = len(m.points)
        for name in ["displacement", "first_harmonic_amplitude"]:
            a = np.asarray(m.point_data.get(name, np.zeros((0, 0))))
            if a.shape != (n, 3) or not np.all(np.isfinite(a)):
                fail(f"{path.name}: point array {name} has shape {a.shape}, expected ({n}, 3)")
        f = np.concatenate([np.asarray(b) for b in m.cell_data["frequency_hz"]])
        if f.min() != f.max():
            fail(f"{path.name}: frequency_hz not constant")
        amp = float(np.asarray(m.point_data["first_harmonic_amplitude"])[:, 0].max())
        print(f"sweep_frames: frame {t!r} {float(f[0])!r} {amp!r}")
    for path in sorted(out.glob("points/*/amplitudes.vtu")):
        d = meshio.read(path).point_data
        c, s = np.asarray(d["harmonic_1_cos"]), np.asarray(d["harmonic_1_sin"])
        amp = float(np.sqrt(c[:, 0] ** 2 + s[:, 0] ** 2).max())
        print(f"sweep_frames: point {path.parent.name} {amp!r}")


main()
