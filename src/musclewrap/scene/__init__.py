"""Scenes: an OpenSim model and motion (or per-frame lines) driving many muscles.

A scene's description: its file read and checked for what it says (`load_scene`,
`Scene`), the keys it may hold (`SCENE_KEYS`), and what drives it frame by frame
(`drive_scene`: lines, bodies' transforms, waypoints and moment arms' side poses from
the model and motion). The engine that runs a scene lives in `musclewrap.run`, the
model's side in `musclewrap.model`; their public names are importable from here too
(``from musclewrap.scene import load_scene, run_scene``), looked up when first asked for.
"""

from __future__ import annotations

import importlib
from typing import Any

from ..errors import SceneError
from ._config import UNITS, BoneSpec, FibreSpec, MuscleSpec, Scene, load_scene
from ._drive import (
    CENTRAL,
    Drive,
    MomentArmPoses,
    Poser,
    Registration,
    Stencil,
    Waypoints,
    drive_scene,
    lattice_parent,
    lattice_paths,
    one_sided,
    parse_frames,
    polyline_length,
    rest_pose,
    reversed_coordinates,
)
from ._keys import OUTPUT_COLUMNS, SCENE_KEYS

#: names of the engine and the model kept importable from here: the package that holds
#: each (`musclewrap.run` imports this one, so they are looked up when first asked for)
_ELSEWHERE = {
    "REPORT_FIELDS": "run",
    "CheckError": "run",
    "CheckReport": "run",
    "Coordinate": "run",
    "Executor": "run",
    "Finding": "run",
    "LiveScene": "run",
    "LocalExecutor": "run",
    "PoseResult": "run",
    "ProcessExecutor": "run",
    "RunOptions": "run",
    "RunSummary": "run",
    "check_scene": "run",
    "default_cache_dir": "run",
    "run_batch": "run",
    "run_scene": "run",
    "Motion": "model",
    "OpenSimModel": "model",
    "random_motion": "model",
    "read_motion": "model",
    "write_motion": "model",
}


def __getattr__(name: str) -> Any:
    """The engine's and the model's public names, from their packages (PEP 562)."""
    if name in _ELSEWHERE:
        return getattr(importlib.import_module(f"musclewrap.{_ELSEWHERE[name]}"), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


__all__ = [
    "CENTRAL",
    "OUTPUT_COLUMNS",
    "REPORT_FIELDS",
    "SCENE_KEYS",
    "UNITS",
    "BoneSpec",
    "CheckError",
    "CheckReport",
    "Coordinate",
    "Drive",
    "Executor",
    "FibreSpec",
    "Finding",
    "LiveScene",
    "LocalExecutor",
    "MomentArmPoses",
    "Motion",
    "MuscleSpec",
    "OpenSimModel",
    "PoseResult",
    "Poser",
    "ProcessExecutor",
    "Registration",
    "RunOptions",
    "RunSummary",
    "Scene",
    "SceneError",
    "Stencil",
    "Waypoints",
    "check_scene",
    "default_cache_dir",
    "drive_scene",
    "lattice_parent",
    "lattice_paths",
    "load_scene",
    "one_sided",
    "parse_frames",
    "polyline_length",
    "random_motion",
    "read_motion",
    "rest_pose",
    "reversed_coordinates",
    "run_batch",
    "run_scene",
    "write_motion",
]
