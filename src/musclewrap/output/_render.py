"""Off-screen pictures of a written scene (PyVista/VTK), isolated in a subprocess.

VTK segfaults at the first render when no OpenGL backend exists (no display,
no EGL, no OSMesa), so rendering runs in a child process: a missing backend
becomes a clear message, never a crash of the run that produced the data.
"""

from __future__ import annotations

import os
import subprocess
import sys
import tempfile
import xml.etree.ElementTree as ET
from pathlib import Path
from typing import Any, TextIO

from .._typing import PathLike
from ..mesh import atomic_path

__all__ = ["Rendering", "render_series", "start_rendering"]

_PALETTE = [
    (0.80, 0.25, 0.22),
    (0.85, 0.55, 0.20),
    (0.65, 0.30, 0.55),
    (0.30, 0.55, 0.75),
    (0.35, 0.65, 0.35),
    (0.75, 0.45, 0.45),
]


def render_series(pvd: PathLike, gif: PathLike, **options: Any) -> Path:
    """`start_rendering` and `Rendering.finish` in one call: the GIF, written.

    ``options`` are `start_rendering`'s (every, size, bones, timeout, processes,
    progress).

    Raises
    ------
    RuntimeError
        As `Rendering.finish`.
    """
    return start_rendering(pvd, gif, **options).finish()


class Rendering:
    """Renderer processes of a GIF (`start_rendering`): `go`, then `finish` writes it.

    The renderers start at once (imports, an OpenGL context) and wait until `go`
    says the files are written: a scene run starts them before its work and lets
    them go when the frames are written, while it draws its plots. Each takes a
    contiguous run of the pictures and places the camera from the first time
    step, so the pictures are the same whatever their number.
    """

    def __init__(
        self,
        pvd: Path,
        gif: Path,
        every: int,
        size: tuple[int, int],
        bones: tuple[str, ...],
        timeout: float,
        processes: int,
        progress: TextIO | None,
    ) -> None:
        self.pvd, self.gif, self.every = Path(pvd), Path(gif), every
        self.timeout, self.progress = timeout, progress
        env = dict(os.environ)
        if not env.get("DISPLAY"):
            env.setdefault("VTK_DEFAULT_OPENGL_WINDOW", "vtkEGLRenderWindow")
        self._tmp = tempfile.TemporaryDirectory(prefix="musclewrap-render-")
        tmp = Path(self._tmp.name)
        k = max(1, processes)
        self.parts = [tmp / f"part{i}.npy" for i in range(k)]
        self.errs = [open(tmp / f"err{i}.txt", "w+") for i in range(k)]  # noqa: SIM115
        self._gone = False
        self.procs = [
            subprocess.Popen(
                [
                    sys.executable,
                    "-c",
                    "import sys; from musclewrap.output._render import _main; "
                    "sys.exit(_main(sys.argv[1:]))",
                    str(self.pvd),
                    str(self.parts[i]),
                    str(every),
                    str(size[0]),
                    str(size[1]),
                    ",".join(bones),
                    str(i),
                    str(k),
                ],
                env=env,
                stdin=subprocess.PIPE,
                stdout=subprocess.PIPE,
                stderr=self.errs[i],  # a file: a chatty renderer cannot fill a pipe and stall
                text=True,
            )
            for i in range(k)
        ]

    def go(self) -> None:
        """The collection is written: the renderers read it and draw their pictures."""
        if self._gone:
            return
        self._gone = True
        for p in self.procs:
            try:
                p.stdin.write("go\n")  # type: ignore[union-attr]
                p.stdin.close()  # type: ignore[union-attr]
            except OSError:
                pass  # it has ended already: finish() says why

    def cancel(self) -> None:
        """Stop the renderers without a picture (the run failed)."""
        for p in self.procs:
            p.kill()
            p.wait()
            for f in (p.stdin, p.stdout):
                if f is not None:
                    f.close()
        for fh in self.errs:
            fh.close()
        self._tmp.cleanup()

    def finish(self) -> Path:
        """Let the renderers go if not yet, wait for them, write the GIF and its PNG.

        Raises
        ------
        RuntimeError
            If no off-screen rendering backend works here (with what to install),
            a renderer failed, or they ran past the time limit.
        """
        import numpy as np

        try:
            n = len(_timesteps(self.pvd)[:: self.every])
            if n == 0:
                raise RuntimeError(f"{self.pvd}: the collection has no time steps")
            self.go()
            try:
                _follow(self.procs, n, self.timeout, self.progress)
            except BaseException:
                for p in self.procs:
                    p.kill()
                raise
            finally:
                for p in self.procs:
                    if p.stdout is not None:
                        p.stdout.close()
            messages = []
            for p, fh in zip(self.procs, self.errs, strict=True):
                p.wait()
                fh.seek(0)
                messages.append(fh.read())
            for p, part, err in zip(self.procs, self.parts, messages, strict=True):
                if p.returncode != 0 or not part.is_file():
                    why = err.strip().splitlines()[-1:] or [f"exit status {p.returncode}"]
                    if p.returncode is not None and p.returncode < 0:
                        why = [f"the renderer crashed (signal {-p.returncode})"]
                    raise RuntimeError(
                        "no working off-screen rendering backend: "
                        + why[0]
                        + ". Install EGL (Debian/Ubuntu: apt install libegl1 libegl-mesa0 "
                        "libgl1-mesa-dri libgbm1) or OSMesa, or run under xvfb-run; the meshes "
                        "and plots are written"
                    )
            frames = np.concatenate([np.load(q) for q in self.parts])
            _save_gif(frames, self.gif, self.gif.with_suffix(".png"))
            return self.gif
        finally:
            for p in self.procs:
                if p.poll() is None:
                    p.kill()
                    p.wait()
            for fh in self.errs:
                fh.close()
            self._tmp.cleanup()


