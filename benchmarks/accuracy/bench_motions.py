"""Contact on motions nobody recorded: extreme hip motions and seeded random smooth ones.

    python benchmarks/accuracy/bench_motions.py [SCENE] [--random 5] [--seconds 3] [--check-every 2]
        [--line-window W] [--anatomical]

Drives SCENE's model (default: examples/lhdl_walk.toml) with

- ``extreme+`` / ``extreme-``: the hip flexed from the rest pose to 120 deg (30 past the LHDL
  model's range) and back over 3 s while it adducts and rotates by 20 deg both ways (the
  adduction's swing in one or the other direction first);
- ``random1`` ... ``randomK``: `musclewrap.scene.random_motion` over the model's ranges of the
  scene's coordinates (seeds 1..K, 20 frames per second); with ``--anatomical`` over those
  ranges cut to a normal adult's range of motion where the coordinate is the hip's or the
  knee's (`ANATOMICAL`: a model's declared range may be far wider, gait2392's hip -120..120
  deg each way),

runs each with contact (and, with ``--no-collisions-too``, without), and checks the written
meshes independently (`musclewrap.run.verify_run`) on every ``--check-every``-th
frame; prints per motion and muscle the deepest muscle vertex in a bone, bone vertex in the
muscle and vertex in another muscle, the largest shape change (with how many frames exceed 0.5) and the skeleton fit (the
per-frame mean distance of the action line's samples from where the surface puts them), over all
frames and over the frames where the action line itself stays out of the bones.
"""

from __future__ import annotations

import argparse
import dataclasses
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]


#: A normal adult's range of motion (degrees; the American Academy of Orthopaedic Surgeons'
#: values: hip flexion 120, extension 30, adduction 30, abduction 45, internal and external
#: rotation 45, knee flexion 135), in gait2392's signs (adduction and internal rotation
#: positive). The knee's sign is the model's: flexion negative where its range is.
ANATOMICAL = {
    "hip_flexion": (-30.0, 120.0),
    "hip_adduction": (-45.0, 30.0),
    "hip_rotation": (-45.0, 45.0),
    "knee_angle": (0.0, 135.0),
}


def anatomical(name: str, lo: float, hi: float) -> tuple[float, float]:
    """The range ``lo..hi`` (degrees) of coordinate ``name`` cut to `ANATOMICAL` where it is one."""
    base = name.removesuffix("_r").removesuffix("_l")
    if base not in ANATOMICAL:
        return lo, hi
    a, b = ANATOMICAL[base]
    if base == "knee_angle" and -lo > hi:  # the model flexes its knee negative
        a, b = -b, -a
    if max(lo, a) > min(hi, b):
        raise ValueError(
            f"{name}: the model's range {lo:g}..{hi:g} misses the anatomical {a:g}..{b:g}"
        )
    return max(lo, a), min(hi, b)


def _extreme(sign: int) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    t = np.linspace(0.0, 3.0, 61)
    s = np.sin(np.pi * t / 3.0) ** 2  # 0 -> 1 -> 0
    return t, {
        "hip_flexion_r": 1.576 + (120.0 - 1.576) * s,
        "hip_adduction_r": -4.727 + 24.727 * s * np.sin(sign * 2 * np.pi * t / 1.5),
        "hip_rotation_r": -5.29 + 25.29 * s * np.cos(2 * np.pi * t / 2.0),
    }


def main() -> None:
    p = argparse.ArgumentParser()
    p.add_argument("scene", nargs="?", default=str(ROOT / "examples" / "lhdl_walk.toml"))
    p.add_argument("--random", type=int, default=5)
    p.add_argument("--seconds", type=float, default=3.0)
    p.add_argument("--check-every", type=int, default=2)
    p.add_argument("--no-extreme", action="store_true")
    p.add_argument("--no-collisions-too", action="store_true")
    p.add_argument("--line-window", type=float, help="the scene's line_window")
    p.add_argument(
        "--anatomical", action="store_true", help="the random motions in a normal range of motion"
    )
    a = p.parse_args()

    from musclewrap.run import verify_run
    from musclewrap.scene import (
        OpenSimModel,
        load_scene,
        random_motion,
        read_motion,
        run_scene,
        write_motion,
    )

    scene = load_scene(a.scene)
    if a.line_window is not None:
        scene = dataclasses.replace(scene, line_window=a.line_window)
    model = OpenSimModel(scene.osim)
    coords = list(scene.coordinates or ())
    ranges = {}
    for c in coords:
        lo, hi = model.coordinate_range(c)
        ranges[c] = (np.degrees(lo), np.degrees(hi)) if model.is_rotational(c) else (lo, hi)
        if a.anatomical and model.is_rotational(c):
            ranges[c] = anatomical(c, *ranges[c])
    if a.anatomical:
        # a model that names its hip or knee otherwise keeps its own ranges: said, not hidden
        kept = [c for c in coords if c.removesuffix("_r").removesuffix("_l") not in ANATOMICAL]
        if kept:
            print(f"--anatomical: no normal range known for {', '.join(kept)}: the model's kept")
    motions = []
    if not a.no_extreme:
        motions += [("extreme+", _extreme(1)), ("extreme-", _extreme(-1))]
    for seed in range(1, a.random + 1):
        motions.append(
            (f"random{seed}", random_motion(ranges, seconds=a.seconds, rate=20.0, seed=seed))
        )
    cache = Path(tempfile.mkdtemp()) / "cache"
    print(
        f"{a.scene}: {len(motions)} motions, run and checked independently every {a.check_every} frames"
    )
    for name, (t, cols) in motions:
        with tempfile.TemporaryDirectory() as tmp:
            mot = write_motion(Path(tmp) / f"{name}.mot", t, cols)
            sc = dataclasses.replace(scene, motions=(mot,), paper_frames=0)
            n = read_motion(mot).n_frames
            frames = f"0:{n}:{a.check_every}"
            peak = ", ".join(f"{c} {cols[c].min():.0f}..{cols[c].max():.0f}" for c in coords)
            print(f"  {name} ({peak})")
            for collisions in (True, False) if a.no_collisions_too else (True,):
                out = Path(tmp) / ("on" if collisions else "off")
                s = run_scene(
                    sc, out, frames=frames, workers=2, cache_dir=cache, progress=None,
                    render=False, collisions=collisions,
                )  # fmt: skip
                checked = verify_run(sc, out, frames)
                for m in sc.muscles:
                    q = [r for r in s.rows if r["muscle"] == m.name]
                    w = [r for r in checked if r["muscle"] == m.name]
                    shape = [r["shape_change_max"] for r in q]
                    fit_all = max(r["skeleton_fit_mean"] for r in q)
                    fit = [r["skeleton_fit_mean"] for r in q if r["line_inside_depth_max"] <= 0.5]
                    fit_out = (
                        f"{max(fit):.2f} where the line is out of the bones"
                        if fit
                        else "no frame with the line out of the bones"
                    )
                    print(
                        f"    {'' if collisions else '--no-collisions '}{m.name:<16} muscle vertex"
                        f" in bone <= {max(r['muscle_in_bone'] for r in w):6.2f}, bone vertex in"
                        f" muscle <= {max(r['bone_in_muscle'] for r in w):6.2f}, in another"
                        f" muscle <= {max(r['muscle_in_muscle'] for r in w):6.2f}, shape change"
                        f" <= {max(shape):.2f} ({sum(x > 0.5 for x in shape)}/{len(q)} over"
                        f" 0.5), fit <= {fit_all:.2f} ({fit_out}), unconverged"
                        f" {sum(not r['converged'] for r in q)}"
                    )


if __name__ == "__main__":
    main()
