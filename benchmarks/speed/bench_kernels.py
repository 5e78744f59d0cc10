"""The per-pose kernels on their own, and the thread-pool contention that skewed the old timing.

    python benchmarks/speed/bench_kernels.py [--repeats 30]

On the 15K capsule's coordinate matrix (15,074 x 300) and its 30,144 faces, median times of:

1. ``rows_dot(W, X6)`` (six columns, each entry of ``W`` loaded once for six sums) against the
   kernel it replaced (six dot products per row), each timed alone;
2. ``rows_dot`` alone, right after a ``W @ X`` (numpy, OpenBLAS) and 0.3 s after one: OpenBLAS's
   threads keep spinning for a while after a call and take a core from the next one;
3. the row mean of an (n, 3) array: numpy's ``mean(axis=0)`` against `musclewrap.mesh.mean_rows`;
4. the volume and volume-cubic reductions over the faces, compiled for one thread and with
   threads (the solver takes threads from 10K faces), and the cubic compiled without the
   multiply-add fusion and reordering it is allowed (``_FACE_MATH``);
5. the products of the cage's and the proxy's size in a pose (three columns): compiled on
   one thread (`musclewrap.solver._proxy`) against numpy (OpenBLAS), each with its matrix in
   the cache and right after a ``rows_dot`` pass (which pushes it out of the cache);
6. whole poses (capsule ``bend``) of capsules of 12.8K, 20K and 30K faces with the face
   reductions on threads and on one thread, in alternating blocks of 10 poses 0.2 s apart:
   where threads start to pay off inside a pose (the solver's ``_PARALLEL_FACES``).
"""

from __future__ import annotations

import argparse
import time

import numba
import numpy as np

import musclewrap.mesh._volume as volume_module
from musclewrap.coordinates import rows_dot
from musclewrap.mesh import mean_rows
from musclewrap.mesh._volume import _FACE_MATH, _cubic_pair_py, _volume_py
from musclewrap.solver import Muscle
from musclewrap.solver._proxy import _mat3_kernel, mat3
from musclewrap.synthetic import capsule, capsule_scenario


@numba.njit(parallel=True, fastmath=True)
def _six_dot_products(W, XT, out):  # noqa: ANN001 - the kernel rows_dot used before
    n, m = W.shape
    for r in numba.prange(n):
        for c in range(XT.shape[0]):
            s = 0.0
            for j in range(m):
                s += W[r, j] * XT[c, j]
            out[r, c] = s


def median_ms(fn, repeats: int, before=None) -> float:  # noqa: ANN001
    """Median of ``repeats`` timed calls of ``fn``, each after ``before()`` when given."""
    ts = []
    for _ in range(repeats):
        if before is not None:
            before()
        t = time.perf_counter()
        fn()
        ts.append(time.perf_counter() - t)
    return float(np.median(ts) * 1e3)


