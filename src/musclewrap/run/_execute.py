"""Executing a plan: one interface over where tasks run, one loop that feeds it.

An `Executor` runs a task (`._work`: an object with ``run()``) and gives a
`concurrent.futures.Future` of its result. Three stand behind the same interface:

- `LocalExecutor`: in this process, at once (``--workers 1``);
- `ProcessExecutor`: spawned worker processes on this machine (the default);
- `DaskExecutor` (`._dask`): the workers of a ``dask.distributed`` cluster.

`Runner` holds the plan's tasks (`Node`: a task, or a function that makes it from
the results of the nodes it waits for) and hands each to the executor once the
nodes it waits for are done, so that a batch of scenes, the chunks of a muscle and,
later, muscles placed in an order against each other all go through one loop.
"""

from __future__ import annotations

import contextlib
import heapq
import os
import queue as queue_mod
import threading
import time
from collections.abc import Callable, Hashable, Iterable, Sequence
from concurrent.futures import Future
from concurrent.futures.process import BrokenProcessPool
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ._work import set_tick

__all__ = ["Executor", "LocalExecutor", "Node", "ProcessExecutor", "Runner", "run_task"]


def run_task(task: Any) -> Any:
    """What every executor calls: the task's ``run()``, on one BLAS thread.

    OpenBLAS's products and factorisations round differently on different
    numbers of threads (a worker gets the machine's cores divided by the
    workers): on one thread, always, a frame's files are the same bytes on any
    number of workers, here or on a cluster. The compiled kernels sum in fixed
    chunks and take every thread they are given.
    """
    from threadpoolctl import threadpool_limits

    with threadpool_limits(1, user_api="blas"):
        return task.run()


#: a worker pool that lost a process, said the same wherever the run finds out
_DIED = (
    "a worker process died without a Python error (out of memory, a crash in a compiled "
    "library, or, from a Python script or standard input, run_scene called outside an "
    "`if __name__ == '__main__':` block); rerun with --workers 1 to see where"
)


class Executor:
    """Where tasks run.

    Attributes
    ----------
    workers : int
        How many tasks run at once.
    fine_progress : bool
        True when `ticks` reports every frame; else the runner counts a chunk's
        frames when it comes back.
    remote : bool
        True when workers may run on other machines (the output and cache folders
        must then be paths every worker shares).
    """

    workers: int = 1
    fine_progress: bool = True
    remote: bool = False
    dashboard: str | None = None

    def submit(self, task: Any) -> Future[Any]:
        raise NotImplementedError

    def attach(self, progress: Callable[[int], None] | None) -> None:
        """Where frames done in this process go at once (only `LocalExecutor` has any)."""

    def step(self) -> bool:
        """Run one queued task in this process, if this executor runs any here."""
        return False

    def result(self, future: Future[Any]) -> Any:
        """A finished task's result (raises its error, in words a user can act on)."""
        return future.result()

    def check_shared(self, paths: Sequence[Path]) -> str | None:
        """None if every worker reaches every folder of ``paths`` (here: they all do)."""
        return None

    def ticks(self, timeout: float | None) -> int:
        """Frames done since the last call (waits up to ``timeout`` for the first)."""
        if timeout:
            time.sleep(timeout)
        return 0

    def close(self, cancel: bool = False) -> None:
        """Stop the workers (``cancel``: drop queued tasks)."""

    def __enter__(self) -> Executor:
        return self

    def __exit__(self, kind: object, *_: object) -> None:
        self.close(cancel=kind is not None)


class _Sink:
    def __init__(self) -> None:
        self.progress: Callable[[int], None] | None = None

    def put(self, n: int) -> None:
        if self.progress is not None:
            self.progress(n)


class LocalExecutor(Executor):
    """Runs the tasks in this process, one per `step` (the runner's loop calls it)."""

    def __init__(self) -> None:
        self._sink = _Sink()
        self._queue: list[tuple[Any, Future[Any]]] = []

    def attach(self, progress: Callable[[int], None] | None) -> None:
        self._sink.progress = progress

    def submit(self, task: Any) -> Future[Any]:
        f: Future[Any] = Future()
        self._queue.append((task, f))
        return f

    def step(self) -> bool:
        if not self._queue:
            return False
        task, f = self._queue.pop(0)
        set_tick(self._sink)
        try:
            f.set_result(run_task(task))
        except Exception as exc:  # noqa: BLE001  # raised where the runner takes the result
            f.set_exception(exc)
        finally:
            set_tick(None)
        return True


