"""How far a run's fibres spread across their muscle, along them, beside the muscle's width.

    musclewrap run examples/lhdl_hip_sweeps.toml -o OUT --frames 0:1 --no-gif
    python benchmarks/accuracy/bench_fibre_spread.py OUT/hip_flexion [--frame 0] [--every 2]

Reads one frame's written fibres (``<muscle>/<muscle>_fibres_<frame>.vtp``) and surface
(``<muscle>/<muscle>_<frame>.vtp``) of every muscle in a run's output folder. At every
``--every``-th point of the fibres (their points lie evenly along each fibre), the standard
deviations of the fibres' positions across their mean direction there (the two largest, mm),
beside those of the muscle's vertices within 2 mm of the plane through the fibres' mean
point: where the fibres gather in a part of the section, and where the muscle itself narrows
(a tendon every fibre must pass through). Issue 48: the fibres' moment arms can spread no
wider than the fibres do where they cross the joint.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np


def _fibres(path: Path) -> np.ndarray:
    """The poly-lines of a fibre file as one (fibres, points, 3) array."""
    import pyvista as pv

    mesh = pv.read(path)
    cells, out, i = mesh.lines, [], 0
    while i < len(cells):
        n = int(cells[i])
        out.append(mesh.points[cells[i + 1 : i + 1 + n]])
        i += n + 1
    return np.asarray(out, dtype=np.float64)


def _across(X: np.ndarray, c: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Standard deviations (largest two, descending) of the points ``X`` across ``t`` at ``c``."""
    Y = (X - c) - np.outer((X - c) @ t, t)
    return np.sqrt(np.maximum(np.linalg.eigvalsh(np.cov(Y.T))[::-1][:2], 0.0))


def main() -> None:
    from musclewrap.mesh import read_mesh

    p = argparse.ArgumentParser()
    p.add_argument("folder", type=Path, help="a run's output folder (one motion's)")
    p.add_argument("--frame", type=int, default=0)
    p.add_argument("--every", type=int, default=2)
    a = p.parse_args()
    files = sorted(a.folder.glob(f"*/*_fibres_{a.frame:04d}.vtp"))
    if not files:
        raise SystemExit(f"{a.folder}: no fibre files of frame {a.frame}")
    for f in files:
        name = f.parent.name
        P = _fibres(f)
        V, _ = read_mesh(f.parent / f"{name}_{a.frame:04d}.vtp")
        n, k, _ = P.shape
        print(f"{name}: {n} fibres of {k} points, frame {a.frame} (sd across them, mm)")
        for j in range(0, k, a.every):
            c = P[:, j].mean(axis=0)
            t = (P[:, min(j + 1, k - 1)] - P[:, max(j - 1, 0)]).mean(axis=0)
            t /= np.linalg.norm(t)
            fib = _across(P[:, j], c, t)
            near = V[np.abs((V - c) @ t) < 2.0]
            sec = _across(near, c, t) if len(near) > 10 else np.array([np.nan, np.nan])
            print(
                f"  point {j:2d}: fibres {fib[0]:5.1f} x {fib[1]:4.1f}; "
                f"the muscle there {sec[0]:5.1f} x {sec[1]:4.1f}"
            )


if __name__ == "__main__":
    main()
