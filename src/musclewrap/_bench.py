"""The capsule benchmark of ``musclewrap bench capsule``, and its interleaved timing."""

from __future__ import annotations

import time

import numpy as np

from .coordinates import rows_dot
from .solver import Muscle
from .synthetic import CAPSULE_SCENARIOS, capsule, capsule_scenario

__all__ = ["capsule_benchmark", "interleaved_ms"]


def interleaved_ms(
    fn, ref, repeats: int, block: int = 8, pause: float = 0.3
) -> tuple[float, float]:  # noqa: ANN001
    """Median times (ms) of ``fn`` and ``ref``, timed in alternating phases.

    Each phase is one untimed call and up to ``block`` timed calls of one of
    the two; phases alternate, so drift on a shared machine hits both, and
    ``pause`` seconds separate them. The pause matters: OpenBLAS's threads
    (``W @ X``) keep spinning for about 0.1-0.2 s after a call, and numba's
    after a pose; whichever runs next in that time loses a core to them
    (``rows_dot`` measured 2.2 ms alone and 6.5 ms right after ``W @ X`` on the
    capsule). A run of poses never has ``W @ X`` between its poses.
    """
    ts: list[float] = []
    tr: list[float] = []
    while len(ts) < repeats:
        k = min(block, repeats - len(ts))
        for f, out in ((fn, ts), (ref, tr)):
            time.sleep(pause)
            f()
            for _ in range(k):
                t = time.perf_counter()
                f()
                out.append(time.perf_counter() - t)
    return float(np.median(ts) * 1e3), float(np.median(tr) * 1e3)


def capsule_benchmark(
    methods: tuple[str, ...] = ("sqp", "exact", "paper"),
    repeats: int = 41,
    cage_coarsening: str = "uniform",
) -> tuple[dict[str, object], list[dict[str, object]]]:
    """Run the five capsule scenarios with each method.

    Parameters
    ----------
    methods : tuple of str, optional
        Solvers to run.
    repeats : int, optional
        Timed repeats per case (a tenth of them for the slow reference methods).
    cage_coarsening : {"uniform", "quadric"}, optional
        Cage construction (see `musclewrap.cage.build_cage`).

    Returns
    -------
    info : dict
        Preparation time (and, apart, the one-off start-up of the first
        preparation in a process: imports and compiled kernels), cage size, coarsening and smallest cage angle, the
        median time of one float64 ``W @ X`` (numpy, 3 columns; each solve is
        timed in phases alternating with it, `interleaved_ms`) and of the
        solver's one pass ``rows_dot(W, [x, u])`` (6 columns) timed the same way.
    rows : list of dict
        One per scenario and method: iterations, volume error, skeleton fit,
        energy, largest shape change (spike measure, in mean rest edge
        lengths), median time per pose (ms) and its ratio to ``W @ X``.
    """
    # the first preparation in a process also imports the cage libraries and loads the
    # compiled kernels: timed apart, on a small capsule, so that `prep` is the muscle's own
    t = time.perf_counter()
    Muscle.from_mesh(*capsule(n_around=16, cap_rings=4, segments=8), cage_size=100)
    startup = time.perf_counter() - t
    V, F = capsule()
    t = time.perf_counter()
    muscle = Muscle.from_mesh(V, F, cage_coarsening=cage_coarsening)
    prep = time.perf_counter() - t
    X = np.random.default_rng(0).random((muscle.W.shape[1], 3))
    X6 = np.random.default_rng(1).random((muscle.W.shape[1], 6))
    ms_rows, ms_wx_rows = interleaved_ms(
        lambda: rows_dot(muscle.W, X6), lambda: muscle.W @ X, repeats
    )
    rows = []
    wx_all = []
    for name in CAPSULE_SCENARIOS:
        rest, cur = capsule_scenario(name)
        d = muscle.bind(rest)
        for method in methods:
            res = d.deform(cur, method=method)
            reps = repeats if method == "sqp" else max(3, repeats // 10)
            ms, wx = interleaved_ms(
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
        "seconds_startup": startup,
        "cage_coarsening": muscle.cage.method,
        "cage_min_angle_deg": muscle.cage.min_angle_deg,
        "ms_rows_dot_6": ms_rows,
        "ratio_rows_dot_6_to_WX": ms_rows / ms_wx_rows,
        "ms_W_at_X": float(np.median(wx_all)),
    }
    return info, rows
