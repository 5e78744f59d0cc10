"""What the GIF costs a scene run: the run with its default pictures against ``--no-gif``.

    python benchmarks/bench_gif.py [SCENE] [--repeats 3]

Runs the scene warm (preparations cached by a first run) with its default GIF and with
``--no-gif``, alternately, ``--repeats`` times each, and prints the medians and their ratio.
"""

from __future__ import annotations

import argparse
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def _run(scene: str, out: Path, extra: list[str]) -> float:
    cmd = [sys.executable, "-m", "musclewrap.cli", "run", scene, "-o", str(out), *extra]
    t0 = time.perf_counter()
    subprocess.run(cmd, check=True, capture_output=True)
    return time.perf_counter() - t0


def main() -> None:
    p = argparse.ArgumentParser()
    p.add_argument("scene", nargs="?", default=str(ROOT / "examples" / "lhdl_walk.toml"))
    p.add_argument("--repeats", type=int, default=3)
    a = p.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        gif, plain = Path(tmp) / "gif", Path(tmp) / "plain"
        _run(a.scene, plain, ["--no-gif"])  # warm: preparations cached
        t_gif, t_plain = [], []
        for _ in range(a.repeats):
            t_gif.append(_run(a.scene, gif, []))
            t_plain.append(_run(a.scene, plain, ["--no-gif"]))
        if not (gif / "scene.gif").is_file():
            raise SystemExit("no scene.gif written (no off-screen rendering here?)")
    m_gif, m_plain = statistics.median(t_gif), statistics.median(t_plain)
    print(f"{a.scene}: warm, {a.repeats} runs each, alternating")
    print(
        f"  with scene.gif: median {m_gif:.1f} s; --no-gif: {m_plain:.1f} s; {m_gif / m_plain:.2f}x"
    )


if __name__ == "__main__":
    main()
