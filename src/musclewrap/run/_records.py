"""The run's records: what each task gets and gives back, typed, frozen and small.

A run (`._plan`) gives one `MuscleJob` per muscle (what every task of that muscle
needs), one `FrameSpan` and `PathSpan` per muscle (the motion's per-frame and per-waypoint
data), and its tasks give back `Prepared`, `PathStates`, `ChunkResult` and `Comparison`;
`MuscleOutcome` gathers a muscle's chunks. Every other module of the run imports these;
they import nothing of the run.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path
from typing import Any

import numpy as np

from .._hashing import cache_key as key_of
from .._typing import FloatArray, IntArray
from ..constants import defaults
from ..mesh import invert_rigid
from ..scene import CENTRAL, Stencil
from ..solver import PREPARATION_FORMAT

__all__ = [
    "FIBRES_FORMAT",
    "BoneMesh",
    "ChunkResult",
    "Comparison",
    "FibreFrame",
    "FibreSettings",
    "FrameSpan",
    "MomentArmSettings",
    "MuscleJob",
    "MuscleOutcome",
    "PathSpan",
    "PathStates",
    "Prepared",
    "SidePoses",
    "fibres_key",
]

FIBRES_FORMAT = 3  # of the cached fibres (2: with their shares and areas; 3: rules)


def fibres_key(muscle_key: str, job: MuscleJob) -> str:
    """The cache key of a muscle's fibres: its preparation's key, rest lines and settings."""
    spec, lines = job.fibres, job.rest_lines
    assert spec is not None
    areas = [
        np.asarray([-1] if a is None else a, dtype=np.int64) for a in (spec.origin, spec.insertion)
    ]
    probes = {b.name: b.probe for b in job.bones}
    on_bones = [
        f"{side}:{b}:{probes.get(b)}"
        for side, bones in (("o", spec.origin_bones), ("i", spec.insertion_bones))
        for b, _ in bones
    ]
    return key_of(
        muscle_key,
        *areas,
        *(np.asarray(lines[p], dtype=np.float64) for p in sorted(lines)),
        *(np.asarray(T, dtype=np.float64) for _, T in (*spec.origin_bones, *spec.insertion_bones)),
        "|".join(on_bones),
        f"{spec.count}|{spec.points}|{spec.voxels}|{FIBRES_FORMAT}",
        f"{spec.attachments}|{job.margin}|{defaults.fibre_area_reach}|"
        f"{defaults.fibre_area_least}|{defaults.fibre_area_end_reach}|"
        f"{defaults.fibre_area_end_part}",
    )[:32]


@dataclass(frozen=True)
class BoneMesh:
    """A bone's mesh in its body's frame, and the name of its probe in the cache."""

    name: str
    V: FloatArray
    F: IntArray
    probe: str


@dataclass(frozen=True)
class FibreSettings:
    """A muscle's ``[fibres]`` settings and attachment areas (vertex numbers; None: default).

    ``attachments``: ``[fibres] attachments``. ``origin_bones``, ``insertion_bones``
    (with ``"bones"``): where an area is not given, the scene's bones
    carried by the body the muscle's lines start (end) in, each with the transform from
    the muscle's body frame into the bone's at rest (the areas then come from where
    the muscle lies on them, `musclewrap.fibres.areas_on_bones`).
    """

    count: int
    points: int
    voxels: int
    origin: IntArray | None = None
    insertion: IntArray | None = None
    origin_bones: tuple[tuple[str, FloatArray], ...] = ()
    insertion_bones: tuple[tuple[str, FloatArray], ...] = ()
    attachments: str = "bones"
    #: the deformation holds the areas to their paths' ends (`musclewrap.Deformer`), as
    #: ``[fibres] attached`` (true by default) says
    attached: bool = True
    #: the fibres written (False: ``--no-fibres``, the areas only, for ``attached``)
    output: bool = True


@dataclass(frozen=True)
class MomentArmSettings:
    """Coordinates of the moment arms, their steps (model units) and per-radian factors."""

    coordinates: tuple[str, ...]
    steps: FloatArray
    per_q: FloatArray
    contact: bool


@dataclass(frozen=True)
class MuscleJob:
    """What every task of one muscle needs: mesh, settings, rest pose, where things go."""

    name: str
    source: str
    V: FloatArray
    F: IntArray
    input_id: IntArray
    cage_size: int | None
    cage_coarsening: Any
    method: str
    max_iterations: int | None
    rest_lines: dict[str, FloatArray]
    rest_reference: FloatArray | None
    anchors: IntArray | None
    contact: dict[str, FloatArray | None] | None
    margin: float
    bones: tuple[BoneMesh, ...]
    fibres: FibreSettings | None
    moment_arms: MomentArmSettings | None
    paper_frames: int
    cache_dir: str | None
    outdir: str
    run: str
    cage_around: FloatArray | None = None
    #: muscles that overlap in a round step together (``[collisions] together``)
    together: bool = False
    #: the action lines' sample windows (the scene's ``line_window``)
    line_window: float = field(default_factory=lambda: defaults.line_window)

    @cached_property
    def cache_key(self) -> str:
        """Hash of the mesh and the preparation's settings (names its cache file; once)."""
        return key_of(
            np.asarray(self.V, dtype=np.float64),
            np.asarray(self.F, dtype=np.int64),
            np.asarray(self.input_id, dtype=np.int64),
            *(() if self.cage_around is None else (np.asarray(self.cage_around),)),
            f"{self.cage_size}|{self.cage_coarsening}|{PREPARATION_FORMAT}",
        )[:32]

    def prepare_path(self) -> Path | None:
        """The cache file of the muscle's preparation (None: no cache)."""
        if self.cache_dir is None:
            return None
        return Path(self.cache_dir) / f"{self.name}-{self.cache_key}.npz"

    def fibres_path(self) -> Path | None:
        """The cache file of the muscle's fibres (None: no cache or no fibres)."""
        if self.cache_dir is None or self.fibres is None:
            return None
        return Path(self.cache_dir) / f"fibres-{self.name}-{fibres_key(self.cache_key, self)}.npz"


