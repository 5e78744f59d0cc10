"""How a scene's model bones (``[bones.NAME] model``) sit against its muscles at rest.

For every bone taken from the OpenSim model: its resolution, and per muscle how far each
lies in the other (libigl's signed distances, both ways: muscle vertices in the bone,
bone vertices in the muscle); for a bone with ``fit = "shaft"``, the same again with the
bone fitted (`musclewrap.model.fit_shaft`, as the run fits it). With ``--slices BONE``, the bone cut across its long axis
(the body frame's y) every ``--step``: the outline's centre and mean radius, and the
largest disc clear of every muscle within ``--reach`` of that centre (a grid of
``--grid`` spacing): where the subject's muscles leave room for the bone, and how wide.

    python benchmarks/accuracy/bench_model_bones.py examples/gait2392_leg.toml --slices femur
    python benchmarks/accuracy/bench_model_bones.py examples/gait2392_leg.toml --slices femur \
        --shift -12.5 -6 -350 -120
    python benchmarks/accuracy/bench_model_bones.py examples/gait2392_leg.toml --place sacrum \
        --reach 30
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import igl
import numpy as np
import trimesh

from musclewrap.mesh import apply_transform, mean_edge_length, self_intersecting_faces
from musclewrap.run._read import ReadBone, fit_bones, read_inputs
from musclewrap.scene import load_scene


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("scene")
    ap.add_argument("--slices", default=None, help="a model bone to cut across its y axis")
    ap.add_argument("--step", type=float, default=30.0, help="between slices (mesh units)")
    ap.add_argument("--reach", type=float, default=20.0, help="of the disc search")
    ap.add_argument("--grid", type=float, default=1.5, help="of the disc search")
    ap.add_argument(
        "--shift",
        nargs=4,
        type=float,
        metavar=("DX", "DZ", "BELOW", "ABOVE"),
        help="the sliced bone moved by (DX, 0, DZ) between y = BELOW and ABOVE, faded out "
        "over 80 mesh units beyond either (a smoothstep): the overlaps again",
    )
    ap.add_argument(
        "--place",
        default=None,
        help="a model bone moved whole: the translation (every one within --reach, on a "
        "--grid) that lies the bone's inside clearest of the muscles, the least move among "
        "equals; the overlaps again",
    )
    a = ap.parse_args()
    t0 = time.perf_counter()
    scene = load_scene(Path(a.scene))
    inp = read_inputs(scene, "0:1", None, False, lambda s: None, [])
    t1 = time.perf_counter()
    fits = fit_bones(scene, inp.drive, inp.muscles, None, lambda s: None, [])
    if fits:
        print(f"(the bones with fit = 'shaft' fitted in {time.perf_counter() - t1:.1f} s)")
    for b in scene.bones:
        if not b.source:
            continue
        V, F, _ = ReadBone(b, None, True).run()
        V = apply_transform(inp.drive.to_body[b.name], V)
        print(
            f"{b.name}: {len(V)} vertices, {len(F)} faces (closed), mean edge "
            f"{mean_edge_length(V, F):.1f}, self-intersecting faces {self_intersecting_faces(V, F)}"
        )
        muscles = {}
        for m in scene.muscles:
            if m.bones is not None and b.name not in m.bones:
                continue
            Vm, Fm = inp.muscles[m.name]
            Vm = apply_transform(inp.drive.rest_between(m.body, b.body), Vm)
            muscles[m.name] = (Vm, Fm)
        _overlaps(V, F, muscles, "  ")
        if b.name in fits:
            f = fits[b.name]
            P = V + f.move(V)
            print(
                f"  fitted along its shaft (fit = 'shaft'): moved up to {f.moved:.1f}, "
                f"self-intersecting faces {self_intersecting_faces(P, F)}"
            )
            _overlaps(P, F, muscles, "    ")
        if a.slices == b.name:
            _slices(V, F, muscles, a.step, a.reach, a.grid)
            if a.shift is not None:
                _shifted(V, F, muscles, *a.shift)
        if a.place == b.name:
            _placed(V, F, muscles, a.reach, max(a.grid, 2.0))
    print(f"({time.perf_counter() - t0:.1f} s)")


def _shifted(
    V: np.ndarray,
    F: np.ndarray,
    muscles: dict[str, tuple[np.ndarray, np.ndarray]],
    dx: float,
    dz: float,
    below: float,
    above: float,
) -> None:
    """The overlaps of the bone with its middle moved across its axis (``--shift``)."""

    def smooth(t: np.ndarray) -> np.ndarray:
        t = np.clip(t, 0.0, 1.0)
        return t * t * (3.0 - 2.0 * t)

    y = V[:, 1]
    w = smooth((y - below + 80.0) / 80.0) * smooth((above + 80.0 - y) / 80.0)
    P = V + np.outer(w, [dx, 0.0, dz])
    print(
        f"  moved by ({dx:g}, 0, {dz:g}) between y = {below:g} and {above:g}: self-intersecting "
        f"faces {self_intersecting_faces(P, F)}"
    )
    _overlaps(P, F, muscles, "    ")


def _placed(
    V: np.ndarray,
    F: np.ndarray,
    muscles: dict[str, tuple[np.ndarray, np.ndarray]],
    reach: float,
    grid: float,
) -> None:
    """The bone moved whole to where its inside is clearest of the muscles (``--place``)."""
    from scipy.signal import correlate

    from musclewrap.model._shaft import _clearance

    margin = 2.0
    lo, hi = np.floor(V.min(axis=0) / grid) * grid, np.ceil(V.max(axis=0) / grid) * grid
    n = int(round(reach / grid))
    axes = [np.arange(lo[d], hi[d] + grid / 2, grid) for d in range(3)]
    cells = igl.winding_number(V, F, np.stack(np.meshgrid(*axes, indexing="ij"), -1).reshape(-1, 3))
    cells = (cells > 0.5).reshape([len(x) for x in axes]).astype(np.float64)
    wide = [np.arange(lo[d] - n * grid, hi[d] + n * grid + grid / 2, grid) for d in range(3)]
    P = np.stack(np.meshgrid(*wide, indexing="ij"), -1).reshape(-1, 3)
    short = np.maximum(0.0, margin - _clearance(P, muscles, margin)) ** 2
    price = np.maximum(correlate(short.reshape([len(x) for x in wide]), cells, "valid", "fft"), 0.0)
    T = np.stack(np.meshgrid(*[np.arange(-n, n + 1) * grid] * 3, indexing="ij"), -1)
    total = price + 1e-6 * (T * T).sum(axis=-1)  # the least move among equally clear ones
    k = np.unravel_index(np.argmin(total), total.shape)
    t = T[k]
    print(
        f"  moved whole by ({t[0]:+.0f}, {t[1]:+.0f}, {t[2]:+.0f}) ({np.linalg.norm(t):.1f}; "
        f"every move within {reach:g} on a {grid:g} grid, cells within {margin:g} of a muscle "
        f"priced): price {price[n, n, n]:.0f} -> {price[k]:.0f}"
    )
    _overlaps(V + t, F, muscles, "    ")


def _overlaps(
    V: np.ndarray, F: np.ndarray, muscles: dict[str, tuple[np.ndarray, np.ndarray]], indent: str
) -> None:
    """Per muscle that overlaps the bone ``(V, F)``: how many vertices lie in the other, how deep."""
    for name, (Vm, Fm) in muscles.items():
        in_bone = igl.signed_distance(Vm, V, F)[0]
        in_muscle = igl.signed_distance(V, Vm, Fm)[0]
        if (in_bone < 0).any() or (in_muscle < 0).any():
            print(
                f"{indent}{name}: {(in_bone < 0).sum()} muscle vertices in the bone (deepest "
                f"{max(0.0, -in_bone.min()):.2f}), {(in_muscle < 0).sum()} bone vertices in "
                f"the muscle (deepest {max(0.0, -in_muscle.min()):.2f})"
            )


def _slices(
    V: np.ndarray,
    F: np.ndarray,
    muscles: dict[str, tuple[np.ndarray, np.ndarray]],
    step: float,
    reach: float,
    grid: float,
) -> None:
    """The bone's centre and radius per slice against the widest disc the muscles leave."""
    print(
        "  y: bone centre (x, z), mean radius [min, max] | clear disc: offset, radius; at the centre"
    )
    g = np.arange(-reach, reach + grid / 2, grid)
    X, Z = np.meshgrid(g, g)
    lo, hi = V[:, 1].min(), V[:, 1].max()
    for y in np.arange(lo + step / 2, hi, step):
        seg = trimesh.intersections.mesh_plane(
            trimesh.Trimesh(V, F, process=False), [0.0, 1.0, 0.0], [0.0, y, 0.0]
        )
        if len(seg) < 3:
            continue
        mid, length = seg.mean(axis=1)[:, [0, 2]], np.linalg.norm(seg[:, 1] - seg[:, 0], axis=1)
        c = (mid * length[:, None]).sum(axis=0) / length.sum()
        r = np.linalg.norm(mid - c, axis=1)
        P = np.c_[X.ravel() + c[0], np.full(X.size, y), Z.ravel() + c[1]]
        d = np.full(len(P), np.inf)
        for Vm, Fm in muscles.values():
            d = np.minimum(d, igl.signed_distance(P, Vm, Fm)[0])
        if not np.isfinite(d).all():
            continue
        k = int(np.argmax(d))
        centre = int(np.argmin(np.abs(X.ravel()) + np.abs(Z.ravel())))
        print(
            f"  {y:7.1f}: ({c[0]:6.1f}, {c[1]:6.1f}), {np.average(r, weights=length):5.1f} "
            f"[{r.min():.1f}, {r.max():.1f}] | ({P[k, 0] - c[0]:+5.1f}, {P[k, 2] - c[1]:+5.1f}), "
            f"{d[k]:5.1f}; {d[centre]:+5.1f}"
        )


if __name__ == "__main__":
    main()
