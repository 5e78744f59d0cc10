"""Running a plan's tasks on a ``dask.distributed`` cluster (the ``[dask]`` extra).

The workers write the frame files themselves, into the output folder, and read and
write the preparation cache: both must be paths that every worker reaches under
the same name (a shared file system). Each run checks that before its first task
(`DaskExecutor.check_shared`) and refuses, naming the worker and the folder, where
one does not. A worker that dies mid-task has its task run again on another worker
by the scheduler; the task writes the same files (each one whole, or not at all).
"""

from __future__ import annotations

import contextlib
import dataclasses
import os
import threading
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import Future
from pathlib import Path
from typing import Any

from ._execute import Executor, run_task

__all__ = ["DaskExecutor", "connect"]

_EXTRA = "pip install 'musclewrap[dask]'"


def _distributed() -> Any:
    try:
        import distributed
    except ImportError:
        raise ImportError(
            f"running on a Dask cluster needs dask.distributed: the [dask] extra ({_EXTRA})"
        ) from None
    return distributed


@contextlib.contextmanager
def connect(address: str, *, log: Callable[[str], None] | None = None) -> Iterator[Any]:
    """A client of the Dask scheduler at ``address`` (closed at the end); says its workers."""
    distributed = _distributed()
    try:
        client = distributed.Client(address, timeout="20s")
    except (OSError, TimeoutError) as exc:
        raise OSError(f"no Dask scheduler reachable at {address} ({exc})") from None
    try:
        if log is not None:
            n = len(client.scheduler_info().get("workers", {}))
            log(f"Dask scheduler {address}: {n} worker(s)")
        yield client
    finally:
        client.close()


def _identity(x: Any) -> Any:
    return x


def _run_with_job(task: Any, job: Any) -> Any:
    """On a worker: the task with its muscle's job put back (it travelled once per worker)."""
    return run_task(dataclasses.replace(task, job=job))


def _check_paths(paths: Sequence[str], token: str) -> str | None:
    """On a worker: each folder holds the client's token file, and takes a new file."""
    import socket

    for p in paths:
        probe = Path(p) / f".musclewrap-shared-{token}"
        try:
            if probe.read_text(encoding="utf-8") != token:
                return f"{p}: the worker on {socket.gethostname()} sees another file there"
            mine = Path(p) / f".musclewrap-shared-{token}-{os.getpid()}"
            mine.write_text(token, encoding="utf-8")
            mine.unlink()
        except OSError as exc:
            return (
                f"{p}: not reachable from the Dask worker on {socket.gethostname()} "
                f"({exc.strerror or exc})"
            )
    return None


class DaskExecutor(Executor):
    """The workers of a ``distributed.Client``'s cluster."""

    fine_progress = False
    remote = True

    def __init__(self, client: Any) -> None:
        _distributed()
        self.client = client
        info = client.scheduler_info()
        self.workers = max(1, sum(w.get("nthreads", 1) for w in info.get("workers", {}).values()))
        self.dashboard = getattr(client, "dashboard_link", None)
        self._held: set[Any] = set()
        self._lock = threading.Lock()
        # per muscle job: its future on the cluster and how many submitted tasks use it
        self._jobs: dict[int, list[Any]] = {}

    def submit(self, task: Any) -> Future[Any]:
        """Submit ``task``, its muscle's ``job`` sent once per muscle, not with every chunk.

        The job becomes the result of a task of its own, which the chunks wait for (and
        which the scheduler computes again, like any task, if the worker holding it dies).
        """
        f: Future[Any] = Future()
        job = getattr(task, "job", None)
        with self._lock:
            if job is not None:
                entry = self._jobs.get(id(job))
                if entry is None:
                    entry = [self.client.submit(_identity, job, pure=False), 0, job]
                    self._jobs[id(job)] = entry
                entry[1] += 1
                df = self.client.submit(
                    _run_with_job, dataclasses.replace(task, job=None), entry[0], pure=False
                )
            else:
                df = self.client.submit(run_task, task, pure=False)
            self._held.add(df)

        def done(d: Any) -> None:
            try:
                f.set_result(d.result())
            except BaseException as exc:  # noqa: BLE001  # the task's error, raised by the runner
                f.set_exception(exc)
            finally:
                with self._lock:
                    self._held.discard(d)
                    if job is not None:
                        entry = self._jobs[id(job)]
                        entry[1] -= 1
                        if entry[1] == 0:  # released on the cluster; sent again if needed
                            del self._jobs[id(job)]

        df.add_done_callback(done)
        return f

    def check_shared(self, paths: Sequence[Path]) -> str | None:
        """None if every worker reaches every folder of ``paths``, else what is wrong."""
        token = os.urandom(8).hex()
        written = []
        try:
            for p in paths:
                Path(p).mkdir(parents=True, exist_ok=True)
                probe = Path(p) / f".musclewrap-shared-{token}"
                probe.write_text(token, encoding="utf-8")
                written.append(probe)
            answers = self.client.run(_check_paths, [str(Path(p).resolve()) for p in paths], token)
        finally:
            for w in written:
                w.unlink(missing_ok=True)
        for worker, problem in sorted(answers.items()):
            if problem is not None:
                return (
                    f"{problem}: the Dask workers write the frames and read the cache there, so "
                    "the output folder (-o) and the cache folder (--cache-dir) must be on a file "
                    f"system every worker shares (worker {worker})"
                )
        return None

    def close(self, cancel: bool = False) -> None:
        if cancel:
            with self._lock:
                held = list(self._held)
            if held:
                with contextlib.suppress(Exception):
                    self.client.cancel(held)
