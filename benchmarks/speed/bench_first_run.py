"""A new user's first `musclewrap demo` against the second, wall time.

    python benchmarks/speed/bench_first_run.py [--no-gif | --kernels | --each | --sides [--repeats N]]

Emulates a fresh install: Numba's cache (``NUMBA_CACHE_DIR``) and musclewrap's
(``MUSCLEWRAP_CACHE``) point at empty folders, then
``musclewrap demo`` runs twice in new processes, the first compiling the kernels, the second
reading them back. (Python's own bytecode is left as it is: pip compiles it when installing.) Prints both wall
times and their ratio (issue 15's target: the first <= 3x the second).

``--each``: every kernel of `musclewrap._jit.KERNELS` compiled in turn in one fresh process
with an empty cache (Numba's own start paid first, on a trivial kernel), the slowest first.

``--sides``: a first run's two shares of the kernels (`musclewrap._jit.compile_here` and the
helper's `_COMPILE_HELPER`) started together in two fresh processes on one empty cache, as
a first run starts them: each side's seconds and the wall time until both are done,
``--repeats`` times. To compare a checkout, run it with ``PYTHONPATH=CHECKOUT/src``.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

_EACH = """
import importlib, time
import numba
from numba.core.sigutils import normalize_signature
from musclewrap._jit import KERNELS
numba.njit(lambda x: x + 1)(1)
rows = []
for group, kernels in KERNELS.items():
    for module, name, signature in kernels:
        k = getattr(importlib.import_module(f"musclewrap.{module}"), name)
        t = time.perf_counter()
        k.compile(tuple(normalize_signature(signature)[0]))
        rows.append((time.perf_counter() - t, group, name))
for dt, group, name in sorted(rows, reverse=True):
    print(f"{dt:6.2f} s  {group:<12} {name}")
print(f"{sum(r[0] for r in rows):6.2f} s  all")
"""


def main() -> None:
    p = argparse.ArgumentParser()
    p.add_argument("--no-gif", action="store_true")
    p.add_argument(
        "--kernels",
        action="store_true",
        help="instead: seconds to compile each group of musclewrap._jit.KERNELS, and all, "
        "each in a fresh process with an empty cache (after the imports)",
    )
    p.add_argument("--each", action="store_true", help="instead: seconds to compile each kernel")
    p.add_argument("--sides", action="store_true", help="instead: both shares of a first run")
    p.add_argument("--repeats", type=int, default=1)
    a = p.parse_args()
    if a.each:
        with tempfile.TemporaryDirectory() as tmp:
            env = {**os.environ, "NUMBA_CACHE_DIR": tmp}
            r = subprocess.run([sys.executable, "-c", _EACH], env=env, capture_output=True,
                               text=True, check=True)  # fmt: skip
        print(r.stdout, end="")
        return
    if a.sides:
        for _ in range(a.repeats):
            _sides()
        return
    if a.kernels:
        for group in ("pose", "preparation", "contact", None):
            with tempfile.TemporaryDirectory() as tmp:
                code = (
                    "import time; from musclewrap._jit import compile_kernels\n"
                    f"t = time.perf_counter(); compile_kernels({group!r})\n"
                    "print(time.perf_counter() - t)"
                )
                env = {**os.environ, "NUMBA_CACHE_DIR": tmp}
                r = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True,
                                   text=True, check=True)  # fmt: skip
            print(f"compile {group or 'all'}: {float(r.stdout.split()[-1]):.1f} s")
        return
    with tempfile.TemporaryDirectory() as tmp:
        env = dict(os.environ)
        env["NUMBA_CACHE_DIR"] = str(Path(tmp) / "numba")
        # the preparations' cache empty too: a new user's first run prepares the muscles
        env["MUSCLEWRAP_CACHE"] = str(Path(tmp) / "cache")
        cmd = [sys.executable, "-m", "musclewrap.cli", "demo", "-o", str(Path(tmp) / "out")]
        cmd += ["--no-gif"] if a.no_gif else []
        times = []
        for _ in range(2):
            t0 = time.perf_counter()
            r = subprocess.run(cmd, env=env, capture_output=True, text=True, check=True)
            times.append(time.perf_counter() - t0)
        said = "compiling kernels, once" in r.stderr
    first, second = times
    print(
        f"musclewrap demo{' --no-gif' if a.no_gif else ''}: first {first:.1f} s, second "
        f"{second:.1f} s, {first / second:.1f}x"
        + ("" if not said else " (the second said it compiled: the cache was not kept)")
    )


def _sides() -> None:
    timed = (
        "import sys, time; from musclewrap import _jit; t = time.perf_counter(); "
        "_jit.compile_here() if sys.argv[1] == 'here' else exec(_jit._COMPILE_HELPER); "
        "print(time.perf_counter() - t)"
    )
    with tempfile.TemporaryDirectory() as tmp:
        env = {**os.environ, "NUMBA_CACHE_DIR": tmp}
        t0 = time.perf_counter()
        procs = {
            side: subprocess.Popen([sys.executable, "-c", timed, side], env=env,
                                   stdout=subprocess.PIPE, text=True)
            for side in ("here", "helper")
        }  # fmt: skip
        took = {side: float(p.communicate()[0].split()[-1]) for side, p in procs.items()}
        wall = time.perf_counter() - t0
    print(
        f"compile, both shares together: the run's {took['here']:.1f} s, the helper's "
        f"{took['helper']:.1f} s, both done {wall:.1f} s"
    )


if __name__ == "__main__":
    main()
