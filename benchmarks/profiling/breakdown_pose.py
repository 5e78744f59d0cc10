"""Where the time of one pose goes (default solver, capsule ``bend``).

Run: ``python benchmarks/profiling/breakdown_pose.py [--repeats N] [--mesh PATH]`` (with ``--mesh``, a
real muscle in the ``bend`` scenario on its principal axis instead of the capsule).

Wraps the solver's building blocks with timers, runs ``deform`` N times and prints the
milliseconds per pose of each block (median over the poses) next to the median time per
pose and the median float64 ``W @ X`` (numpy, 3 columns) timed in phases alternating with
it (`musclewrap._bench.interleaved_ms`). The timers add a little overhead of their own.
"""

import argparse
import time

import numpy as np

import musclewrap.solver._deformer as solver
from musclewrap import Muscle
from musclewrap._bench import interleaved_ms
from musclewrap.synthetic import capsule, capsule_scenario

BLOCKS = {
    "W @ [x, u] (rows_dot)": (solver, "rows_dot"),
    "fine cubic": (solver, "volume_cubic_pair"),
    "final volume": (solver, "volume"),
    "positions": (solver, "combine_pair"),
    "targets and rotations": (solver.Deformer, "_targets"),
    "proxy iterations": (solver, "plain_iterations"),
    "small products": (solver, "mat3"),
    "fine cubic root": (solver, "cubic_root_near"),
    "skeleton fit": (solver.Deformer, "_skeleton_fit"),
    "energy and samples": (solver.Deformer, "_energy_and_samples"),
}


def main(repeats: int, mesh: str | None = None) -> None:
    if mesh:
        from musclewrap.synthetic import principal_axis_scenario

        muscle = Muscle.from_file(mesh)
        rest, cur = principal_axis_scenario(muscle.V, "bend")
    else:
        muscle = Muscle.from_mesh(*capsule())
        rest, cur = capsule_scenario("bend")
    d = muscle.bind(rest)
    spent = dict.fromkeys(BLOCKS, 0.0)
    for label, (owner, name) in BLOCKS.items():
        fn = getattr(owner, name)

        def timed(*args, _fn=fn, _label=label, **kwargs):
            t = time.perf_counter()
            out = _fn(*args, **kwargs)
            spent[_label] += time.perf_counter() - t
            return out

        setattr(owner, name, timed)
    per_pose = {label: [] for label in BLOCKS}

    def pose() -> None:
        for label in spent:
            spent[label] = 0.0
        d.deform(cur)
        for label, s in spent.items():
            per_pose[label].append(s)

    for _ in range(5):
        pose()
    X = np.random.default_rng(0).random((muscle.W.shape[1], 3))
    ms, wx = interleaved_ms(pose, lambda: muscle.W @ X, repeats)
    print(f"per pose {ms:.2f} ms (median), W@X {wx:.2f} ms (median), {repeats} repeats")
    med = {label: float(np.median(v[-repeats:])) * 1e3 for label, v in per_pose.items()}
    for label, v in sorted(med.items(), key=lambda kv: -kv[1]):
        print(f"  {label:24s} {v:6.2f} ms (median)")
    print(f"  {'sum of the medians':24s} {sum(med.values()):6.2f} ms")


if __name__ == "__main__":
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--repeats", type=int, default=41)
    p.add_argument("--mesh", help="a muscle mesh file instead of the capsule")
    a = p.parse_args()
    main(a.repeats, a.mesh)
