"""Scenes: an OpenSim model and motion (or per-frame lines) driving many muscles."""

from ._check import CheckReport, Finding, check_scene
from ._config import BoneSpec, MuscleSpec, Scene, load_scene
from ._drive import Drive, drive_scene, parse_frames
from ._errors import SceneError
from ._execute import Executor, LocalExecutor, ProcessExecutor
from ._keys import OUTPUT_COLUMNS, SCENE_KEYS
from ._live import CheckError, Coordinate, LiveScene, PoseResult
from ._motion import Motion, random_motion, read_motion, write_motion
from ._opensim import OpenSimModel
from ._run import REPORT_FIELDS, RunSummary, default_cache_dir, run_batch, run_scene

__all__ = [
    "OUTPUT_COLUMNS",
    "REPORT_FIELDS",
    "SCENE_KEYS",
    "BoneSpec",
    "CheckError",
    "CheckReport",
    "Coordinate",
    "Drive",
    "Executor",
    "Finding",
    "LiveScene",
    "LocalExecutor",
    "Motion",
    "MuscleSpec",
    "OpenSimModel",
    "PoseResult",
    "ProcessExecutor",
    "RunSummary",
    "Scene",
    "SceneError",
    "check_scene",
    "default_cache_dir",
    "drive_scene",
    "load_scene",
    "parse_frames",
    "random_motion",
    "read_motion",
    "run_batch",
    "run_scene",
    "write_motion",
]
