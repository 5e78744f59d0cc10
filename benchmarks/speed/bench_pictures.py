"""The GIF's pictures, piece by piece: renderer start, a picture, 256 colours, the GIF.

    python benchmarks/speed/bench_pictures.py [SCENE] [--repeats 5]

Writes the scene (default the LHDL walk) once with ``--no-gif``, then times on its series,
in this process (medians of ``--repeats``):

- starting a renderer process (`musclewrap.output.Renderer`: VTK only), against what the
  renderer before it paid to start: importing musclewrap and building PyVista's plotter
  (each in a fresh process);
- drawing the scene's pictures (every ``gif_every``-th frame) in one renderer, per picture;
- reducing them to 256 colours (per picture);
- writing the GIF with and without Pillow's palette optimisation (seconds and size);
- `render_series` on the written series with one and with two renderers.
"""

from __future__ import annotations

import argparse
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def fresh(code: str) -> float:
    """Seconds a fresh Python process takes to run ``code`` (the process's own clock)."""
    out = subprocess.run(
        [sys.executable, "-c", f"import time; t = time.perf_counter()\n{code}\n"
         "print(time.perf_counter() - t)"],
        capture_output=True, text=True, check=True,
    )  # fmt: skip
    return float(out.stdout.split()[-1])


def median(f, repeats: int) -> float:  # noqa: ANN001
    return statistics.median(f() for _ in range(repeats))


def main() -> None:
    p = argparse.ArgumentParser()
    p.add_argument("scene", nargs="?", default=str(ROOT / "examples" / "lhdl_walk.toml"))
    p.add_argument("--repeats", type=int, default=5)
    a = p.parse_args()
    import numpy as np

    from musclewrap.output import PictureTask, render_series, save_gif
    from musclewrap.output._render import (
        Renderer,
        _timesteps,
        frame_view,
        label_files,
        muscles_box,
        to_256_colours,
    )
    from musclewrap.scene import load_scene

    scene = load_scene(a.scene)
    bones = tuple(b.name for b in scene.bones)
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "out"
        subprocess.run(
            [sys.executable, "-m", "musclewrap.cli", "run", a.scene, "-o", str(out), "--no-gif"],
            check=True, capture_output=True,
        )  # fmt: skip
        pvd = out / "scene.pvd"
        steps = _timesteps(pvd)
        colours: dict[str, str] = {}
        shown = tuple((t, label_files(f, bones, colours)) for t, f in steps[:: scene.gif_every])
        n = len(shown)
        view = frame_view(*muscles_box(out, shown), (0.0, 0.0), scene.image_size)
        task = PictureTask(str(out), view, shown, 0, n // 2, scene.image_size)
        print(f"{a.scene}: {n} pictures of {scene.image_size[0]} x {scene.image_size[1]}, "
              f"medians of {a.repeats}")  # fmt: skip

        def start() -> float:
            t = time.perf_counter()
            Renderer().close()
            return time.perf_counter() - t

        print(f"  start a renderer (VTK only)          {median(start, a.repeats):6.2f} s")
        imp = median(lambda: fresh("import musclewrap"), a.repeats)
        plotter = median(
            lambda: fresh(
                "import pyvista as pv\npv.Plotter(off_screen=True, window_size=(800, 600))"
            ),
            a.repeats,
        )
        print(f"  before: import musclewrap            {imp:6.2f} s")
        print(f"  before: import PyVista, build plotter {plotter:5.2f} s")
        r = Renderer()
        rgb = None

        def draw() -> float:
            nonlocal rgb
            t = time.perf_counter()
            r.draw(task.request(Path(tmp) / "p.npy"), 600)
            dt = time.perf_counter() - t
            rgb = np.load(Path(tmp) / "p.npy")
            return dt

        per = median(draw, a.repeats) / n
        r.close()
        print(f"  draw, per picture                    {1e3 * per:6.1f} ms")

        def reduce() -> float:
            t = time.perf_counter()
            to_256_colours(rgb)
            return time.perf_counter() - t

        print(
            f"  256 colours, per picture             {1e3 * median(reduce, a.repeats) / n:6.1f} ms"
        )
        pictures = [task.run()]
        for optimize in (False, True):
            gif = Path(tmp) / f"o{int(optimize)}.gif"

            def write(gif: Path = gif, optimize: bool = optimize) -> float:
                t = time.perf_counter()
                save_gif(pictures, gif, optimize=optimize)
                return time.perf_counter() - t

            s = median(write, a.repeats)
            print(f"  write the GIF, optimize={optimize!s:5}       {s:6.2f} s, "
                  f"{gif.stat().st_size / 1e6:.2f} MB")  # fmt: skip
        for k in (1, 2):

            def series(k: int = k) -> float:
                t = time.perf_counter()
                render_series(pvd, Path(tmp) / "s.gif", every=scene.gif_every, bones=bones,
                              size=scene.image_size, processes=k)  # fmt: skip
                return time.perf_counter() - t

            print(f"  render_series, {k} renderer(s)         {median(series, a.repeats):6.2f} s")


if __name__ == "__main__":
    main()
