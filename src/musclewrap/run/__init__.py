"""The run: a scene read, planned as tasks, executed on workers, written, checked, viewed live.

`run_scene` and `run_batch` read a scene's meshes and drive (`._read`), plan one job
per muscle and its tasks (`._plan`, records in `._records`), hand them to an executor
(`._execute`: this process, worker processes, or a Dask cluster, `._dask`), solve each
frame (`._work`: a muscle alone or the muscles of a frame together, with contact), and
write the files (`._write`, `._fibres`; `._journal` lets an interrupted run go on).
`check_scene` says what would make a run wrong before it starts, `verify_run` measures
a finished run independently, and `LiveScene` solves one pose at a time for the viewer.
"""

from ._check import CheckReport, Finding, check_scene
from ._dask import DaskExecutor, connect
from ._execute import Executor, LocalExecutor, Node, ProcessExecutor, Runner, run_task
from ._live import CheckError, Coordinate, LiveScene, PoseResult, refusal
from ._run import (
    REPORT_FIELDS,
    RunOptions,
    RunSummary,
    default_cache_dir,
    local_executor,
    run_batch,
    run_scene,
)
from ._verify import inside_depth, inside_depths, muscle_overlaps, verify_run

__all__ = [
    "REPORT_FIELDS",
    "CheckError",
    "CheckReport",
    "Coordinate",
    "DaskExecutor",
    "Executor",
    "Finding",
    "LiveScene",
    "LocalExecutor",
    "Node",
    "PoseResult",
    "ProcessExecutor",
    "RunOptions",
    "RunSummary",
    "Runner",
    "check_scene",
    "connect",
    "default_cache_dir",
    "inside_depth",
    "inside_depths",
    "local_executor",
    "muscle_overlaps",
    "refusal",
    "run_batch",
    "run_scene",
    "run_task",
    "verify_run",
]
