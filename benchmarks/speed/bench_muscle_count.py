"""How contact's cost and rounds grow with the muscles a frame holds: 4, 6, 18 and 19.

    python benchmarks/speed/bench_muscle_count.py [SCENE ...] [--frames 0:211:10] [--repeats 1]

Each scene (default: the LHDL walk's 4 muscles, the gait2392 walk's 6 VHF muscles, the 18 VHF
hip and thigh muscles and the 19-muscle leg with gait2392's femur and pelvis, all on the same
walk) over the same frames, warm (a first run of each way fills the caches), no GIF, 2 workers
(`musclewrap run`'s default), with contact and with ``--no-collisions`` in turns, ``--repeats``
times each. Prints per scene: the muscles and muscle-frames, the median walls and their ratio,
what contact adds a muscle-frame (the difference of the walls over the muscle-frames, times the
2 workers: CPU seconds, the fixed costs of a run cancelled), and from the contact run's
report.csv the rounds a frame (median and most), the largest shape change and the deepest
vertex in another muscle (the run's own measure).
"""

from __future__ import annotations

import argparse
import csv
import statistics
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
SCENES = (
    "examples/lhdl_walk.toml",
    "examples/gait2392_walk.toml",
    "examples/gait2392_hip_thigh.toml",
    "examples/gait2392_leg.toml",
)


def _rows(out: Path) -> list[dict[str, str]]:
    with open(out / "report.csv", newline="") as fh:
        return list(csv.DictReader(fh))


def main() -> None:
    p = argparse.ArgumentParser()
    p.add_argument("scenes", nargs="*", default=list(SCENES))
    p.add_argument("--frames", default="0:211:10")
    p.add_argument("--repeats", type=int, default=1)
    a = p.parse_args()
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # the shared helpers
    from _common import most, timed_run

    print(f"frames {a.frames}, warm, no GIF, 2 workers, {a.repeats} run(s) each way in turns")
    print(
        "| scene | muscles | muscle-frames | contact / --no-collisions | ratio "
        "| contact adds a muscle-frame | rounds a frame (median, most) | shape change "
        "| in another muscle |"
    )
    print("|---|---|---|---|---|---|---|---|---|")
    with tempfile.TemporaryDirectory() as tmp:
        for i, scene in enumerate(a.scenes):
            path = str(ROOT / scene) if not Path(scene).is_absolute() else scene
            on_dir, off_dir = Path(tmp) / f"on{i}", Path(tmp) / f"off{i}"
            args = ["--no-gif", "--frames", a.frames]
            timed_run(path, on_dir, args)  # warm: preparations, bone probes, kernels
            timed_run(path, off_dir, [*args, "--no-collisions"])
            on, off = [], []
            for _ in range(a.repeats):
                on.append(timed_run(path, on_dir, args))
                off.append(timed_run(path, off_dir, [*args, "--no-collisions"]))
            rows = _rows(on_dir)
            muscles = sorted({r["muscle"] for r in rows})
            rounds: dict[str, int] = {}
            for r in rows:
                rounds[r["frame"]] = int(float(r.get("muscle_rounds") or 0))
            t_on, t_off = statistics.median(on), statistics.median(off)
            extra = 2 * (t_on - t_off) / len(rows) * 1000.0
            print(
                f"| {Path(scene).stem} | {len(muscles)} | {len(rows)} | {t_on:.1f} / {t_off:.1f} s "
                f"| {t_on / t_off:.2f}x | {extra:.0f} ms "
                f"| {statistics.median(rounds.values()):g}, {max(rounds.values())} "
                f"| {most(rows, 'shape_change_max'):.3f} "
                f"| {most(rows, 'muscle_overlap_max'):.3f} mm |",
                flush=True,
            )


if __name__ == "__main__":
    main()
