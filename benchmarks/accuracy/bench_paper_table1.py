"""The paper's Table 1 reproduced: iterations and volume kept by eq. 11 for each step length.

Kohout, Kellnhofer & Martelli (2012), Table 1: for a fixed step ``alpha`` of 0.025 ... 0.75 and
for their adaptive ``alpha``, the iterations of eq. 11 and the volume kept. Here the same rows
for ``method="paper"`` (`musclewrap.solver._paper.solve_paper`, at most
``defaults.paper_max_iterations`` = 200 iterations, the paper's own limit) on a real muscle whose
action line is bent by 30 degrees and shortened by 15 % (``bend_short`` along its principal
axis), beside the paper's figures and beside musclewrap's default solver on the same pose:
iterations, whether it met the stopping test (step below 1e-9 of the cage's size with the fine
volume within 1e-9), the volume kept (deformed / rest fine volume), the largest relative volume
error of the fine mesh over the iterations, the energy of the soft conditions (`Deformer.energy`)
and the median time per pose; then ``method="exact"`` (the fine mesh's own constrained
Gauss-Newton, the reference) and the default.

    python benchmarks/accuracy/bench_paper_table1.py [--muscle MESH] [--scenario bend_short] [--repeats 3]
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
DATA = ROOT.parent / "shared" / "data"

#: Table 1 of the paper: alpha -> (iterations, volume preservation in %)
PAPER = {
    0.025: (186, 99.89),
    0.05: (106, 99.85),
    0.1: (59, 99.77),
    0.25: (27, 99.58),
    0.5: (24, 99.35),
    0.75: (76, 99.19),
    None: (57, 99.93),
}


def _timed(fn, repeats: int) -> tuple[object, float]:  # noqa: ANN001
    out, times = None, []
    for _ in range(repeats):
        t = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t)
    return out, 1e3 * float(np.median(times))


def main() -> None:
    from musclewrap import Muscle
    from musclewrap.synthetic import principal_axis_scenario

    p = argparse.ArgumentParser()
    p.add_argument(
        "--muscle", default=str(DATA / "vhf" / "VHF_Right_Muscle_RectusFemoris_smooth.stl")
    )
    p.add_argument("--scenario", default="bend_short")
    p.add_argument("--repeats", type=int, default=3)
    a = p.parse_args()
    m = Muscle.from_file(a.muscle)
    rest, cur = principal_axis_scenario(m.V, a.scenario)
    d = m.bind(rest)
    d.deform(cur)  # kernels loaded outside the timings
    print(
        f"{Path(a.muscle).name}: {len(m.V)} vertices, cage {len(m.cage.C)}, scenario {a.scenario}"
    )
    print(
        f"{'alpha':>9s} | {'paper: it':>9s} {'vol kept':>9s} | {'it':>4s} {'stopped':>7s} "
        f"{'vol kept':>12s} {'rel. vol. error':>15s} {'worst on the way':>16s} "
        f"{'energy':>10s} {'ms/pose':>8s}"
    )
    for alpha, (p_it, p_vol) in PAPER.items():
        res, ms = _timed(lambda alpha=alpha: d.deform(cur, method="paper", alpha=alpha), a.repeats)
        worst = max(abs(e) for _, e in res.history) if res.history else float("nan")
        label = "adaptive" if alpha is None else f"{alpha:g}"
        print(
            f"{label:>9s} | {p_it:9d} {p_vol:8.2f}% | {res.iterations:4d} "
            f"{'yes' if res.converged else 'no':>7s} {100 * (1 + res.relative_volume_error):11.9f}% "
            f"{res.relative_volume_error:15.2e} {worst:16.2e} {res.energy:10.2f} {ms:8.1f}"
        )
    for method in ("exact", "sqp"):  # the reference iteration, and the default
        res, ms = _timed(lambda method=method: d.deform(cur, method=method), max(a.repeats, 11))
        label = "default" if method == "sqp" else method
        print(
            f"{label:>9s} | {'':>9s} {'':>9s} | {res.iterations:4d} "
            f"{'yes' if res.converged else 'no':>7s} "
            f"{100 * (1 + res.relative_volume_error):11.9f}% "
            f"{res.relative_volume_error:15.2e} {'':>16s} {res.energy:10.2f} {ms:8.1f}"
        )


if __name__ == "__main__":
    main()