def start_rendering(
    pvd: PathLike,
    gif: PathLike,
    *,
    every: int = 1,
    size: tuple[int, int] = (800, 600),
    bones: tuple[str, ...] = (),
    timeout: float = 900.0,
    processes: int | None = None,
    progress: TextIO | None = None,
) -> Rendering:
    """Start rendering every ``every``-th time step of a ``.pvd`` collection into a GIF.

    Returns at once: the renderers start (imports, an OpenGL context) and draw
    once told to (`Rendering.go`, or `Rendering.finish`, which writes the GIF).

    The middle picture is also written as a PNG beside it (same name). The frames
    are shared out, in contiguous runs, among ``processes`` renderers (child
    processes: see the module's note); each places the camera from the first
    time step, so the pictures are the same whatever their number.

    Parameters
    ----------
    pvd : str or os.PathLike
        Collection written by `write_pvd` (files relative to its folder).
    gif : str or os.PathLike
        Destination (written atomically).
    every : int, optional
        Time-step stride.
    size : (int, int), optional
        Image size in pixels.
    bones : tuple of str, optional
        Folder names drawn as bones (ivory); ``*_lines_*`` files are action
        lines; everything else is a muscle.
    timeout : float, optional
        Seconds before the renderers are stopped.
    processes : int, optional
        Renderers at once; default the CPU count, at most 4.
    progress : text stream, optional
        Where to show the pictures rendered so far (a line redrawn on a
        terminal, else one line at the end).

    Returns
    -------
    Rendering
    """
    k = processes or min(os.cpu_count() or 1, 4)
    return Rendering(Path(pvd), Path(gif), every, size, bones, timeout, k, progress)


def _follow(procs: list[subprocess.Popen], n: int, timeout: float, progress: TextIO | None) -> None:
    """Count the pictures the renderers report (a line each) until they end or time out."""
    import selectors
    import time

    t0 = time.perf_counter()
    sel = selectors.DefaultSelector()
    for p in procs:
        if p.stdout is not None:
            sel.register(p.stdout, selectors.EVENT_READ)
    done, open_ = 0, len(procs)
    tty = progress is not None and bool(getattr(progress, "isatty", lambda: False)())
    while open_:
        left = timeout - (time.perf_counter() - t0)
        if left <= 0:
            for p in procs:
                p.kill()
            raise RuntimeError(f"rendering took more than {timeout:.0f} s and was stopped")
        for key, _ in sel.select(timeout=min(left, 1.0)):
            line = key.fileobj.readline()  # type: ignore[union-attr]
            if not line:
                sel.unregister(key.fileobj)
                open_ -= 1
            elif line.startswith("picture"):
                done += 1
                if tty:
                    progress.write(  # type: ignore[union-attr]
                        f"\rrendering scene pictures: {done}/{n} {time.perf_counter() - t0:5.1f} s"
                    )
                    progress.flush()  # type: ignore[union-attr]
    if progress is not None:
        progress.write(
            ("\r" if tty else "")
            + f"rendered {done} pictures in {time.perf_counter() - t0:.1f} s\n"
        )
        progress.flush()


