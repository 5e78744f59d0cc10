"""Numba's cache of the compiled kernels: whether it has them, and filling it on a first run."""

from __future__ import annotations

import os
import subprocess
import sys
from typing import TextIO

#: what compiling the kernels adds to the demo's first run: 13 s in issue 26's sitting, 33 s
#: in a slow one with the contact's newer kernels; 10-12 s since the kernels lost numpy's
#: reductions and zeroed arrays (2026-11-30), about twice that in a slow sitting
#: (`benchmarks/speed/bench_first_run.py`, BENCHMARKS.md, "First run and the demo")
FIRST_RUN_SECONDS = "10-25 s"


def kernels_cached() -> bool:
    """True when the solver's kernels were compiled and cached by an earlier run.

    Asks Numba's index of the main solver kernel whether it holds a compiled version
    for its source as it is now (Numba keys its cache by a hash of the source file,
    not by its time: a source rewritten with the same text, by a checkout or a
    reinstall, is still cached). Anything unexpected about Numba's cache counts as
    cached: then nothing is said.
    """
    try:
        from .solver._proxy import _plain_iterations

        return bool(_plain_iterations._cache._cache_file._load_index())
    except Exception:  # noqa: BLE001 # Numba's private cache: any surprise is "cached"
        return True


#: Element loops: inside these kernels and the compiled helpers beside them, arrays are made
#: by ``np.empty`` and filled by loops, and reduced by loops, never by ``np.zeros``,
#: ``np.full``, ``np.flatnonzero`` or an array's ``min``/``max``/``mean``: Numba compiles each
#: such call's implementation again in every kernel that makes it (0.1-0.3 s each, by Numba's
#: compile events per process); without them the demo's first run fell from 3.1-3.2x its
#: second to 2.7-2.9x (`bench_first_run.py`, BENCHMARKS.md). A test holds the rule.
#:
#: the kernels of a pose, of a preparation and of the contact, each with the signature it is
#: called with. On a first run a second process compiles the pose's and some of the
#: contact's while the run's own compiles the preparation's and the contact's others
#: (`HERE`), before its workers start. Kernels that only these call are compiled with them.
#: A test checks that the demo compiles nothing else. A kernel the demo does not call is left
#: to its first call.
_A2, _A1, _I2, _I1 = "float64[:, ::1]", "float64[::1]", "int64[:, ::1]", "int64[::1]"
_A3, _F2 = "float64[:, :, ::1]", "float32[:, ::1]"
KERNELS: dict[str, tuple[tuple[str, str, str], ...]] = {
    "pose": (
        ("solver._proxy", "_plain_iterations",
         f"({_A2}, {_F2}, {_F2}, {_I2}, float64, int64, float64, float64, float64)"),
        ("solver._proxy", "_mat3", f"({_F2}, {_A2})"),
        ("solver._deformer", "_point_polyline_distance", f"({_A2}, {_A2})"),
        ("mesh._volume", "_combine_kernel", f"({_A2}, float64, {_A1})"),
        # the written surface's stretch
        ("mesh._geometry", "_vertex_areas_kernel", f"({_A2}, {_I2}, {_A1})"),
        ("coordinates._mvc", "_rows_dot_kernel", f"({_A2}, {_A2}, {_A2})"),
        ("solver._deformer", "_energy_kernel",
         f"({_I1}, {_I1}, {_A1}, {_A2}, {_A2}, {_A2}, {_A2}, float64)"),
    ),
    # with the rotations and lines of the first pose, which come before the solve
    "preparation": (
        ("conditions._rotation", "_tangents_kernel", f"({_A2}, {_I1}, {_A2})"),
        ("coordinates._mvc", "_mvc_kernel",
         f"({_A2}, {_A2}, {_I2}, {_I2}, {_I2}, float64, float64, float64, {_A2})"),
        ("conditions._rotation", "_blend_rotate",
         f"({_A2}, {_A3}, boolean[::1], {_A2}, {_A3})"),
        ("conditions._rotation", "_frame_rotations", f"({_A2}, {_A2}, {_A2}, {_A2}, {_A3})"),
        ("conditions._rotation", "_quaternions_kernel", f"({_A3}, {_A2})"),
        ("conditions._rotation", "_matrices_kernel", f"({_A2}, {_A3})"),
        ("mesh._volume", "_volume_ser", f"({_A2}, {_I2}, {_A1})"),
        ("mesh._volume", "_cubic_pair_ser", f"({_A2}, {_I2})"),
        ("mesh._volume", "_mean_rows_kernel", f"({_A2},)"),
        ("conditions._lines", "_arclength_kernel", f"({_A2},)"),
        ("conditions._lines", "_polyline_at_kernel", f"({_A2}, {_A1}, {_A2})"),
        # the samples' windows (`line_window`, 0.5 by default since 2026-11-30)
        ("conditions._lines", "_window_mean_kernel", f"({_A2}, {_A2}, {_A1}, {_A1}, {_A2})"),
    ),
    # a scene with bones or muscles in contact (the demo's): the bones' distance grids,
    # which muscle vertices are near them, winding numbers, the nearest triangles
    "contact": (
        ("contact._obstacle", "_signed_kernel",
         f"({_A2}, {_A2}, {_I1}, {_A1}, {_A2}, {_I2}, {_A2}, {_A2}, {_A2}, {_I2}, {_A1}, {_A2})"),
        ("contact._obstacle", "_convexity_kernel", f"({_A2}, {_A2}, {_I1}, {_I1}, {_A1})"),
        ("contact._obstacle", "_bounds_kernel",
         f"({_A2}, {_A1}, float64, {_I1}, float32[::1], float32[::1], {_A1}, {_A1})"),
        ("contact._obstacle", "_interpolate_kernel",
         f"({_A2}, {_A1}, float64, {_I1}, float32[::1], float32[::1], float64, {_I1}, {_A1}, "
         f"{_A2})"),
        ("contact._obstacle", "_nearest_within_kernel",
         f"({_A2}, {_A2}, {_A1}, float64, {_I1}, {_I1}, {_A1}, {_I1})"),
        ("contact._near", "_within_kernel", f"({_A2}, {_A2}, {_A1}, {_A1}, {_I1})"),
        ("contact._inside", "_nearest_face_kernel",
         f"({_A2}, {_I2}, {_A2}, {_I2}, {_I1}, {_I1}, {_I1}, {_I1}, int64, {_A1}, {_A2}, {_I1})"),
        ("contact._inside", "_reach_kernel", f"({_A2}, {_I2}, {_I1}, {_I1}, {_I1}, {_A1})"),
        ("contact._muscles", "_closest_kernel", f"({_A2}, {_A2}, {_I2}, {_A1}, {_A2}, {_I1})"),
        ("mesh._geometry", "_normals_kernel", f"({_A2}, {_I2}, {_A2})"),
        ("mesh._winding", "_cells_kernel", f"({_A2}, int64)"),
        ("mesh._winding", "_region_kernel", f"({_A2}, int64, float64, float64, float64, float64)"),
        ("mesh._winding", "_bin_kernel", f"({_I2}, {_I1}, {_I1}, int64, int64, int64, int64)"),
        ("mesh._winding", "_query_kernel",
         f"({_A2}, {_A2}, {_I2}, int64, float64, float64, float64, float64, int64, int64, "
         f"int64, int64, {_I1}, {_I1}, {_I1})"),
        # the flood over a bone's vertices inside a muscle (`WindingGrid.flood`; it calls
        # the query: compiled after it, in the same process)
        ("mesh._winding", "_flood_kernel",
         f"({_I1}, {_A2}, {_A2}, {_A1}, {_I1}, {_I1}, boolean[::1], {_A2}, {_I2}, int64, "
         f"float64, float64, float64, float64, int64, int64, int64, int64, {_I1}, {_I1}, "
         f"{_I1})"),
        ("mesh._geometry", "_in_box_kernel", f"({_A2}, {_A1}, {_A1}, {_I1})"),
        ("mesh._geometry", "_scatter_kernel", f"({_A2},)"),
        ("mesh._geometry", "_projected_box_kernel", f"({_A2}, {_A2})"),
        ("mesh._geometry", "_in_oriented_box_kernel", f"({_A2}, {_A2}, {_A1}, {_A1}, {_I1})"),
        # the fine finish's spread of a push over the rings round it
        ("contact._finish", "_rings_kernel", f"(int32[::1], int32[::1], {_I1}, int64, {_I1})"),
        ("contact._finish", "_smooth", f"(int32[::1], int32[::1], {_A2}, {_I1}, int64, float64)"),
        # a contact step's deepest vertex per cage vertex
        ("solver._step", "_deepest_one_kernel", f"({_A1}, {_I1}, int64)"),
        # a round's fine step as a thin plate: its conjugate gradients (1.8 s to compile, a
        # scratch `Dispatcher.compile` after two others on an empty cache; the helper's: its
        # side took 13.2 s against the run's 15.7, `bench_first_run.py --sides`, 2026-12-04)
        ("contact._finish", "_plate_cg_kernel",
         f"({_I1}, {_I1}, {_A1}, {_I1}, {_I1}, {_A1}, {_I1}, {_I1}, {_A1}, {_I1}, {_I1}, {_A1}, "
         f"{_A1}, float64, {_A1}, {_A1}, {_A1}, int64, float64)"),
    ),
}  # fmt: skip


