"""Batches and executors (issue 13): walk, strong scaling, Dask, scheduling cost.

The local walk against an earlier commit, strong scaling of a 4-scene batch, the Dask
cluster against local processes, and the cost of scheduling a task.

    python benchmarks/speed/bench_batch.py --baseline d10dc57 --repeats 5

Every run is ``musclewrap run ... --no-gif`` in a fresh process with a warm cache (one
cold run first), wall time; the cases of a comparison alternate, and medians are
quoted. Parts:

- ``walk``: ``examples/lhdl_walk.toml`` at this checkout against ``--baseline`` (a git
  revision, checked out into a temporary worktree and run from its own sources);
- ``scaling``: four copies of the walk scene (different file names: one batch, four
  output folders, one preparation per muscle) on ``--workers 1`` and ``--workers 2``;
- ``dask``: the walk on a Dask cluster of two one-thread workers started here
  (``dask scheduler`` / ``dask worker``, loopback) against the local default;
- ``overhead``: 400 empty tasks through each executor, per task (the scheduling cost);
- ``phases``: the walk in this process with 2 workers, cold cache then warm: the seconds
  the main process spends reading (with the reading tasks it waits for), writing the bones'
  display meshes and writing the series, report and plots; output bytes per muscle-frame.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import signal
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
WALK = ROOT / "examples" / "lhdl_walk.toml"


def run(args: list[str], env: dict[str, str] | None = None) -> tuple[float, str]:
    cmd = [sys.executable, "-m", "musclewrap.cli", "run", *args, "--no-gif"]
    t0 = time.perf_counter()
    r = subprocess.run(cmd, capture_output=True, text=True, env=env)
    wall = time.perf_counter() - t0
    if r.returncode != 0:
        raise SystemExit(f"{' '.join(cmd)} failed ({r.returncode}):\n{r.stderr[-3000:]}")
    return wall, r.stdout


def alternate(cases: dict[str, tuple[list[str], dict[str, str] | None]], repeats: int) -> dict:
    for args, env in cases.values():  # cold caches, compiled kernels
        run(args, env)
    times: dict[str, list[float]] = {k: [] for k in cases}
    for _ in range(repeats):
        for k, (args, env) in cases.items():
            times[k].append(run(args, env)[0])
    return times


def show(title: str, times: dict[str, list[float]], ref: str) -> None:
    print(title)
    med = {k: statistics.median(v) for k, v in times.items()}
    for k, v in times.items():
        print(
            f"  {k:28s} median {med[k]:6.1f} s  ({', '.join(f'{x:.1f}' for x in v)})"
            + ("" if k == ref else f"  {med[k] / med[ref]:.2f}x of {ref}")
        )


def part_walk(tmp: Path, baseline: str, repeats: int) -> None:
    tree = tmp / "baseline"
    subprocess.run(["git", "-C", str(ROOT), "worktree", "add", "-f", "--detach", str(tree), baseline],
                   check=True, capture_output=True)  # fmt: skip
    try:
        env = {**os.environ, "PYTHONPATH": str(tree / "src")}
        cache = str(tmp / "cache-walk")
        times = alternate(
            {
                f"baseline {baseline}": (
                    [str(WALK), "-o", str(tmp / "o1"), "--cache-dir", cache],
                    env,
                ),
                "this checkout": ([str(WALK), "-o", str(tmp / "o2"), "--cache-dir", cache], None),
            },
            repeats,
        )
        show("walk, local default (warm, no GIF):", times, f"baseline {baseline}")
    finally:
        subprocess.run(["git", "-C", str(ROOT), "worktree", "remove", "--force", str(tree)],
                       capture_output=True)  # fmt: skip


def four_scenes(tmp: Path) -> list[str]:
    # beside examples/, so that the scene's relative data paths hold
    d = Path(tempfile.mkdtemp(prefix=".bench-batch-", dir=ROOT))
    out = []
    for s in ("a", "b", "c", "d"):
        p = d / f"walk_{s}.toml"
        shutil.copy(WALK, p)
        out.append(str(p))
    return out


def part_scaling(tmp: Path, repeats: int) -> None:
    scenes = four_scenes(tmp)
    try:
        cache = str(tmp / "cache-scaling")
        times = alternate(
            {
                f"{w} worker(s)": (
                    [
                        *scenes,
                        "-o",
                        str(tmp / f"batch{w}"),
                        "--cache-dir",
                        cache,
                        "--workers",
                        str(w),
                    ],
                    None,
                )
                for w in (1, 2)
            },
            repeats,
        )
        show("4-scene batch (4 x the walk, 3,376 muscle-frames):", times, "1 worker(s)")
        med = {k: statistics.median(v) for k, v in times.items()}
        print(f"  strong scaling 1 -> 2 workers: {med['1 worker(s)'] / med['2 worker(s)']:.2f}x")
    finally:
        shutil.rmtree(Path(scenes[0]).parent, ignore_errors=True)


class Cluster:
    """``dask scheduler`` and two one-thread ``dask worker`` processes on this machine."""

    def __init__(self, tmp: Path) -> None:
        f = tmp / "scheduler.json"
        self.procs = [self._start(["scheduler", "--scheduler-file", str(f), "--host", "127.0.0.1",
                                   "--port", "0", "--dashboard-address", ":0"])]  # fmt: skip
        while not f.is_file():
            time.sleep(0.1)
        self.address = json.loads(f.read_text())["address"]
        for _ in range(2):
            self.procs.append(self._start(["worker", "--scheduler-file", str(f), "--nthreads", "1",
                                           "--host", "127.0.0.1"]))  # fmt: skip
        import distributed

        with distributed.Client(self.address) as c:
            c.wait_for_workers(2, timeout=120)

    @staticmethod
    def _start(args: list[str]) -> subprocess.Popen:
        return subprocess.Popen([sys.executable, "-m", "dask", *args], stdout=subprocess.DEVNULL,
                                stderr=subprocess.DEVNULL, start_new_session=True)  # fmt: skip

    def close(self) -> None:
        """Stop the scheduler and the workers."""
        for p in self.procs:
            os.killpg(p.pid, signal.SIGTERM)
        for p in self.procs:
            p.wait()


def part_dask(tmp: Path, repeats: int) -> None:
    cluster = Cluster(tmp)
    try:
        cache = str(tmp / "cache-dask")
        times = alternate(
            {
                "local processes (default)": (
                    [str(WALK), "-o", str(tmp / "l"), "--cache-dir", cache],
                    None,
                ),
                "dask, 2 workers (loopback)": (
                    [
                        str(WALK),
                        "-o",
                        str(tmp / "d"),
                        "--cache-dir",
                        cache,
                        "--scheduler",
                        cluster.address,
                    ],
                    None,
                ),
            },
            repeats,
        )
        show("walk on a Dask cluster against local processes:", times, "local processes (default)")
    finally:
        cluster.close()


class _Empty:
    def run(self) -> None:
        return None


def part_overhead(tmp: Path, n: int = 400) -> None:
    import distributed

    from musclewrap.run import DaskExecutor, Node, Runner
    from musclewrap.scene import ProcessExecutor

    def per_task(ex: object) -> float:
        runner = Runner(ex, None)  # type: ignore[arg-type]
        runner.add([Node(("warm", i), _Empty()) for i in range(8)])
        runner.wait()
        t0 = time.perf_counter()
        runner.add([Node(i, _Empty()) for i in range(n)])
        runner.wait()
        return (time.perf_counter() - t0) / n

    with ProcessExecutor(2) as ex:
        pool = per_task(ex)
    cluster = Cluster(tmp)
    try:
        with distributed.Client(cluster.address) as c, DaskExecutor(c) as ex:
            dask = per_task(ex)
    finally:
        cluster.close()
    print(f"scheduling an empty task, {n} in a row through the runner:")
    print(
        f"  local processes {pool * 1e3:.2f} ms per task; Dask (loopback) {dask * 1e3:.2f} ms per task"
    )


def part_phases(tmp: Path) -> None:
    import musclewrap.run._run as run
    from musclewrap.scene import load_scene, run_batch

    spent: dict[str, float] = {}

    def timed(name: str) -> None:
        f = getattr(run, name)

        def g(*a: object, **k: object) -> object:
            t = time.perf_counter()
            out = f(*a, **k)
            spent[name] = spent.get(name, 0.0) + time.perf_counter() - t
            return out

        setattr(run, name, g)

    for name in ("read_inputs", "write_bones", "write_outputs"):
        timed(name)
    scene = load_scene(WALK)
    for label in ("cold", "warm"):
        spent.clear()
        out = tmp / f"phases-{label}"
        t = time.perf_counter()
        s = run_batch([scene], [out], workers=2, progress=None, render=False,
                      cache_dir=tmp / "cache-phases")[0]  # fmt: skip
        wall = time.perf_counter() - t
        size = sum(f.stat().st_size for f in out.rglob("*") if f.is_file())
        print(
            f"walk, {label} cache, 2 workers: {wall:.1f} s; main process: "
            + ", ".join(f"{k} {v:.2f} s" for k, v in spent.items())
            + f"; {size / len(s.rows) / 1e3:.0f} KB per muscle-frame"
        )


def main() -> None:
    ap = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    ap.add_argument("--baseline", default=None, help="git revision for the walk's comparison")
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--parts", default="walk,scaling,dask,overhead,phases")
    a = ap.parse_args()
    parts = a.parts.split(",")
    print(f"{os.cpu_count()} CPUs; warm caches, no GIF, cases alternating, {a.repeats} runs each")
    with tempfile.TemporaryDirectory() as t:
        tmp = Path(t)
        if "walk" in parts and a.baseline:
            part_walk(tmp, a.baseline, a.repeats)
        if "scaling" in parts:
            part_scaling(tmp, a.repeats)
        if "dask" in parts:
            part_dask(tmp, a.repeats)
        if "overhead" in parts:
            part_overhead(tmp)
        if "phases" in parts:
            part_phases(tmp)


if __name__ == "__main__":
    main()
