"""Where init's shape tests and its placement limit stand on the shared meshes.

    python benchmarks/tuning/bench_shapes.py [--placements]

Prints, for `musclewrap.model.femur_landmarks`: the head and knee of OpenSim's two right
femurs (in the femur's frame: the hip is its origin), how far the LHDL femur's head moves
from its own when the mesh is turned and moved anyhow, and why half a femur is refused;
then, for every mesh of ../shared/data/vhf, its sphere fit's rms over its radius and its
`cap_spread` (what `defaults.init_cap_rms` and the cap test of init weigh), and which
meshes the femur detector would pass. ``--placements``: also, per init case, the median
muscle's nearest-quarter distance over its extent in the placement init takes (what
`defaults.init_far` weighs), from ``init_scene`` on the shared folders.
"""

from __future__ import annotations

import argparse
import tempfile
from pathlib import Path

import numpy as np

DATA = Path(__file__).resolve().parents[2].parent / "shared" / "data"


def femurs() -> None:
    from musclewrap.errors import SceneError
    from musclewrap.mesh import read_mesh
    from musclewrap.model import femur_landmarks

    for name in ("femur_r.vtp", "r_femur.vtp"):
        V, F = read_mesh(DATA / "opensim/Geometry" / name)[:2]
        head, knee, said = femur_landmarks(V, F, name)
        print(f"{name}: head {1e3 * np.linalg.norm(head):.2f} mm from the hip, knee at "
              f"{np.round(1e3 * knee, 1)} mm; {said}")  # fmt: skip
    V, F = read_mesh(DATA / "lhdl/bones/LHDL_R_Femur.vtk")[:2]
    head, knee, said = femur_landmarks(V, F, "LHDL")
    rng = np.random.default_rng(7)
    moved = []
    for _ in range(10):
        Q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
        Q *= np.sign(np.linalg.det(Q))
        shift = rng.normal(scale=500.0, size=3)
        h2 = femur_landmarks(V @ Q.T + shift, F, "LHDL")[0]
        moved.append(np.linalg.norm(h2 - (head @ Q.T + shift)))
    print(f"LHDL femur: {said}; turned and moved 10 times, its head within "
          f"{max(moved):.3f} mm of its own")  # fmt: skip
    t = (V - V.mean(0)) @ np.linalg.eigh(np.cov(V.T))[1][:, -1]
    for half, which in ((t < np.median(t), "one half"), (t > np.median(t), "the other half")):
        keep = np.flatnonzero(half)
        sub = np.full(len(V), -1)
        sub[keep] = np.arange(len(keep))
        Fk = sub[F][(sub[F] >= 0).all(axis=1)]
        try:
            femur_landmarks(V[keep], Fk, which)
            print(f"LHDL femur, {which}: NOT refused")
        except SceneError as e:
            print(f"LHDL femur, {e}")


def vhf_shapes() -> None:
    from musclewrap.errors import SceneError
    from musclewrap.mesh import read_mesh, tidy_mesh
    from musclewrap.model import cap_spread, femur_landmarks, fit_sphere

    print("VHF meshes: sphere fit rms / radius, cap spread, the femur detector")
    for f in sorted((DATA / "vhf").glob("*.stl")):
        V, F, _ = tidy_mesh(*read_mesh(f))
        c, r, rms = fit_sphere(V)
        try:
            femur_landmarks(V, F, f.name)
            femur = "passes"
        except SceneError:
            femur = "-"
        print(f"  {f.stem[4:]:<44} {rms / r:6.3f} {cap_spread(V, c):6.2f}  {femur}")


def placements() -> None:
    import musclewrap.subject._init as si
    from musclewrap.errors import SceneError

    seen: list[tuple[float, float]] = []
    refuse = si._refuse_far

    def kept(meshes, candidates, fits_by, k, unit):  # noqa: ANN001, ANN202
        ratio = [f.near / f.extent for f in fits_by[k].values()]
        seen.append((float(np.median(ratio)), float(np.max(ratio))))
        return refuse(meshes, candidates, fits_by, k, unit)

    si._refuse_far = kept
    gait = DATA / "opensim/models/subject01_simbody.osim"
    walk = DATA / "opensim/motions/subject01_walk1_ik.mot"
    with tempfile.TemporaryDirectory() as tmp:
        unnamed = Path(tmp) / "unnamed"
        unnamed.mkdir()
        for i, f in enumerate(sorted((DATA / "vhf").glob("*.stl"))):
            (unnamed / (f"scan_{i:02d}.stl" if "Cartilage" in f.name else f.name)).symlink_to(f)
        lhdl = Path(tmp) / "lhdl"
        lhdl.mkdir()
        for m in ("GluteusMaximus", "GluteusMedius", "Iliacus", "Psoas"):
            (lhdl / f"LHDL_R_{m}.vtk").symlink_to(DATA / f"lhdl/muscles/LHDL_R_{m}.vtk")
        cases = [
            ("VHF folder on gait2392", gait, DATA / "vhf", walk),
            ("VHF folder on Rajagopal 2016", DATA / "opensim/models/Rajagopal2016.osim",
             DATA / "vhf", walk),
            ("LHDL muscles on their model", DATA / "lhdl/model/LHDL_hip_r.osim", lhdl, None),
            ("VHF folder, cartilages unnamed, on gait2392", gait, unnamed, walk),
        ]  # fmt: skip
        print("placements: the median muscle's nearest quarter over its extent (and the most)")
        for label, osim, folder, motion in cases:
            seen.clear()
            try:
                si.init_scene(osim, folder, Path(tmp) / "s.toml", motion=motion)
                verdict = "written"
            except SceneError:
                verdict = "refused"
            med, most = seen[-1]
            print(f"  {label}: {med:.4f} (most {most:.3f}), {verdict}")


def main() -> None:
    p = argparse.ArgumentParser()
    p.add_argument("--placements", action="store_true")
    a = p.parse_args()
    femurs()
    vhf_shapes()
    if a.placements:
        placements()


if __name__ == "__main__":
    main()