#: on a first run, the contact's kernels that the run's own process compiles (after the
#: preparation's) while the helper compiles the pose's and the contact's others. Each
#: process compiles the callees and numpy functions it needs itself, so the two sides took
#: 11.6-14.1 s each where all take 18.7 s in one process (`bench_first_run.py --each`;
#: a scratch timing of each side, 2026-11-27): with the winding grid's binning here too
#: (it was the helper's, which then finished 1.4-2.2 s after this side) and the paths'
#: windows not compiled, the demo's first run took 22.9-25.6 s against 25.1-27.7 s
#: (`bench_first_run.py`, three each in turns). The nearest face's kernel is here since
#: 2026-11-30 (it shares the closest point on a triangle with `_closest_kernel`: compiled
#: once, not in both processes), and the boxes' four kernels, which balance the two sides
#: (the demo's first run with empty caches, as `bench_first_run.py` starts it, 16.6 / 16.6 s
#: against 17.3 / 17.0 s with them in the helper, two each in turns, 2026-11-30)
HERE = (
    "_closest_kernel",
    "_nearest_face_kernel",
    "_region_kernel",
    "_query_kernel",
    "_bin_kernel",
    "_cells_kernel",
    "_flood_kernel",
    "_in_box_kernel",
    "_scatter_kernel",
    "_projected_box_kernel",
    "_in_oriented_box_kernel",
)

