"""Off-screen pictures of a written scene (PyVista/VTK), isolated in a subprocess.

VTK segfaults at the first render when no OpenGL backend exists (no display,
no EGL, no OSMesa), so rendering runs in a child process: a missing backend
becomes a clear message, never a crash of the run that produced the data.
"""

from __future__ import annotations

import os
import subprocess
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

from .._typing import PathLike
from ..mesh import atomic_path

__all__ = ["render_series"]

_PALETTE = [
    (0.80, 0.25, 0.22),
    (0.85, 0.55, 0.20),
    (0.65, 0.30, 0.55),
    (0.30, 0.55, 0.75),
    (0.35, 0.65, 0.35),
    (0.75, 0.45, 0.45),
]


def render_series(
    pvd: PathLike,
    gif: PathLike,
    *,
    every: int = 1,
    size: tuple[int, int] = (800, 600),
    bones: tuple[str, ...] = (),
    timeout: float = 900.0,
) -> Path:
    """Render every ``every``-th time step of a ``.pvd`` collection into an animated GIF.

    The middle picture is also written as a PNG beside it (same name).

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
        Seconds before the renderer is stopped.

    Returns
    -------
    pathlib.Path

    Raises
    ------
    RuntimeError
        If no off-screen rendering backend works here (with what to install),
        or the renderer failed.
    """
    out = Path(gif)
    env = dict(os.environ)
    if not env.get("DISPLAY"):
        env.setdefault("VTK_DEFAULT_OPENGL_WINDOW", "vtkEGLRenderWindow")
    png = out.with_suffix(".png")
    with atomic_path(out) as tmp, atomic_path(png) as tmp_png:
        cmd = [
            sys.executable,
            "-c",
            "import sys; from musclewrap.output._render import _main; sys.exit(_main(sys.argv[1:]))",
            str(pvd),
            str(tmp),
            str(every),
            str(size[0]),
            str(size[1]),
            ",".join(bones),
            str(tmp_png),
        ]
        try:
            r = subprocess.run(cmd, env=env, capture_output=True, text=True, timeout=timeout)
        except subprocess.TimeoutExpired:
            raise RuntimeError(
                f"rendering took more than {timeout:.0f} s and was stopped"
            ) from None
        if r.returncode != 0 or Path(tmp).stat().st_size == 0 or Path(tmp_png).stat().st_size == 0:
            why = (r.stderr or "").strip().splitlines()[-1:] or [f"exit status {r.returncode}"]
            if r.returncode < 0:
                why = [f"the renderer crashed (signal {-r.returncode})"]
            raise RuntimeError(
                "no working off-screen rendering backend: "
                + why[0]
                + ". Install EGL (Debian/Ubuntu: apt install libegl1 libegl-mesa0 libgl1-mesa-dri "
                "libgbm1) or OSMesa, or run under xvfb-run; the meshes and plots are written"
            )
    return out


def _timesteps(pvd: Path) -> list[tuple[float, list[str]]]:
    steps: dict[float, list[str]] = {}
    for ds in ET.parse(pvd).getroot().iter("DataSet"):
        steps.setdefault(float(ds.get("timestep", "0")), []).append(ds.get("file", ""))
    return sorted(steps.items())


def _main(argv: list[str]) -> int:  # pragma: no cover - runs in a child process
    pvd, gif = Path(argv[0]), Path(argv[1])
    every, w, h = int(argv[2]), int(argv[3]), int(argv[4])
    bones = set(filter(None, argv[5].split(",")))
    import numpy as np
    import pyvista as pv
    from PIL import Image

    steps = _timesteps(pvd)[::every]
    if not steps:
        raise SystemExit("the collection has no time steps")
    pl = pv.Plotter(off_screen=True, window_size=(w, h))
    pl.set_background("white")
    colours: dict[str, tuple[float, float, float]] = {}
    shown: dict[str, tuple[str, pv.PolyData]] = {}  # part -> (file, mesh drawn)
    frames = []
    text = None
    for i, (t, files) in enumerate(steps):
        for f in files:
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
                pl.add_mesh(new, color="black", line_width=3)
            elif folder in bones:
                pl.add_mesh(new, color=(0.93, 0.90, 0.80))
            else:
                c = colours.setdefault(folder, _PALETTE[len(colours) % len(_PALETTE)])
                pl.add_mesh(new, color=c)
            shown[part] = (f, new)
        if i == 0:
            # look along the scene's thinnest extent, its longest one up (a side view of a
            # limb whatever the frame's convention), fixed for the whole motion
            ext = np.diff(np.array(pl.bounds).reshape(3, 2), axis=1).ravel()
            look, vup = np.zeros(3), np.zeros(3)
            look[int(np.argmin(ext))] = 1.0
            vup[int(np.argmax(ext))] = 1.0
            pl.view_vector(tuple(look), viewup=tuple(vup))
            pl.reset_camera()
            pl.camera.zoom(1.05)
        if text is not None:
            pl.remove_actor(text)
        text = pl.add_text(f"t = {t:.3f}", font_size=10, color="black")
        frames.append(Image.fromarray(pl.screenshot(return_img=True)))
    pl.close()
    frames[0].save(gif, format="GIF", save_all=True, append_images=frames[1:], duration=50, loop=0)
    if len(argv) > 6 and argv[6]:
        frames[len(frames) // 2].save(argv[6], format="PNG")
    return 0


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(_main(sys.argv[1:]))
