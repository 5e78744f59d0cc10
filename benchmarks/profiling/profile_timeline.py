"""Where the wall time of `musclewrap run` goes: each task's span in the worker processes.

    python benchmarks/profiling/profile_timeline.py [SCENE] [-- RUN ARGS ...]
    python benchmarks/profiling/profile_timeline.py examples/lhdl_walk.toml -- --no-collisions

Runs ``musclewrap run SCENE -o TMP RUN ARGS`` as a user types it, in a new process whose
workers record when each task (`musclewrap.run._execute.run_task`) starts and ends (a
``sitecustomize`` on ``PYTHONPATH`` wraps it; nothing of the package changes). Prints the
command's wall time; the start (command to the first task); per kind of task, how many, their
seconds in all and from the first one's start to the last one's end; and the end (the last
task to the command's exit: the report, plots and GIF written in the command's process).
Run it twice for warm caches: the first run of a scene prepares its muscles.
"""

from __future__ import annotations

import argparse
import collections
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]

_HOOK = """
import os, time
from musclewrap.run import _execute
_run = _execute.run_task
def run_task(task):
    t0 = time.time()
    try:
        return _run(task)
    finally:
        with open(os.environ["MUSCLEWRAP_TIMELINE"], "a") as fh:
            fh.write(f"{os.getpid()} {type(task).__name__} {t0!r} {time.time()!r}\\n")
_execute.run_task = run_task
"""


def main() -> None:
    p = argparse.ArgumentParser()
    p.add_argument("scene", nargs="?", default=str(ROOT / "examples" / "lhdl_walk.toml"))
    p.add_argument("run_args", nargs=argparse.REMAINDER)
    a = p.parse_args()
    extra = [x for x in a.run_args if x != "--"]
    with tempfile.TemporaryDirectory() as tmp:
        hook = Path(tmp) / "hook"
        hook.mkdir()
        (hook / "sitecustomize.py").write_text(_HOOK)
        log = Path(tmp) / "timeline.txt"
        env = dict(os.environ, MUSCLEWRAP_TIMELINE=str(log))
        env["PYTHONPATH"] = os.pathsep.join([str(hook)] + [x for x in [env.get("PYTHONPATH")] if x])
        # the console script beside this interpreter, as a user types it
        exe = Path(sys.executable).with_name("musclewrap")
        cmd = [str(exe), "run", a.scene, "-o", str(Path(tmp) / "out")]
        t0 = time.time()
        done = subprocess.run(cmd + extra, env=env, capture_output=True, text=True)
        if done.returncode:
            sys.exit(f"{' '.join(cmd + extra)} failed:\n{done.stderr}")
        t1 = time.time()
        rows = [line.split() for line in log.read_text().splitlines()] if log.exists() else []
    spans = collections.defaultdict(list)
    for _, kind, s, e in rows:
        spans[kind].append((float(s) - t0, float(e) - t0))
    print(f"musclewrap run {Path(a.scene).name} {' '.join(extra)}: {t1 - t0:.2f} s wall")
    if not rows:
        print("  no task ran in a worker (--workers 1 runs them in the command's process)")
        return
    first = min(s for v in spans.values() for s, _ in v)
    last = max(e for v in spans.values() for _, e in v)
    print(f"  start: the command to its first task      {first:6.2f} s")
    for kind, v in sorted(spans.items(), key=lambda kv: min(s for s, _ in kv[1])):
        busy = sum(e - s for s, e in v)
        lo, hi = min(s for s, _ in v), max(e for _, e in v)
        print(f"  {kind:<14} {len(v):4d} tasks, {busy:6.2f} s in all, {lo:6.2f} .. {hi:6.2f} s")
    print(f"  end: its last task to the command's exit  {t1 - t0 - last:6.2f} s")


if __name__ == "__main__":
    main()
