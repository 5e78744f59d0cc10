"""Whole-motion benchmark: ``musclewrap run`` on a scene, cold and warm cache, wall time.

Everything a user waits for is inside the timing (process start, imports, OpenSim, mesh
reading and repair, preparation or cache load, solving, penetration, writing every file,
plots), except the GIF (``--no-gif``), as issue 3 specifies.

    python benchmarks/speed/bench_scene.py examples/lhdl_walk.toml --warm-repeats 3
"""

from __future__ import annotations

import argparse
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path


def run_once(scene: str, out: Path, cache: Path, workers: int | None) -> tuple[float, str]:
    cmd = [sys.executable, "-m", "musclewrap.cli", "run", scene, "-o", str(out), "--no-gif"]
    cmd += ["--cache-dir", str(cache)]
    if workers:
        cmd += ["--workers", str(workers)]
    shutil.rmtree(out, ignore_errors=True)
    t0 = time.perf_counter()
    r = subprocess.run(cmd, capture_output=True, text=True)
    wall = time.perf_counter() - t0
    if r.returncode != 0:
        raise SystemExit(f"run failed ({r.returncode}):\n{r.stderr[-2000:]}")
    return wall, r.stdout


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("scene")
    ap.add_argument("--warm-repeats", type=int, default=3)
    ap.add_argument("--workers", type=int, default=None)
    a = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        cache, out = Path(tmp) / "cache", Path(tmp) / "out"
        cold, text = run_once(a.scene, out, cache, a.workers)
        warm = [run_once(a.scene, out, cache, a.workers)[0] for _ in range(a.warm_repeats)]
        size = sum(f.stat().st_size for f in out.rglob("*") if f.is_file())
        n_files = sum(1 for f in out.rglob("*") if f.is_file())
    print(f"scene {a.scene}, {os.cpu_count()} CPUs, workers {a.workers or 'default'}")
    print(text.strip())
    print(f"cold cache: {cold:.1f} s wall")
    print(
        f"warm cache: median {statistics.median(warm):.1f} s wall over {len(warm)} runs "
        f"({', '.join(f'{w:.1f}' for w in warm)})"
    )
    print(f"output: {n_files} files, {size / 2**20:.0f} MiB")


if __name__ == "__main__":
    main()
