"""Where init's shape tests and its placement limit stand on the shared meshes.

    python benchmarks/tuning/bench_shapes.py [--placements] [--places]

Prints, for `musclewrap.model.femur_landmarks`: the head and knee of OpenSim's two right
femurs (in the femur's frame: the hip is its origin), how far the LHDL femur's head moves
from its own when the mesh is turned and moved anyhow, and why half a femur is refused;
then, for every mesh of ../shared/data/vhf, its sphere fit's rms over its radius and its
`cap_spread` (what `defaults.init_cap_rms` and the cap test of init weigh), and which
meshes the femur detector would pass. ``--placements``: also, per init case, the median
muscle's nearest-quarter distance over its extent in the placement init takes (what
`defaults.init_far` weighs), from ``init_scene`` on the shared folders. ``--places``:
the VHF folder with all but three muscles named Segment_N.stl, on gait2392 and Rajagopal
2016: what init takes each mesh for by its shape and place, the margin of each muscle's
assignment (`defaults.init_place_tie`), and how far each closed mesh lies from the
model's nearest bone (`defaults.init_bone_place`).
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
    from musclewrap.subject import survey

    print(
        "VHF meshes: sphere fit rms / radius, cap spread, the femur detector, mean "
        "thickness over width and over the median named muscle's (init's shell test)"
    )
    thin = {
        mi.path.name: f"{mi.thickness / mi.width:.3f} {mi.thickness / mi.muscles_thickness:.2f}"
        for mi in survey(DATA / "vhf")
    }
    for f in sorted((DATA / "vhf").glob("*.stl")):
        V, F, _ = tidy_mesh(*read_mesh(f))
        c, r, rms = fit_sphere(V)
        try:
            femur_landmarks(V, F, f.name)
            femur = "passes"
        except SceneError:
            femur = "-"
        print(
            f"  {f.stem[4:]:<44} {rms / r:6.3f} {cap_spread(V, c):6.2f}  {femur:<6}  {thin[f.name]}"
        )
    print("LHDL meshes: mean thickness over width")
    for sub in ("muscles", "bones"):
        for mi in survey(DATA / "lhdl" / sub):
            print(f"  {mi.path.name:<44} {mi.thickness / mi.width:.3f}")


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
            if "FemurDistal" not in f.name:  # nothing for the knee
                name = f"scan_{i:02d}.stl" if "Cartilage" in f.name else f.name
                (unnamed / name).symlink_to(f)
        lhdl = Path(tmp) / "lhdl"
        lhdl.mkdir()
        for m in ("GluteusMaximus", "GluteusMedius", "Iliacus", "Psoas"):
            (lhdl / f"LHDL_R_{m}.vtk").symlink_to(DATA / f"lhdl/muscles/LHDL_R_{m}.vtk")
        cases = [
            ("VHF folder on gait2392", gait, DATA / "vhf", walk),
            ("VHF folder on Rajagopal 2016", DATA / "opensim/models/Rajagopal2016.osim",
             DATA / "vhf", walk),
            ("LHDL muscles on their model", DATA / "lhdl/model/LHDL_hip_r.osim", lhdl, None),
            ("VHF folder, hip cartilages unnamed, no knee's, on gait2392", gait, unnamed, walk),
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


def places() -> None:
    """What init takes meshes no name places for, on the VHF folder as Segment_N.stl."""
    import re

    import musclewrap.subject._init as si

    seen: dict = {}
    bones_by_place, muscles_by_place = si._bones_by_place, si._muscles_by_place

    def bones(model, meshes, best, s, side):  # noqa: ANN001, ANN202
        seen["bones"] = (model, meshes, best, s, side)
        return bones_by_place(model, meshes, best, s, side)

    def muscles(model, meshes, *rest):  # noqa: ANN001, ANN002, ANN202
        out = muscles_by_place(model, meshes, *rest)
        seen["muscles"] = meshes
        return out

    si._bones_by_place, si._muscles_by_place = bones, muscles
    keep = ("GluteusMaximus", "RectusFemoris", "AdductorMagnus")
    for label, osim in (
        ("gait2392", DATA / "opensim/models/subject01_simbody.osim"),
        ("Rajagopal 2016", DATA / "opensim/models/Rajagopal2016.osim"),
    ):
        with tempfile.TemporaryDirectory() as tmp:
            folder = Path(tmp) / "segments"
            folder.mkdir()
            truth = {}
            for i, f in enumerate(sorted((DATA / "vhf").glob("*.stl"))):
                name = f.name if any(k in f.name for k in keep) else f"Segment_{i + 1}.stl"
                (folder / name).symlink_to(f)
                truth[name] = f.stem.split("_")[3] if f.stem.count("_") > 3 else f.stem
            si.init_scene(osim, folder, Path(tmp) / "s.toml")
            print(f"VHF folder as Segment_N.stl but {', '.join(keep)}, on {label}:")
            print("  file, what it is, what init took it for, the next best assignment's margin")
            for mi in seen["muscles"]:
                if not mi.path.name.startswith("Segment_"):
                    continue
                took = mi.match.name if mi.match is not None else "-"
                how = mi.match.how if mi.match is not None else mi.why
                margin = re.search(r"costs ([0-9.e-]+) (thicknesses|of its)", how)
                print(
                    f"  {mi.path.name:<15} {truth[mi.path.name]:<22} {took:<22} "
                    f"{margin.group(1) if margin else '-'}"
                )
            model, meshes, best, s, side = seen["bones"]
            points = si._model_bone_points(model, best, s, side)
            print("  every closed mesh against the model's bones: the nearest body, its score")
            for mi in meshes:
                if mi.closed and points:
                    sc = si._bone_scores(mi, points)
                    b = min(sc, key=sc.__getitem__)
                    print(f"    {truth.get(mi.path.name, mi.stem):<22} {b:<10} {sc[b]:.3f}")
    si._bones_by_place, si._muscles_by_place = bones_by_place, muscles_by_place


def main() -> None:
    p = argparse.ArgumentParser()
    p.add_argument("--placements", action="store_true")
    p.add_argument("--places", action="store_true")
    a = p.parse_args()
    femurs()
    vhf_shapes()
    if a.placements:
        placements()
    if a.places:
        places()


if __name__ == "__main__":
    main()