def main(repeats: int) -> None:
    V, F = capsule()
    W = Muscle.from_mesh(V, F).W
    rng = np.random.default_rng(0)
    X, X6 = rng.random((W.shape[1], 3)), rng.random((W.shape[1], 6))
    XT, out = np.ascontiguousarray(X6.T), np.empty((len(W), 6))
    assert np.allclose(rows_dot(W, X6), W @ X6)
    _six_dot_products(W, XT, out)
    time.sleep(0.3)
    new = median_ms(lambda: rows_dot(W, X6), repeats)
    time.sleep(0.3)
    old = median_ms(lambda: _six_dot_products(W, XT, out), repeats)
    print(
        f"1. rows_dot, 6 columns: {new:.2f} ms; the previous kernel {old:.2f} ms ({old / new:.1f}x)"
    )

    def wx() -> None:
        W @ X

    def wx_pause() -> None:
        W @ X
        time.sleep(0.3)

    time.sleep(0.3)
    alone = median_ms(lambda: rows_dot(W, X6), repeats)
    after = median_ms(lambda: rows_dot(W, X6), repeats, before=wx)
    paused = median_ms(lambda: rows_dot(W, X6), max(5, repeats // 3), before=wx_pause)
    time.sleep(0.3)
    ref = median_ms(wx, repeats)
    print(
        f"2. rows_dot alone {alone:.2f} ms, right after W @ X {after:.2f} ms, 0.3 s after "
        f"W @ X {paused:.2f} ms (W @ X alone {ref:.2f} ms)"
    )
    for n in (6400, len(V)):
        P = rng.random((n, 3))
        mean_rows(P)
        print(
            f"3. mean of {n} x 3: numpy mean(axis=0) {median_ms(lambda P=P: P.mean(axis=0), repeats) * 1e3:.0f} us, "
            f"mean_rows {median_ms(lambda P=P: mean_rows(P), repeats) * 1e3:.0f} us"
        )
    c = mean_rows(V)
    XU = np.ascontiguousarray(np.hstack([V - c, 0.01 * V]))
    for label, py, args, flags in (
        ("volume", _volume_py, (V, F, c), _FACE_MATH),
        ("volume cubic", _cubic_pair_py, (XU, F), _FACE_MATH),
        ("volume cubic, no fast math", _cubic_pair_py, (XU, F), False),
    ):
        one = numba.njit(fastmath=flags)(py)
        par = numba.njit(parallel=True, fastmath=flags)(py)
        one(*args), par(*args)
        a = median_ms(lambda f=one, a=args: f(*a), repeats)
        b = median_ms(lambda f=par, a=args: f(*a), repeats)
        print(f"4. {label} over {len(F)} faces: one thread {a:.2f} ms, threads {b:.2f} ms")
    H, G = rng.random((300, 300)), rng.random((300, 3))
    B32 = rng.random((300, 500)).astype(np.float32)
    g, g32T, u32 = (
        rng.random((500, 3)),
        rng.random((3, 500)).astype(np.float32),
        np.empty((300, 3), np.float32),
    )
    g32 = np.ascontiguousarray(g32T.T)
    cases = (
        ("300 x 300, double", lambda: mat3(H, G), lambda: H @ G),
        ("300 x 500, single", lambda: _mat3_kernel(B32, g32T, u32), lambda: B32 @ g32),
        (
            "300 x 500, single matrix, double sums",
            lambda: mat3(B32, g),
            lambda: B32.astype(float) @ g,
        ),
    )
    for label, ours, blas in cases:

        def evict() -> None:
            rows_dot(W, X6)

        blas(), ours()
        r = [
            median_ms(f, repeats * 10, before=b) * 1e3 for f in (ours, blas) for b in (None, evict)
        ]
        print(
            f"5. {label}, 3 columns: compiled {r[0]:.0f} us (after rows_dot {r[1]:.0f} us), "
            f"numpy {r[2]:.0f} us (after rows_dot {r[3]:.0f} us)"
        )

    rest, cur = capsule_scenario("bend")
    for n_around, cap_rings, segments in ((64, 16, 84), (80, 20, 105), (96, 24, 110)):
        d = Muscle.from_mesh(*capsule(n_around=n_around, cap_rings=cap_rings, segments=segments))
        deformer = d.bind(rest)
        times: dict[str, list[float]] = {"threads": [], "one thread": []}
        saved = volume_module._PARALLEL_FACES
        for _ in range(max(3, repeats // 3)):
            for label, threshold in (("threads", 0), ("one thread", 10**12)):
                volume_module._PARALLEL_FACES = threshold
                time.sleep(0.2)
                deformer.deform(cur)
                for _ in range(10):
                    t = time.perf_counter()
                    deformer.deform(cur)
                    times[label].append(time.perf_counter() - t)
        volume_module._PARALLEL_FACES = saved
        a, b = (float(np.median(v)) * 1e3 for v in times.values())
        print(
            f"6. pose, {len(d.F)} faces: face reductions on threads {a:.2f} ms, one thread {b:.2f} ms"
        )


if __name__ == "__main__":
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--repeats", type=int, default=30)
    main(p.parse_args().repeats)
