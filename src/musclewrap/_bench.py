"""The capsule benchmark (shared by ``musclewrap bench capsule`` and ``benchmarks/``)."""

from __future__ import annotations

import time

import numpy as np

from .solver import Muscle
from .synthetic import CAPSULE_SCENARIOS, capsule, capsule_scenario

__all__ = ["capsule_benchmark"]


def _interleaved_ms(fn, ref, repeats: int) -> tuple[float, float]:  # noqa: ANN001
    """Median times (ms) of ``fn`` and ``ref`` run alternately, so drift hits both."""
    fn()
    ref()
    ts, tr = [], []
    for _ in range(repeats):
        t = time.perf_counter()
        fn()
        ts.append(time.perf_counter() - t)
        t = time.perf_counter()
        ref()
        tr.append(time.perf_counter() - t)
    return float(np.median(ts) * 1e3), float(np.median(tr) * 1e3)


def capsule_benchmark(
    methods: tuple[str, ...] = ("sqp", "exact", "paper"), repeats: int = 41
) -> tuple[dict[str, float], list[dict[str, object]]]:
    """Run the five capsule scenarios with each method.

    Returns
    -------
    info : dict
        Preparation time, cage size, and the median time of one float64
        ``W @ X`` (numpy, 3 columns), each solve timed alternately with it.
    rows : list of dict
        One per scenario and method: iterations, volume error, skeleton fit,
        energy, largest shape change (spike measure, in mean rest edge
        lengths), median time per pose (ms) and its ratio to ``W @ X``.
    """
    V, F = capsule()
    t = time.perf_counter()
    muscle = Muscle.from_mesh(V, F)
    prep = time.perf_counter() - t
    X = np.random.default_rng(0).random((muscle.W.shape[1], 3))
    rows = []
    wx_all = []
    for name in CAPSULE_SCENARIOS:
        rest, cur = capsule_scenario(name)
        d = muscle.bind(rest)
        for method in methods:
            res = d.deform(cur, method=method)
            reps = repeats if method == "sqp" else max(3, repeats // 10)
            ms, wx = _interleaved_ms(
                lambda d=d, cur=cur, method=method: d.deform(cur, method=method),
                lambda: muscle.W @ X,
                reps,
            )
            wx_all.append(wx)
            rows.append(
                {
                    "scenario": name,
                    "method": method,
                    "iterations": res.iterations,
                    "converged": res.converged,
                    "relative_volume_error": res.relative_volume_error,
                    "skeleton_fit_mean": res.skeleton_fit_mean,
                    "shape_change_max": float(muscle.shape_change(res.V).max()),
                    "energy": res.energy,
                    "ms_per_pose": ms,
                    "ratio_to_WX": ms / wx,
                }
            )
    info = {
        "n_vertices": float(len(muscle.V)),
        "n_cage_vertices": float(len(muscle.cage.C)),
        "seconds_prepare": prep,
        "ms_W_at_X": float(np.median(wx_all)),
    }
    return info, rows
