"""A run as a plan of typed tasks: what each task gets, and what it gives back.

Reading a scene (`._read`) gives one `MuscleJob` per muscle (what every task of
that muscle needs, the same for all of them) and one `FrameSpan` (the motion's
per-frame data: lines, transforms, the moment arms' side poses), cut into chunks.
The tasks are:

- `Prepare`: a muscle's preparation (and its fibres) into the cache;
- `ProbeBone`: a bone's signed-distance probe into the cache;
- `FollowPath`: one muscle at the waypoints between the rest pose and the frames, against
  its bones (where contact takes its sides, see `._drive.Waypoints`);
- `DeformChunk`: one muscle on one chunk of frames, its files written;
- `Compare`: one muscle's comparison with the paper's iteration on a few frames.

Each is a frozen dataclass whose ``run`` method (in `._work`) executes it in any
process: the executor (`._execute`) only hands tasks to workers and results back.
Large data (prepared muscles, bone probes, fibres) travels through the cache folder,
which every worker reads; tasks carry only what differs between them. Results are
small records that the journal keeps as JSON, so that an interrupted run goes on.

A chunk task names the tasks it waits for (``after``): its muscle's and its bones'
preparation today; the same mechanism lets a later muscle of the same frames wait
for the muscles already placed (muscle-muscle contact in an order).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from .._runs import contiguous_runs
from .._typing import FloatArray, IntArray
from ._read import Inputs, attachment_area, end_bones
from ._records import (
    FibreSettings,
    FrameSpan,
    MomentArmSettings,
    MuscleJob,
    PathSpan,
    SidePoses,
)

__all__ = [
    "chunks",
    "frame_span",
    "muscle_jobs",
    "path_span",
    "rest_placements",
]


# ---------------------------------------------------------------------------- planning
def chunks(n_frames: int, n_jobs: int, workers: int, muscles: int = 1) -> list[range]:
    """Frame ranges per task: about three tasks per worker, for an even finish.

    ``n_jobs`` tasks share each range (a muscle's chunk each, or 1: a group's);
    ``muscles``: the muscles a task solves in each frame (a group's). At least 20
    muscle-frames a task (what a task's start costs is small beside them), at most
    128 frames: a chunk is also what an interrupted run keeps. A group of 18 muscles
    on 5 frames is 4 tasks: as one, it kept one worker busy and left the other idle.
    """
    enough = n_frames * max(1, muscles) // 20
    k = 1 if workers <= 1 else max(1, min(-(-3 * workers // n_jobs), enough))
    return contiguous_runs(n_frames, max(k, -(-n_frames // 128)))


def muscle_jobs(inputs: Inputs, outdir: Path, run: str) -> list[MuscleJob]:
    """One job per muscle of a read scene (`._read.Inputs`), largest first.

    Largest first: the workers then finish about together.
    """
    scene, drive = inputs.scene, inputs.drive
    bones = tuple(inputs.bones[b.name] for b in scene.bones)
    cache = inputs.cache
    jobs = []
    for spec in scene.muscles:
        V, F = inputs.muscles[spec.name]
        ids = inputs.input_ids.get(spec.name, np.arange(len(V)))
        fibres = None
        if scene.fibres is not None:
            f = scene.fibres
            on = end_bones(scene, drive, spec)
            fibres = FibreSettings(
                f.count,
                f.points,
                f.voxels,
                attachment_area(scene, drive, spec, "origin", V, ids),
                attachment_area(scene, drive, spec, "insertion", V, ids),
                on[0],
                on[1],
                f.attachments,
                f.attached,
                f.output,
            )
        ma = drive.moment_arms
        jobs.append(
            MuscleJob(
                name=spec.name,
                source=str(spec.mesh),
                V=V,
                F=F,
                input_id=ids,
                cage_size=spec.cage_size,
                cage_coarsening=spec.cage_coarsening,
                method=spec.method,
                max_iterations=spec.max_iterations,
                rest_lines=drive.rest_lines[spec.name],
                rest_reference=drive.rest_reference[spec.name],
                anchors=None if inputs.anchors is None else inputs.anchors[spec.name],
                contact=None if inputs.contact is None else inputs.contact[spec.name],
                margin=scene.margin,
                bones=bones,
                fibres=fibres,
                moment_arms=(
                    None
                    if fibres is None or ma is None
                    else MomentArmSettings(
                        tuple(ma.coordinates),
                        np.asarray(ma.steps),
                        np.asarray(ma.per_q),
                        scene.fibres.moment_arm_contact,
                    )
                ),
                paper_frames=scene.paper_frames,
                cache_dir=None if cache is None else str(cache),
                outdir=str(outdir),
                run=run,
                cage_around=inputs.cage_around.get(spec.name),
                together=scene.muscle_together,
                line_window=scene.line_window,
            )
        )
    jobs.sort(key=lambda j: -len(j.V))
    return jobs


def frame_span(inputs: Inputs, name: str) -> FrameSpan:
    """A muscle's per-frame data over the whole run."""
    scene, drive = inputs.scene, inputs.drive
    spec = next(s for s in scene.muscles if s.name == name)
    ma = drive.moment_arms
    side = None
    if scene.fibres is not None and scene.fibres.output and ma is not None:
        side = SidePoses(
            ma.lines[name],
            ma.references[name],
            ma.to_output[spec.body],
            {b.name: ma.to_output[b.body] for b in scene.bones},
            ma.one_sided[name],
        )
    wp = drive.waypoints
    return FrameSpan(
        0,
        np.asarray(drive.frames),
        np.asarray(drive.times),
        drive.lines[name],
        drive.references[name],
        drive.to_output[spec.body],
        {b.name: drive.to_output[b.body] for b in scene.bones},
        side,
        None if inputs.contact is None else _frame_waypoints(wp, len(drive.frames)),
    )


def _frame_waypoints(wp: Any, n: int) -> IntArray:
    """Each frame's waypoint, -1 (the rest pose) for all where there are none."""
    return np.full(n, -1, dtype=np.int64) if wp is None else np.asarray(wp.frame, dtype=np.int64)


def rest_placements(inputs: Inputs, name: str) -> dict[str, FloatArray]:
    """Per bone, the transform from muscle ``name``'s body frame into the bone's at rest."""
    scene, drive = inputs.scene, inputs.drive
    body = next(s.body for s in scene.muscles if s.name == name)
    return {b.name: drive.rest_between(body, b.body) for b in scene.bones}


def path_span(inputs: Inputs, name: str) -> PathSpan:
    """A muscle's waypoints and its bones' placements there and at rest."""
    scene, drive = inputs.scene, inputs.drive
    spec = next(s for s in scene.muscles if s.name == name)
    wp = drive.waypoints
    rest_T = rest_placements(inputs, name)
    if wp is None:
        empty = np.zeros((0, 4, 4))
        return PathSpan(
            np.zeros(0, np.int64), [], [], empty, {b.name: empty for b in scene.bones}, rest_T
        )
    return PathSpan(
        np.asarray(wp.parent, dtype=np.int64),
        wp.lines[name],
        wp.references[name],
        wp.to_output[spec.body],
        {b.name: wp.to_output[b.body] for b in scene.bones},
        rest_T,
    )