def _save_gif(frames, gif: Path, png: Path) -> None:  # noqa: ANN001
    """The GIF (256 colours per frame, fast octree) and its middle picture as a PNG."""
    from PIL import Image

    images = [Image.fromarray(f) for f in frames]
    paletted = [im.quantize(colors=256, method=Image.Quantize.FASTOCTREE) for im in images]
    with atomic_path(gif) as tmp:
        paletted[0].save(
            tmp, format="GIF", save_all=True, append_images=paletted[1:], duration=50, loop=0
        )
    with atomic_path(png) as tmp:
        images[len(images) // 2].save(tmp, format="PNG")


def _timesteps(pvd: Path) -> list[tuple[float, list[str]]]:
    steps: dict[float, list[str]] = {}
    for ds in ET.parse(pvd).getroot().iter("DataSet"):
        steps.setdefault(float(ds.get("timestep", "0")), []).append(ds.get("file", ""))
    return sorted(steps.items())


def _main(argv: list[str]) -> int:  # pragma: no cover - runs in a child process
    # renderer `index` of `count`: starts (imports, an OpenGL context), waits for a line on
    # stdin (the files are written; end of input: nothing to draw), then renders its
    # contiguous share of the pictures into a .npy stack, printing a line per picture
    pvd, dest = Path(argv[0]), Path(argv[1])
    every, w, h = int(argv[2]), int(argv[3]), int(argv[4])
    bones = set(filter(None, argv[5].split(",")))
    index, count = int(argv[6]), int(argv[7])
    import numpy as np
    import pyvista as pv

    pl = pv.Plotter(off_screen=True, window_size=(w, h))
    # no multisampling: in a software OpenGL (llvmpipe, what a server without a GPU has) 4x
    # MSAA tripled the time of a picture (72 against 23 ms for the LHDL walk at 800 x 600;
    # FXAA cost the same), and a 256-colour GIF keeps little of it
    pl.ren_win.SetMultiSamples(0)
    pl.set_background("white")
    pl.ren_win.Render()  # the OpenGL context now, while waiting
    if sys.stdin.readline().strip() != "go":
        return 0  # cancelled
    steps = _timesteps(pvd)[::every]
    edges = np.linspace(0, len(steps), count + 1).round().astype(int)
    first, last = int(edges[index]), int(edges[index + 1])
    if first >= last:
        np.save(dest, np.zeros((0, h, w, 3), dtype=np.uint8))
        return 0
    colours: dict[str, tuple[float, float, float]] = {}
    shown: dict[str, tuple[str, pv.PolyData]] = {}  # part -> (file, mesh drawn)
    frames = []
    text = None
    # the first time step places the camera, the same in every renderer
    for i in [0, *range(max(first, 1), last)] if first > 0 else range(first, last):
        t, files = steps[i]
        for f in files:
            if "_fibres_" in Path(f).name:
                continue  # inside the muscle, hidden by it
            part = Path(f).parts[0] + ("_lines" if "_lines_" in Path(f).name else "")
            if part in shown and shown[part][0] == f:
                continue  # a static bone: drawn once
            new = pv.read(pvd.parent / f)
            if part in shown and shown[part][1].n_points == new.n_points:
                shown[part][1].points = new.points  # same topology: move the points only
                shown[part] = (f, shown[part][1])
                continue
            folder = Path(f).parts[0]
            if part.endswith("_lines"):
                pl.add_mesh(new, color="black", line_width=3, render=False)
            # back faces culled: muscles and bones are closed and face outward, so the
            # pictures are the same (1 pixel in 480,000 differed on the walk) at 0.6 of the time
            elif folder in bones:
                pl.add_mesh(new, color=(0.93, 0.90, 0.80), culling="back", render=False)
            else:
                c = colours.setdefault(folder, _PALETTE[len(colours) % len(_PALETTE)])
                pl.add_mesh(new, color=c, culling="back", render=False)
            shown[part] = (f, new)
        if i == 0:
            # look along the scene's thinnest extent, its longest one up (a side view of a
            # limb whatever the frame's convention), fixed for the whole motion
            ext = np.diff(np.array(pl.bounds).reshape(3, 2), axis=1).ravel()
            look, vup = np.zeros(3), np.zeros(3)
            look[int(np.argmin(ext))] = 1.0
            vup[int(np.argmax(ext))] = 1.0
            pl.view_vector(tuple(look), viewup=tuple(vup))
            pl.reset_camera(render=False)
            pl.camera.zoom(1.05)
            if first > 0:
                continue  # placed the camera only
        if text is not None:
            pl.remove_actor(text, render=False)
        text = pl.add_text(f"t = {t:.3f}", font_size=10, color="black", render=False)
        pl.render()  # one render per picture (the screenshot alone may reuse the last one)
        frames.append(pl.screenshot(return_img=True))
        print("picture", flush=True)
    pl.close()
    np.save(dest, np.stack(frames))
    return 0


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(_main(sys.argv[1:]))
