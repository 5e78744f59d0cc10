"""Fibres of a scene's muscles: built once per muscle, carried and measured per frame, written.

A worker builds (or reads from the cache) each muscle's fibres at rest
(`musclewrap.fibres.fibres_at_rest`), carries them with every frame's cage and, where
the scene asks for moment arms, deforms the muscle again at the poses on either side
of the frame (``q -/+ h`` for each coordinate, each solved from the rest pose like any
frame) for ``r = -dL/dq`` by central differences. Where a path of the muscle changes its
points between the frame and one side (a conditional via point, a wrap), the length has a
kink or a step there: the difference is one-sided (second order, on the frame, ``q + h``
and ``q + 2h`` of the side without the change), so the moment arm has the kink of the
model's path and no spike. The main process writes the rows
(``fibres.csv``, ``moment_arms.csv``) and the plot (``moment_arms.png``).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from .._cache import cached_arrays
from .._typing import FloatArray, IntArray
from ..constants import defaults
from ..contact import Obstacle, Placed
from ..fibres import Fibres, areas_on_bones, fibres_at_rest, keep_inside
from ..mesh import apply_transform, mean_edge_length, write_mesh
from ..output import plot_moment_arms, write_csv
from ..scene import OUTPUT_COLUMNS, Drive
from ..solver import DeformationResult, Muscle
from ._files import FIBRES_CSV, MOMENT_ARMS_CSV, PLOT_MOMENT_ARMS
from ._records import BoneMesh, MomentArmSettings, MuscleJob, MuscleOutcome, SidePoses

#: a bone's signed-distance probe (`musclewrap.run._work.bone_probe` with the run's cache)
Probe = Callable[[BoneMesh], Obstacle]

__all__ = [
    "FIBRE_FIELDS",
    "MOMENT_ARM_FIELDS",
    "fibres_of",
    "frame_fibres",
    "on_bones",
    "write_fibre_outputs",
    "write_frame_fibres",
]

# their meanings: `OUTPUT_COLUMNS` (the documentation lists them)
FIBRE_FIELDS = list(OUTPUT_COLUMNS[FIBRES_CSV])
MOMENT_ARM_FIELDS = list(OUTPUT_COLUMNS[MOMENT_ARMS_CSV])


def on_bones(
    V: FloatArray, F: IntArray, margin: float, placed: Sequence[Placed]
) -> npt.NDArray[np.bool_] | None:
    """Per vertex at rest, whether it lies on one of the bones ``placed`` (None: none given).

    Within the margin and ``defaults.fibre_area_reach`` of the muscle's mean edge lengths
    of the bone's surface, or inside it (exact, `Obstacle.query`).
    """
    if not placed:
        return None
    V = np.asarray(V, dtype=np.float64)
    within = margin + defaults.fibre_area_reach * mean_edge_length(V, F)
    on = np.zeros(len(V), dtype=bool)
    for pl in placed:
        on[pl.obstacle.query(pl.to_obstacle(V), within)[0]] = True
    return on


def choose_areas(
    V: FloatArray,
    F: IntArray,
    lines: Mapping[str, npt.ArrayLike],
    margin: float,
    given: Sequence[IntArray | None],
    placed: Sequence[Sequence[Placed]],
) -> tuple[IntArray, IntArray, tuple[str, str]]:
    """The fibres' attachment areas of a muscle at rest ``V, F``, and per side its rule.

    Per side (origin, insertion): the area the scene gives (``"given"``), else where the
    muscle lies on the bones ``placed`` on that side (`on_bones`,
    `musclewrap.fibres.areas_on_bones`: ``"bones"``), else its end cap (``"ends"``).
    What the run and `check` both take.
    """
    masks = [
        None if g is not None else on_bones(V, F, margin, p)
        for g, p in zip(given, placed, strict=True)
    ]
    o, i, rules = areas_on_bones(
        np.asarray(V, dtype=np.float64), np.asarray(F, dtype=np.int64), lines, *masks
    )
    got = [
        (a, r) if g is None else (g, "given") for g, a, r in zip(given, (o, i), rules, strict=True)
    ]
    return got[0][0], got[1][0], (got[0][1], got[1][1])


def describe_areas(
    rules: tuple[str, str],
    given: tuple[bool, bool],
    bones: tuple[str, str],
    sizes: tuple[int, int],
    attachments: str,
) -> str:
    """Which rule gave each attachment area (the notes of `run` and `check`).

    Per side: its rule, whether the scene gave it, the bones of its body (names joined,
    "" for none) and its size; ``attachments`` as ``[fibres]`` says.
    """
    parts = []
    for side, rule, g, names, n in zip(
        ("origin", "insertion"), rules, given, bones, sizes, strict=True
    ):
        if g:
            how = "given by the scene"
        elif rule == "bones":
            how = f"where it lies on {names}"
        elif attachments == "ends":
            how = "its end cap"
        elif names:
            how = (
                f"its end cap, as fewer than {defaults.fibre_area_least} vertices lie on "
                f"{names} near its end of the muscle"
            )
        else:
            how = "its end cap, as the scene has no bone of its body"
        parts.append(f"{side}: {how} ({n} vertices)")
    return "the fibres' attachment areas: " + "; ".join(parts)


def _areas_note(job: MuscleJob, rules: tuple[str, str], sizes: tuple[int, int]) -> str:
    """`describe_areas` for the job's muscle, for the run's notes."""
    spec = job.fibres
    assert spec is not None
    names = [
        " or ".join(b for b, _ in bones) for bones in (spec.origin_bones, spec.insertion_bones)
    ]
    given = (spec.origin is not None, spec.insertion is not None)
    return f"{job.name}: " + describe_areas(
        rules, given, (names[0], names[1]), sizes, spec.attachments
    )


def fibres_of(
    muscle: Muscle, job: MuscleJob, path: Path | None, probe: Probe | None = None
) -> tuple[Fibres | None, str | None]:
    """The muscle's fibres at rest, read from the cache file ``path`` or built (and cached).

    ``probe``: a bone's signed-distance probe (`Obstacle`), for the attachment areas
    on the bones of the muscle's ends (`musclewrap.fibres.areas_on_bones`); without
    it, or where the scene gives an area, the end caps or the given areas.

    Returns
    -------
    Fibres or None, and a note: which rule gave each attachment area, or why the
    muscle has no fibres
    """
    spec = job.fibres
    assert spec is not None

    def build() -> dict[str, np.ndarray]:
        meshes = {b.name: b for b in job.bones}
        placed = tuple(
            [Placed(probe(meshes[n]), np.asarray(T, dtype=np.float64)) for n, T in bones]
            if probe is not None
            else []
            for bones in (spec.origin_bones, spec.insertion_bones)
        )
        origin, insertion, rules = choose_areas(
            muscle.V, muscle.F, job.rest_lines, job.margin, (spec.origin, spec.insertion), placed
        )
        why = ""
        kw = {"count": spec.count, "points": spec.points, "voxels": spec.voxels}
        try:
            fb = fibres_at_rest(muscle, job.rest_lines, origin=origin, insertion=insertion, **kw)
        except ValueError as exc:
            if "bones" not in rules:
                raise
            # the areas on the bones gave no fibres: the end caps (and the areas given)
            why = str(exc)
            rules = (rules[0].replace("bones", "ends"), rules[1].replace("bones", "ends"))
            fb = fibres_at_rest(
                muscle, job.rest_lines, origin=spec.origin, insertion=spec.insertion, **kw
            )
        return {
            "points": fb.points,
            "W": fb.W,
            "origin": fb.origin,
            "insertion": fb.insertion,
            "spacing": np.array(fb.spacing),
            "share": fb.share,
            "area": fb.area,
            "rules": np.array([*rules, why]),
        }

    try:
        z = cached_arrays(path, build)
    except ValueError as exc:
        return None, f"{job.name}: no fibres ({exc})"
    # the two sides' rules and why the areas on the bones were not used ("": they were)
    got = [str(r) for r in z.get("rules", ())]
    rules = (got + ["ends", "ends", ""][len(got) :])[:3]
    note = _areas_note(job, (rules[0], rules[1]), (len(z["origin"]), len(z["insertion"])))
    if rules[2]:
        note += f" (the areas on the bones gave no fibres: {rules[2]})"
    return Fibres(
        points=z["points"],
        W=z["W"],
        origin=z["origin"],
        insertion=z["insertion"],
        spacing=float(z["spacing"]),
        share=z["share"],
        area=z["area"],
    ), note


def frame_fibres(
    fb: Fibres,
    F: Any,
    res: DeformationResult,
    k: int,
    ma: MomentArmSettings | None,
    side: SidePoses | None,
    solve: Callable[[Any, Any, FloatArray, dict[str, FloatArray], bool, bool], Any],
) -> dict[str, Any]:
    """One frame's fibres: their lengths and, where asked, their moment arms.

    Parameters
    ----------
    fb : Fibres
    F : (m, 3) int array
        The muscle's triangles.
    res : DeformationResult
        The frame's deformation.
    k : int
        The frame's position in ``side``.
    ma : MomentArmSettings or None
        The moment arms asked for (None: lengths only).
    side : SidePoses or None
        The side poses of the frames (with ``ma``).
    solve : callable
        ``solve(lines, reference, T, bone_T, finish, bones)``: the deformation at a
        pose with the muscle body's transform ``T`` and each bone's ``bone_T``;
        called with ``finish=False`` (`musclewrap.Deformer.deform`) and ``bones`` as
        the scene's ``[fibres] moment_arm_contact`` says.

    Returns
    -------
    dict
        ``points`` (N, K, 3) or None, ``lengths`` (N,), ``moment_arms`` (C, N) (NaN
        where a solve failed or did not converge), ``unconverged`` (solves), and
        ``moved``, ``farthest``, ``left`` from `musclewrap.fibres.keep_inside`.
    """
    n = len(fb.points)
    coords = () if ma is None or side is None else ma.coordinates
    out: dict[str, Any] = {
        "points": None,
        "lengths": np.full(n, np.nan),
        "moment_arms": np.full((len(coords), n), np.nan),
        "unconverged": 0,
        "moved": 0,
        "farthest": 0.0,
        "left": 0,
    }
    if not (res.converged and np.isfinite(res.cage).all()):
        return out
    # where the deformation folds the surface onto itself, or the contact's finish pushed
    # it past them, points are moved back inside (counted, and said in the run's notes)
    P, out["moved"], out["farthest"], out["left"] = keep_inside(
        fb.at(res.cage).reshape(-1, 3), res.V, F, depth=defaults.fibre_inside_depth * fb.spacing
    )
    out["points"] = P.reshape(fb.points.shape)
    out["lengths"] = fb.lengths(out["points"])
    for j in range(len(coords)):
        poses, weights = side.poses(k, j)
        dL = np.zeros(n)
        for (lines, reference, T, bone_T), w in zip(poses, weights, strict=True):
            # the fine finish moves no cage vertex: the fibres are the same without it
            r = solve(lines, reference, T, bone_T, False, ma.contact)
            if not (r.converged and np.isfinite(r.cage).all()):
                out["unconverged"] += 1
                break
            dL += w * fb.lengths(fb.at(r.cage))
        else:
            out["moment_arms"][j] = -dL / ma.steps[j] * ma.per_q[j]
    return out


def write_frame_fibres(path: Path, fb: Fibres, points: FloatArray, T: FloatArray) -> None:
    """A frame's fibres as one poly-line cell each, in the output frame (VTP)."""
    n, k = points.shape[:2]
    lengths = fb.lengths(points)
    write_mesh(
        path,
        apply_transform(T, points.reshape(-1, 3)),
        np.zeros((0, 3), dtype=np.int64),
        lines=np.arange(n * k).reshape(n, k),
        cell_data={
            "fibre": np.arange(n, dtype=np.int64),
            "length": lengths,
            "stretch": lengths / fb.lengths(),
            "share": fb.share,
            "area": fb.area,
        },
    )