def _init_worker(queue: Any, threads: int) -> None:
    set_tick(queue)
    # Ticks are progress only: a worker exits without flushing those nobody read (more
    # than its pipe holds, unread, kept it waiting at exit and the run with it).
    queue.cancel_join_thread()
    # A failing initializer breaks the whole pool: thread limits are best effort.
    try:
        import numba

        numba.set_num_threads(max(1, min(threads, numba.config.NUMBA_NUM_THREADS)))
        from threadpoolctl import threadpool_limits

        threadpool_limits(threads)
    except Exception:  # pragma: no cover  # noqa: BLE001
        pass


def warm_up() -> None:
    """Import what the tasks need (a worker does this while the client reads the scene)."""
    import igl  # noqa: F401


class ProcessExecutor(Executor):
    """Spawned worker processes on this machine, with a queue for the frames-done ticks."""

    def __init__(self, n: int) -> None:
        import multiprocessing as mp
        from concurrent.futures import ProcessPoolExecutor

        ctx = mp.get_context("spawn")
        self.queue = ctx.Queue()
        threads = max(1, (os.cpu_count() or 1) // n)
        self.pool = ProcessPoolExecutor(
            max_workers=n, mp_context=ctx, initializer=_init_worker, initargs=(self.queue, threads)
        )
        self.workers = n
        # one task per worker starts them all now, each importing what the tasks need
        for _ in range(n):
            self.pool.submit(warm_up)

    def submit(self, task: Any) -> Future[Any]:
        try:
            return self.pool.submit(run_task, task)
        except BrokenProcessPool:
            raise RuntimeError(_DIED) from None

    def ticks(self, timeout: float | None) -> int:
        n = 0
        try:
            n += self.queue.get(timeout=timeout) if timeout else self.queue.get_nowait()
            while True:
                n += self.queue.get_nowait()
        except queue_mod.Empty:
            pass
        return n

    def result(self, future: Future[Any]) -> Any:
        try:
            return future.result()
        except BrokenProcessPool:
            raise RuntimeError(_DIED) from None

    def close(self, cancel: bool = False) -> None:
        # On an error, queued work is dropped, but the workers are still waited for: one
        # left starting up after this process unlinked the queue's semaphore would print
        # a traceback of its own.
        self.pool.shutdown(wait=True, cancel_futures=cancel)


#: the priority from which a ready task is handed out only to an idle worker (`Runner`)
LATE = 4


@dataclass
class Node:
    """One task of a plan.

    Parameters
    ----------
    key : hashable
        Unique in the plan.
    task : object with ``run()``, or callable
        The task; or a function of the results of ``after`` (a dict by key) that
        makes it, called once they are done.
    after : tuple of keys
        Nodes that must be done first.
    done : callable, optional
        Called in this process with the result (e.g. to record it in the journal).
    result : object, optional
        Set for a node already done (kept from an interrupted run): not run.
    frames : int
        Muscle-frames the task covers (for the progress where the executor reports
        whole tasks only).
    priority : int
        Among ready tasks, lower goes first (reading a scene before deforming the
        last one: the workers never wait for the main process to plan); from `LATE`
        on, a task waits for an idle worker rather than queue in the pool.
    """

    key: Hashable
    task: Any
    after: tuple[Hashable, ...] = ()
    done: Callable[[Any], Any] | None = None
    result: Any = None
    finished: bool = False
    frames: int = 0
    priority: int = 2
    future: Future[Any] | None = field(default=None, repr=False)


class Runner:
    """Feeds nodes to an executor as their dependencies finish; collects their results.

    Each node counts the nodes it still waits for; a finished node's future puts it on
    a queue (from whichever thread completes it), and `poll` takes the queue in: the
    cost per task is constant, whatever the plan's size.
    """

    def __init__(self, executor: Executor, progress: Callable[[int], None] | None) -> None:
        self.executor = executor
        self.progress = progress
        self.nodes: dict[Hashable, Node] = {}
        self.waiting: dict[Hashable, int] = {}  # unfinished dependencies of pending nodes
        self.dependents: dict[Hashable, list[Hashable]] = {}
        self.ready: list[tuple[int, int, Node]] = []  # a heap: (priority, order, node)
        self.running = 0
        self.count = 0
        # tasks handed out at once: enough to keep every worker busy, few enough that a
        # task of higher priority made ready later does not queue behind all the rest
        self.capacity = max(1, 2 * executor.workers)
        self.finished_q: queue_mod.SimpleQueue[Node] = queue_mod.SimpleQueue()
        executor.attach(progress)

    def add(self, nodes: Iterable[Node]) -> None:
        """Add nodes (their ``after`` must name nodes added already, or with them).

        A node whose key is taken already is the same work (a muscle or bone that two
        scenes of a batch share): it is not added again.
        """
        new = []
        for n in nodes:
            if n.key in self.nodes:
                continue
            self.nodes[n.key] = n
            new.append(n)
        for n in new:
            if n.finished:
                self._count(n.frames)
                continue
            missing = [a for a in n.after if a not in self.nodes]
            if missing:
                raise ValueError(f"the task {n.key!r} waits for unknown tasks {missing!r}")
            left = [a for a in n.after if not self.nodes[a].finished]
            self.waiting[n.key] = len(left)
            for a in left:
                self.dependents.setdefault(a, []).append(n.key)
            if not left:
                self._ready(n)
        self._submit()

    def _ready(self, n: Node) -> None:
        self.count += 1
        heapq.heappush(self.ready, (n.priority, self.count, n))

    def result(self, key: Hashable) -> Any:
        return self.nodes[key].result

    def release(self, keys: Iterable[Hashable]) -> None:
        """Drop the results of finished nodes once used (they stay done: not run again).

        No node may wait for them afterwards. A batch's main process would otherwise hold
        every scene's pictures to its end.
        """
        for k in keys:
            n = self.nodes[k]
            if not n.finished:
                raise ValueError(f"the task {k!r} is not done")
            n.result = None

    def _count(self, frames: int) -> None:
        if self.progress is not None and frames:
            self.progress(frames)

    def _submit(self) -> None:
        while self.ready and self.running < self.capacity:
            if self.ready[0][0] >= LATE and self.running >= self.executor.workers:
                # the last tasks of a scene (its pictures) only to an idle worker: queued in
                # the pool, they held its paper comparison, and the report and plots that
                # wait for it, behind them (the LHDL walk's end, 4.0 s after its last task)
                break
            n = heapq.heappop(self.ready)[2]
            del self.waiting[n.key]
            task = n.task
            if not hasattr(task, "run"):
                task = task({a: self.nodes[a].result for a in n.after})
            n.future = self.executor.submit(task)
            self.running += 1
            n.future.add_done_callback(lambda _, n=n: self.finished_q.put(n))

    def poll(self, timeout: float = 0.05) -> None:
        """Take in what finished (waiting up to ``timeout`` for something), submit what is ready."""
        self.executor.step()
        idle = self.running > 0 and self.finished_q.empty()
        if self.executor.fine_progress:
            # read even with no display, so the workers' ticks never pile up unread
            n = self.executor.ticks(timeout if idle else None)
            if n and self.progress is not None:
                self.progress(n)
            idle = False
        while True:
            try:
                node = (
                    self.finished_q.get(timeout=timeout) if idle else self.finished_q.get_nowait()
                )
            except queue_mod.Empty:
                break
            idle = False
            self._take(node)
        self._submit()

    def _take(self, node: Node) -> None:
        self.running -= 1
        result = self.executor.result(node.future)  # type: ignore[arg-type]  # raises its error
        node.future = None
        if node.done is not None:
            result = node.done(result)
        node.result, node.finished = result, True
        if not self.executor.fine_progress:
            self._count(node.frames)
        for k in self.dependents.pop(node.key, ()):
            self.waiting[k] -= 1
            if self.waiting[k] == 0:
                self._ready(self.nodes[k])

    def busy(self, keys: Iterable[Hashable] | None = None) -> bool:
        """Whether any of ``keys`` (default: any node) is not done yet."""
        if keys is None:
            return bool(self.waiting or self.running)
        return not all(self.nodes[k].finished for k in keys)

    def wait(self, keys: Iterable[Hashable] | None = None) -> None:
        keys = None if keys is None else list(keys)
        while self.busy(keys):
            if self.waiting and not self.running and not self.ready:
                raise RuntimeError(
                    "tasks wait for each other: "
                    + ", ".join(repr(k) for k in list(self.waiting)[:5])
                )
            self.poll()
        if self.progress is not None and self.executor.fine_progress:  # the last ticks
            n = self.executor.ticks(None)
            if n:
                self.progress(n)


def import_plotting_meanwhile() -> None:
    """Import matplotlib in a thread (this process waits for workers meanwhile)."""

    def go() -> None:
        with contextlib.suppress(Exception):
            import matplotlib

            matplotlib.use("Agg")
            import matplotlib.pyplot  # noqa: F401

    threading.Thread(target=go, daemon=True).start()