#: on a first run, the preparation's kernels that the helper compiles (after the pose's)
#: instead of the run's own process: the bodies' rotations as matrices and quaternions. With
#: the contact's `HERE` grown, this side took 18.4 s against the helper's 14.2 (each alone);
#: both sides together, as a first run starts them, 14.6-16.6 s against 17.0-17.9
#: (`bench_first_run.py --sides`, six runs each in turns, 2026-11-28; BENCHMARKS.md)
HELPED = ("_blend_rotate", "_matrices_kernel", "_quaternions_kernel")


def run_compiles(group: str, name: str) -> bool:
    """Whether a first run's own process compiles kernel ``name`` of ``group`` (else the helper).

    The preparation's but `HELPED`, and the contact's `HERE`.
    """
    return (group == "preparation" and name not in HELPED) or (group == "contact" and name in HERE)


def compile_kernels(group: str | None = None, *, here: bool | None = None) -> None:
    """Compile (into Numba's cache) the kernels of ``group`` of `KERNELS`, or all.

    ``here``: only the first run's own share (True, `run_compiles`) or only the
    helper's (False), in the order of `KERNELS`.
    """
    import importlib

    from numba.core.sigutils import normalize_signature

    for g, kernels in KERNELS.items():
        if group not in (None, g):
            continue
        for module, name, signature in kernels:
            if here is not None and run_compiles(g, name) != here:
                continue
            kernel = getattr(importlib.import_module(f"musclewrap.{module}"), name)
            if hasattr(kernel, "compile"):  # not with NUMBA_DISABLE_JIT
                # the argument types as a call passes them: Numba's cache is keyed by the
                # signature as given (a string would be another key, never found by a call)
                kernel.compile(tuple(normalize_signature(signature)[0]))


#: the helper's share: the pose's kernels, the preparation's `HELPED`, the contact's others
_COMPILE_HELPER = "from musclewrap._jit import compile_kernels; compile_kernels(here=False)"


def compile_here() -> None:
    """The first run's own share of the kernels (`run_compiles`).

    Compiled before the run starts its workers, while the helper of
    `compile_if_first_run` compiles the rest: the workers then find every kernel in
    the cache instead of each compiling the preparation's (and the contact's the
    helper has not reached) at once on two cores.
    """
    compile_kernels(here=True)


def compile_if_first_run(stream: TextIO | None = None) -> subprocess.Popen[bytes] | None:
    """On a first run, say so once and start compiling half of the kernels meanwhile.

    Returns the process that compiles them into Numba's cache (`KERNELS` ``"pose"``,
    then the preparation's `HELPED` and the contact's not in `HERE`) while this one
    compiles the others (`compile_here`, the CLI's ``run``, ``demo`` and ``view``) or
    reads, prepares and compiles what it needs as it goes (a kernel that the helper has
    not reached when a pose needs it is compiled there too). None if the kernels were in
    the cache already, or this machine has one CPU.
    """
    if kernels_cached():
        return None
    print(
        f"compiling kernels, once: about {FIRST_RUN_SECONDS} on this first run "
        "(kept in Numba's cache; later runs start at once)",
        file=stream or sys.stderr,
        flush=True,
    )
    if (os.cpu_count() or 1) < 2:
        return None
    return subprocess.Popen(
        [sys.executable, "-c", _COMPILE_HELPER],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