def _value(drive: Drive, coordinate: str, k: int) -> float | str:
    """The coordinate's value at frame position ``k`` (degrees or mm), or '' unknown."""
    v = drive.coordinate_values.get(coordinate)
    return "" if v is None else float(v[k])


def _rows(
    drive: Drive, results: Sequence[MuscleOutcome], muscles: dict[str, tuple[str, ...]]
) -> tuple[list[dict[str, Any]], list[dict[str, Any]]]:
    ma = drive.moment_arms
    coords = () if ma is None else ma.coordinates
    fibre_rows: list[dict[str, Any]] = []
    arm_rows: list[dict[str, Any]] = []
    position = {f: k for k, f in enumerate(drive.frames)}
    for res in results:
        name = res.name
        for fr in res.fibres:
            k = position[fr.frame]
            lengths = np.asarray(fr.lengths, dtype=np.float64)
            nan = [float("nan")] * len(lengths)
            share = res.fibre_share if len(res.fibre_share) == len(lengths) else nan
            area = res.fibre_area if len(res.fibre_area) == len(lengths) else nan
            arms = np.asarray(fr.moment_arms, dtype=np.float64).reshape(len(coords), len(lengths))
            base = {"frame": fr.frame, "time": fr.time, "muscle": name}
            if not coords:
                fibre_rows += [
                    {
                        **base,
                        "fibre": i,
                        "share": share[i],
                        "area": area[i],
                        "length": float(x),
                        "coordinate": "",
                        "coordinate_value": "",
                        "moment_arm": "",
                    }
                    for i, x in enumerate(lengths)
                ]
                continue
            for j, c in enumerate(coords):
                value = _value(drive, c, k)
                fibre_rows += [
                    {
                        **base,
                        "fibre": i,
                        "share": share[i],
                        "area": area[i],
                        "length": float(x),
                        "coordinate": c,
                        "coordinate_value": value,
                        "moment_arm": float(r),
                    }
                    for i, (x, r) in enumerate(zip(lengths, arms[j], strict=True))
                ]
                ok = np.isfinite(arms[j])
                paths = muscles[name]
                arm_rows.append(
                    {
                        **base,
                        "coordinate": c,
                        "coordinate_value": value,
                        "fibre_min": float(arms[j].min()) if ok.all() else float("nan"),
                        "fibre_mean": float(arms[j].mean()) if ok.all() else float("nan"),
                        "fibre_max": float(arms[j].max()) if ok.all() else float("nan"),
                        # a muscle of several paths: the mean of its paths' moment arms
                        "line_moment_arm": float(np.mean([ma.line[p][k, j] for p in paths])),
                        "opensim_moment_arm": float(np.mean([ma.opensim[p][k, j] for p in paths])),
                    }
                )
    return fibre_rows, arm_rows


