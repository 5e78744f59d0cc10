"""What PyVista (VTK) and libigl do with the bad meshes musclewrap refuses or repairs.

    python tools/other_tools.py

Each case is a capsule (volume known) damaged one way; the table shows what each library
reports when asked for the enclosed volume (and, where it has one, its own manifold or
closed check). Nothing here is musclewrap code; it documents the field's behaviour for
RELIABILITY.md.
"""

from __future__ import annotations

import warnings

import numpy as np


def cases() -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """A clean capsule and copies damaged one way each."""
    from musclewrap.synthetic import capsule

    V, F = capsule(n_around=24, cap_rings=6, segments=20)
    out = {"clean capsule": (V, F)}
    out["hole (one face removed)"] = (V, F[1:])
    out["inward orientation"] = (V, F[:, ::-1])
    out["second belly (two components)"] = (
        np.vstack([V, V + [60.0, 0, 0]]),
        np.vstack([F, F + len(V)]),
    )
    Vn = V.copy()
    Vn[5, 0] = np.nan
    out["one NaN coordinate"] = (Vn, F)
    c = V.mean(axis=0)
    Vf = V.copy()
    band = (np.abs(V[:, 2] - c[2]) < 15) & (V[:, 0] > c[0] + 10)
    Vf[band, 0] -= 2 * (V[band, 0] - c[0]) + 10
    out["fold (passes through itself)"] = (Vf, F)
    # non-manifold edge: a fin triangle sharing an edge with the surface
    a, b = F[0, 0], F[0, 1]
    Vx = np.vstack([V, V[a] + 10 * (V[a] - c) / np.linalg.norm(V[a] - c)])
    out["non-manifold edge (a fin)"] = (Vx, np.vstack([F, [[a, b, len(V)]]]))
    # ten faces oriented against their neighbours
    Fi = F.copy()
    Fi[5:15] = Fi[5:15, ::-1]
    out["10 faces flipped"] = (V, Fi)
    # a second capsule standing on the first, sharing its pole vertex
    top, bottom = int(np.argmax(V[:, 2])), int(np.argmin(V[:, 2]))
    F2 = F + len(V)
    F2[F2 == len(V) + bottom] = top
    out["non-manifold vertex (two touch)"] = (
        np.vstack([V, V - V[bottom] + V[top]]),
        np.vstack([F, F2]),
    )
    return out


def main() -> None:
    """Print what each library reports for each case."""
    import igl
    import pyvista as pv
    from vtkmodules.vtkCommonCore import vtkLogger

    vtkLogger.SetStderrVerbosity(vtkLogger.VERBOSITY_OFF)

    from musclewrap.mesh import volume

    warnings.simplefilter("ignore")
    ref = volume(*cases()["clean capsule"])
    print(f"{'case':34s} {'PyVista volume':>16s} {'PyVista manifold':>17s} {'libigl w(mean)':>14s}")
    for name, (V, F) in cases().items():
        mesh = pv.PolyData(V, np.hstack([np.full((len(F), 1), 3), F]).ravel())
        try:
            pv_vol = f"{mesh.volume / ref:.4f} x"
        except Exception as exc:  # noqa: BLE001 - recording what happens is the point
            pv_vol = type(exc).__name__
        try:
            manifold = str(bool(mesh.is_manifold))
        except Exception as exc:  # noqa: BLE001
            manifold = type(exc).__name__
        try:
            # libigl has no surface volume; its generalized winding number is its inside test
            w = igl.fast_winding_number(V, F, np.nanmean(V, axis=0)[None])
            igl_w = f"{float(w[0]):.2f}"
        except Exception as exc:  # noqa: BLE001
            igl_w = type(exc).__name__
        print(f"{name:34s} {pv_vol:>16s} {manifold:>17s} {igl_w:>14s}")
    print(f"(volumes relative to the clean capsule, {ref:.1f}; w: libigl's winding number at")
    print(" the vertex mean, 1 inside a closed outward surface)")


def intersection_tests() -> None:
    """False alarms of two self-intersection tests on moved copies of a clean capsule."""
    from pymeshfix import _meshfix
    from scipy.spatial.transform import Rotation

    from musclewrap.mesh import self_intersecting_faces
    from musclewrap.synthetic import capsule

    V, F = capsule(n_around=32, cap_rings=8, segments=30)
    flagged = {"MeshFix (PyMeshFix)": 0, "musclewrap": 0}
    n = 0
    for scale in (1e-3, 0.0183, 1.0, 54.6, 1e3):
        for seed in range(6):
            R = Rotation.random(random_state=seed).as_matrix()
            W = scale * V @ R.T + np.random.default_rng(seed).uniform(-500, 500, 3)
            t = _meshfix.PyTMesh()
            t.set_quiet(True)
            t.load_array(np.ascontiguousarray(W), np.ascontiguousarray(F, dtype=np.int32))
            flagged["MeshFix (PyMeshFix)"] += len(t.select_intersecting_triangles()) > 0
            flagged["musclewrap"] += self_intersecting_faces(W, F) > 0
            n += 1
    for name, k in flagged.items():
        print(f"self-intersections reported on a clean capsule moved {n} ways: {name} {k} of {n}")


if __name__ == "__main__":
    main()
    intersection_tests()
