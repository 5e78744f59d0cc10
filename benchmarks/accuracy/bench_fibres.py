"""Fibres of a scene's muscles carried through a few frames, checked inside the muscle.

    python benchmarks/accuracy/bench_fibres.py [SCENE] [--frames 0:211:105] [--count 100]

Runs the scene's frames in one process, keeps each muscle's prepared and bound
deformer, builds its fibres at rest (`musclewrap.fibres.fibres_at_rest`, default
100 fibres of 15 points) and deforms them with every frame: prints per muscle the time
to build them, their rest lengths, the attachment areas' sizes and the smallest
generalized winding number of a fibre point in the deformed muscle (inside: > 0.5),
or why no fibres could be built.
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def main() -> None:
    import igl

    import musclewrap.run._work as work
    from musclewrap.fibres import fibres_at_rest
    from musclewrap.scene import load_scene, run_scene

    p = argparse.ArgumentParser()
    p.add_argument("scene", nargs="?", default=str(ROOT / "examples" / "lhdl_walk.toml"))
    p.add_argument("--frames", default="0:211:105")
    p.add_argument("--count", type=int, default=100)
    a = p.parse_args()
    kept = {}
    chunk = work._deform_chunk

    def keep(job, span):  # noqa: ANN001, ANN202
        out = chunk(job, span)
        m, d = work._deformer(job)[:2]
        kept[job.name] = (m, d, job, span)
        return out

    work._deform_chunk = keep
    with tempfile.TemporaryDirectory() as tmp:
        scene = load_scene(Path(a.scene))
        run_scene(scene, Path(tmp), frames=a.frames, workers=1, progress=None, render=False)
    for name, (m, d, job, span) in kept.items():
        t = time.perf_counter()
        try:
            fb = fibres_at_rest(m, job.rest_lines, count=a.count)
        except ValueError as exc:
            print(f"{name:18s} no fibres: {exc}")
            continue
        seconds = time.perf_counter() - t
        worst = min(
            float(igl.fast_winding_number(r.V, m.F, fb.at(r.cage).reshape(-1, 3)).min())
            for r in (
                d.deform(span.lines[k], reference_point=span.references[k])
                for k in range(len(span))
            )
        )
        L = fb.lengths()
        print(
            f"{name:18s} {seconds:4.1f} s, lengths {L.min():.0f}-{L.max():.0f} mm, areas "
            f"{len(fb.origin)}/{len(fb.insertion)} vertices, smallest winding number over "
            f"{len(span)} frames {worst:.3f}"
        )


if __name__ == "__main__":
    main()