def write_fibre_outputs(
    outdir: Path,
    drive: Drive,
    results: Sequence[MuscleOutcome],
    muscles: dict[str, tuple[str, ...]],
    notes: list[str],
    unit: str = "mm",
) -> list[Path]:
    """``fibres.csv`` and, with moment arms, ``moment_arms.csv`` and ``moment_arms.png``.

    Parameters
    ----------
    muscles : dict of str to tuple of str
        Each muscle's OpenSim paths (its action line's moment arm is their mean).
    unit : str
        The meshes' length unit (the moment arms' in the plot are in mm).
    notes : list of str
        Gets a line per path whose points change between a frame and a side pose
        (a one-sided difference there), and per muscle with unconverged moment-arm
        solves.
    """
    fibre_rows, arm_rows = _rows(drive, results, muscles)
    files = [write_csv(outdir / FIBRES_CSV, fibre_rows, FIBRE_FIELDS)]
    for res in results:
        moved = [fr for fr in res.fibres if fr.moved]
        if moved:
            n = sum(fr.moved for fr in moved)
            far = max(fr.farthest for fr in moved)
            left = sum(fr.left for fr in moved)
            notes.append(
                f"{res.name}: {n} fibre point(s) on {len(moved)} frame(s) lay outside the "
                f"deformed surface (where it folds onto itself, or the contact pushed it past "
                f"them) and were moved inside it, by up to {far:.2g}"
                + (f"; {left} stayed outside" if left else "")
            )
        bad = sum(fr.unconverged for fr in res.fibres)
        if bad:
            notes.append(
                f"{res.name}: {bad} solve(s) at a moment arm's side pose did not converge: "
                "those moment arms are empty (nan)"
            )
    ma = drive.moment_arms
    if ma is None:
        return files

    def frames_of(mask: Any) -> str:
        return "; ".join(
            f"{c} at frame(s) {', '.join(str(drive.frames[k]) for k in np.flatnonzero(mask[:, j]))}"
            for j, c in enumerate(ma.coordinates)
            if mask[:, j].any()
        )

    for p, sw in ma.switch.items():
        both = ma.both_sides[p]
        if (sw & ~both).any():
            notes.append(
                f"path {p}: its points change between the frame and one side pose "
                f"({frames_of(sw & ~both)}: a conditional via point or a wrap switches): "
                "there its moment arm, and its muscle's fibres', is the one-sided difference "
                "on the side without the change"
            )
        if both.any():
            notes.append(
                f"path {p}: its points change on both sides of the frame ({frames_of(both)}): "
                "no side is free of the change, the central difference is kept and may jump; "
                "a smaller [fibres] step separates the two changes"
            )
    files.append(write_csv(outdir / MOMENT_ARMS_CSV, arm_rows, MOMENT_ARM_FIELDS))

    files.append(
        plot_moment_arms(
            outdir / PLOT_MOMENT_ARMS,
            arm_rows,
            ma.coordinates,
            ma.per_q,
            swept=drive.swept,
            swept_values=(
                None
                if drive.swept is None
                else dict(zip(drive.frames, drive.coordinate_values[drive.swept], strict=True))
            ),
            swept_unit=drive.coordinate_units.get(drive.swept or "", "deg"),
            unit=unit,
        )
    )
    return files
