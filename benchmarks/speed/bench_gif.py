"""What the GIF costs a scene run: the run with its default pictures against ``--no-gif``.

    python benchmarks/speed/bench_gif.py [SCENE] [--repeats 3]

Runs the scene warm (preparations cached by a first run) with its default GIF and with
``--no-gif``, alternately, ``--repeats`` times each, and prints the medians and their ratio.
"""

from __future__ import annotations

import argparse
import statistics
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def main() -> None:
    p = argparse.ArgumentParser()
    p.add_argument("scene", nargs="?", default=str(ROOT / "examples" / "lhdl_walk.toml"))
    p.add_argument("--repeats", type=int, default=3)
    a = p.parse_args()
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # the shared helpers
    from _common import timed_run

    with tempfile.TemporaryDirectory() as tmp:
        gif, plain = Path(tmp) / "gif", Path(tmp) / "plain"
        timed_run(a.scene, plain, ["--no-gif"])  # warm: preparations cached
        t_gif, t_plain = [], []
        for _ in range(a.repeats):
            t_gif.append(timed_run(a.scene, gif, []))
            t_plain.append(timed_run(a.scene, plain, ["--no-gif"]))
        if not (gif / "scene.gif").is_file():
            raise SystemExit("no scene.gif written (no off-screen rendering here?)")
    m_gif, m_plain = statistics.median(t_gif), statistics.median(t_plain)
    print(f"{a.scene}: warm, {a.repeats} runs each, alternating")
    print(
        f"  with scene.gif: median {m_gif:.1f} s; --no-gif: {m_plain:.1f} s; {m_gif / m_plain:.2f}x"
    )


if __name__ == "__main__":
    main()