@dataclass(frozen=True)
class SidePoses:
    """The moment arms' side poses of some frames: ``[k][coordinate][side]`` (q -/+ h).

    ``one_sided[(k, coordinate)]``: where a path of the muscle switches between the
    frame and a side pose, the poses of the one-sided difference used instead.
    """

    lines: list[list[tuple[dict[str, FloatArray], dict[str, FloatArray]]]]
    references: list[list[tuple[FloatArray | None, FloatArray | None]]]
    to_output: FloatArray  # (k, C, 2, 4, 4), the muscle's body
    bone_T: dict[str, FloatArray]  # bone -> (k, C, 2, 4, 4)
    one_sided: dict[tuple[int, int], Stencil] = field(default_factory=dict)

    def poses(self, k: int, j: int) -> tuple[list[tuple[Any, ...]], tuple[float, ...]]:
        """Frame ``k``'s poses about coordinate ``j`` and their weights in the difference.

        Each pose is ``(lines, reference, to_output, bone_T)``; the central difference's
        two, or the one-sided `Stencil`'s where the muscle has one.
        """
        st = self.one_sided.get((k, j))
        if st is None:
            return [
                (
                    self.lines[k][j][s],
                    self.references[k][j][s],
                    self.to_output[k, j, s],
                    {b: T[k, j, s] for b, T in self.bone_T.items()},
                )
                for s in (0, 1)
            ], CENTRAL[1]
        return [
            (
                st.lines[i],
                st.references[i],
                st.to_output[i],
                {b: T[i] for b, T in st.bone_T.items()},
            )
            for i in range(len(st.weights))
        ], st.weights

    def slice(self, a: int, b: int) -> SidePoses:
        return SidePoses(
            self.lines[a:b],
            self.references[a:b],
            self.to_output[a:b],
            {n: T[a:b] for n, T in self.bone_T.items()},
            {(k - a, j): st for (k, j), st in self.one_sided.items() if a <= k < b},
        )


@dataclass(frozen=True)
class FrameSpan:
    """One muscle's per-frame data on consecutive frames of a run (from its ``start``).

    ``waypoint`` (k,) is each frame's waypoint (`PathSpan`; -1: the rest pose), None
    without contact.
    """

    start: int
    frames: IntArray
    times: FloatArray
    lines: list[dict[str, FloatArray]]
    references: list[FloatArray | None]
    to_output: FloatArray  # (k, 4, 4): the muscle's body frame -> output frame
    bone_T: dict[str, FloatArray]  # bone -> (k, 4, 4)
    side: SidePoses | None = None
    waypoint: IntArray | None = None

    def __len__(self) -> int:
        return len(self.frames)

    def slice(self, a: int, b: int) -> FrameSpan:
        """Frames ``a`` to ``b`` of this span (indices into it)."""
        return FrameSpan(
            self.start + a,
            self.frames[a:b],
            self.times[a:b],
            self.lines[a:b],
            self.references[a:b],
            self.to_output[a:b],
            {n: T[a:b] for n, T in self.bone_T.items()},
            None if self.side is None else self.side.slice(a, b),
            None if self.waypoint is None else self.waypoint[a:b],
        )


@dataclass(frozen=True)
class PathSpan:
    """One muscle's waypoints (`._drive.Waypoints`): what `FollowPath` deforms it to.

    ``parent`` (K,) is each waypoint's earlier one (-1: the rest pose); ``lines``,
    ``references``, ``to_output`` (K, 4, 4: the muscle's body frame to the output
    frame) and ``bone_T`` (bone -> (K, 4, 4)) as in `FrameSpan`, per waypoint;
    ``rest_T`` (bone -> (4, 4)) takes the muscle's body frame to each bone's at the
    rest pose.
    """

    parent: IntArray
    lines: list[dict[str, FloatArray]]
    references: list[FloatArray | None]
    to_output: FloatArray
    bone_T: dict[str, FloatArray]
    rest_T: dict[str, FloatArray]

    def __len__(self) -> int:
        return len(self.parent)

    def placement(self, k: int) -> dict[str, FloatArray]:
        """Per bone, the transform from the muscle's body frame into the bone's at waypoint ``k``."""
        return {b: invert_rigid(T[k]) @ self.to_output[k] for b, T in self.bone_T.items()}


