r"""The rounds that take one pose's muscles out of each other, round by round.

    python benchmarks/profiling/trace_rounds.py [SCENE] --frames 716,724
        [--motion MOT [--negate COORDINATE ...]] [--set NAME=VALUE ...]

Solves each frame as a run solves it (`musclewrap.run.LiveScene`, one process), and
prints per round of `musclewrap.solver.meet` the deepest overlap (in its muscle's mean
edges, what the rounds stop on: ``defaults.muscle_overlap_depth``) and the three muscles
deepest in another or with another deepest in them; then the pose's time, the five
deepest exact overlaps after the finish (mm) and the three largest shape changes.
``--set``: a default of `musclewrap.constants.defaults` changed in this process first
(``contact_cage_reach=3``).
``--motion``, ``--negate``: as `bench_contact.py`'s. For the stacked leg at the deep squat's
bottom (issue 46, item 3):

    python benchmarks/profiling/trace_rounds.py examples/gait2392_leg.toml --frames 716 \
        --motion ../shared/data/opensim/motions/opencap_squat_videoAndMocap.mot \
        --negate knee_angle_r
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def main() -> None:
    p = argparse.ArgumentParser()
    p.add_argument("scene", nargs="?", default=str(ROOT / "examples" / "gait2392_leg.toml"))
    p.add_argument("--frames", required=True, help="frame positions, comma-separated")
    p.add_argument("--motion", default=None)
    p.add_argument("--negate", nargs="*", default=[])
    p.add_argument("--set", nargs="*", default=[], metavar="NAME=VALUE")
    a = p.parse_args()
    from musclewrap.constants import defaults
    from musclewrap.run import LiveScene
    from musclewrap.scene import load_scene
    from musclewrap.solver import _together

    for item in a.set:
        name, value = item.split("=")
        kind = type(getattr(defaults, name))
        object.__setattr__(defaults, name, value == "1" if kind is bool else kind(float(value)))
    scene = load_scene(a.scene)
    rounds: list[tuple[int, float, list[tuple[str, float]]]] = []
    deepest = _together._Rounds._deepest

    def traced(self):  # noqa: ANN001, ANN202
        got = deepest(self)
        worst = sorted(got[3].items(), key=lambda kv: -kv[1])[:3]
        rounds.append((self.count, got[0], worst))
        return got

    _together._Rounds._deepest = traced
    with tempfile.TemporaryDirectory() as tmp:
        if a.motion is not None:
            sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # the shared helpers
            from _common import negated_motion

            path = negated_motion(a.motion, a.negate, Path(tmp))
            scene = dataclasses.replace(scene, motions=(path,), gif=False)
        live = LiveScene(scene, check=False)
        for frame in (int(x) for x in a.frames.split(",")):
            rounds.clear()
            t0 = time.perf_counter()
            res = live.solve(frame=frame)
            print(f"frame {frame}: {time.perf_counter() - t0:.1f} s")
            for count, depth, worst in rounds:
                who = ", ".join(f"{n} {v:.2f}" for n, v in worst)
                print(f"  round {count:2d}: deepest {depth:7.3f} mean edges ({who})")
            left = sorted(((r["muscle_overlap_max"], n) for n, r in res.rows.items()), reverse=True)
            print("  after the finish, in another muscle (mm): "
                  + ", ".join(f"{n} {d:.3f}" for d, n in left[:5]))  # fmt: skip
            solvers, results, _ = res.solved
            shape = sorted(
                ((float(solvers[n].muscle.shape_change(r.V).max()), n) for n, r in results.items()),
                reverse=True,
            )
            print("  shape change: " + ", ".join(f"{n} {d:.3f}" for d, n in shape[:3]))


if __name__ == "__main__":
    main()