@dataclass
class PathStates:
    """A muscle's cage at each waypoint, deformed against its bones (from `FollowPath`).

    ``cages`` (K, m, 3); ``T`` (bone -> (K, 4, 4)) and ``rest_T`` (bone -> (4, 4)) the
    bones' placements there and at the rest pose (the muscle's body frame into the
    bone's); ``reasons`` the waypoints where the contact was not met (index, why);
    ``prepared`` how the muscle's preparation was had (the first task of a muscle
    prepares it, or reads it from the cache).
    """

    cages: FloatArray
    T: dict[str, FloatArray]
    rest_T: dict[str, FloatArray]
    reasons: list[tuple[int, str]] = field(default_factory=list)
    prepared: Prepared | None = None


@dataclass
class Prepared:
    """What a muscle's preparation reports."""

    name: str
    seconds: float
    cache_hit: bool
    note: str | None


@dataclass
class FibreFrame:
    """One frame's fibres of a muscle: lengths, moment arms ``(C, N)``, what was corrected."""

    frame: int
    time: float
    lengths: list[float]
    moment_arms: list[list[float]]
    unconverged: int
    moved: int
    farthest: float
    left: int


@dataclass
class ChunkResult:
    """One muscle's frames of a chunk: report rows, files written (frame index, name), fibres."""

    name: str
    rows: list[dict[str, Any]]
    entries: list[tuple[int, str]]
    fibres: list[FibreFrame] = field(default_factory=list)
    seconds_prepare: float = 0.0
    cache_hit: bool = False
    note: str | None = None
    #: the fibres' shares of the cross-section and their areas (`musclewrap.fibres.Fibres`)
    fibre_share: list[float] = field(default_factory=list)
    fibre_area: list[float] = field(default_factory=list)

    def to_json(self) -> dict[str, Any]:
        return dataclasses.asdict(self)

    @classmethod
    def from_json(cls, d: dict[str, Any]) -> ChunkResult:
        return cls(
            name=d["name"],
            rows=d["rows"],
            entries=[(int(k), str(f)) for k, f in d["entries"]],
            fibres=[FibreFrame(**f) for f in d["fibres"]],
            seconds_prepare=d["seconds_prepare"],
            cache_hit=d["cache_hit"],
            note=d["note"],
            fibre_share=d.get("fibre_share", []),
            fibre_area=d.get("fibre_area", []),
        )


@dataclass
class Comparison:
    """The paper's iteration beside the default, and the worst frame's convergence histories.

    ``paper`` has (frame, volume error, iterations, seconds) on a few frames.
    """

    paper: list[tuple[int, float, int, float]] = field(default_factory=list)
    worst_frame: int | None = None
    convergence: dict[str, list[tuple[float, ...]]] = field(default_factory=dict)

    def to_json(self) -> dict[str, Any]:
        return dataclasses.asdict(self)

    @classmethod
    def from_json(cls, d: dict[str, Any]) -> Comparison:
        return cls(
            paper=[tuple(p) for p in d["paper"]],  # type: ignore[misc]
            worst_frame=d["worst_frame"],
            convergence={k: [tuple(h) for h in v] for k, v in d["convergence"].items()},
        )


@dataclass
class MuscleOutcome:
    """One muscle's whole run: its chunks in frame order, its preparation, its comparison."""

    name: str
    rows: list[dict[str, Any]]
    entries: list[tuple[int, str]]
    fibres: list[FibreFrame]
    seconds_prepare: float
    cache_hit: bool
    note: str | None
    comparison: Comparison
    fibre_share: list[float] = field(default_factory=list)
    fibre_area: list[float] = field(default_factory=list)

    @classmethod
    def merge(
        cls, name: str, parts: list[ChunkResult], prepared: Prepared | None, comparison: Comparison
    ) -> MuscleOutcome:
        first = parts[0]
        notes = [n for n in [prepared and prepared.note, *(p.note for p in parts)] if n]
        return cls(
            name=name,
            rows=[r for p in parts for r in p.rows],
            entries=[e for p in parts for e in p.entries],
            fibres=[f for p in parts for f in p.fibres],
            seconds_prepare=prepared.seconds if prepared is not None else first.seconds_prepare,
            cache_hit=prepared.cache_hit if prepared is not None else first.cache_hit,
            note="; ".join(dict.fromkeys(notes)) or None,
            comparison=comparison,
            fibre_share=next((p.fibre_share for p in parts if p.fibre_share), []),
            fibre_area=next((p.fibre_area for p in parts if p.fibre_area), []),
        )
