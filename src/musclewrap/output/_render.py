"""Off-screen pictures of written meshes, and the GIF made of them.

A `PictureTask` draws a contiguous run of a series' time steps: a scene run hands
such tasks to its workers once the frames they show are written, so the GIF is
drawn beside the deformation, and `render_series` draws a written ``.pvd``. Each
task asks a renderer process (`Renderer`: ``_picture_server.py``, VTK only) that the
process running the task keeps for its next tasks. VTK may crash at the first render
where no OpenGL backend exists (no display, no EGL, no OSMesa): in that child, so it
becomes a clear message, never a crash of the run that produced the data.
"""

from __future__ import annotations

import contextlib
import os
import selectors
import subprocess
import sys
import tempfile
import threading
import time
import xml.etree.ElementTree as ET
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, TextIO

import numpy as np

from .._runs import contiguous_runs
from .._typing import PathLike
from ..mesh import atomic_path, read_mesh

__all__ = [
    "PictureTask",
    "Pictures",
    "Renderer",
    "RenderingError",
    "View",
    "frame_view",
    "label_files",
    "render_series",
    "save_gif",
    "to_256_colours",
]

_PALETTE = [
    (0.80, 0.25, 0.22),
    (0.85, 0.55, 0.20),
    (0.65, 0.30, 0.55),
    (0.30, 0.55, 0.75),
    (0.35, 0.65, 0.35),
    (0.75, 0.45, 0.45),
]
_BONE = (0.93, 0.90, 0.80)
_INSTALL = (
    ". Install EGL (Debian/Ubuntu: apt install libegl1 libegl-mesa0 libgl1-mesa-dri libgbm1) "
    "or OSMesa, or run under xvfb-run"
)

_SERVER = Path(__file__).with_name("_picture_server.py")

#: a file shown in a picture: (part, how it is drawn, file relative to the series' folder);
#: drawn as "line", "stretch" (its ``area_stretch`` array in colours) or in a colour "r,g,b"
Shown = tuple[str, str, str]

#: the colours of ``area_stretch``: this range (a factor of 1.35 either side of 1, in
#: equal ratios) from blue through white to red; beyond it the ends' colours
STRETCH_RANGE = (1 / 1.35, 1.35)


def stretch_table(n: int = 256) -> np.ndarray:
    """The colours of ``area_stretch`` over `STRETCH_RANGE` in equal ratios: (n, 3) RGB in 0-1.

    Entry ``i`` is the stretch ``lo * (hi / lo) ** (i / (n - 1))``: blue (compressed) through
    near-white at 1 to red (stretched), linear in RGB on either side. The run's pictures and
    the live viewer colour by it.
    """
    t = np.linspace(-1.0, 1.0, n)[:, None]
    end = np.where(t < 0, [[0.23, 0.30, 0.75]], [[0.71, 0.02, 0.15]])
    w = 1.0 - np.abs(t)
    return w * 0.97 + (1.0 - w) * end


def stretch_colours(stretch: np.ndarray) -> np.ndarray:
    """Each ``area_stretch`` value's colour from `stretch_table`: (k, 3) uint8 (NaN: as 1).

    The nearest entry on the table's log scale, as the run's pictures' lookup table takes it.
    """
    table = _STRETCH_RGB
    lo, hi = np.log(STRETCH_RANGE[0]), np.log(STRETCH_RANGE[1])
    s = np.log(np.nan_to_num(np.asarray(stretch, dtype=np.float64), nan=1.0).clip(1e-300))
    last = len(table) - 1
    return table[np.rint((s - lo) / (hi - lo) * last).clip(0, last).astype(np.intp)]


#: `stretch_table` in 8-bit RGB, for `stretch_colours`
_STRETCH_RGB = np.rint(255.0 * stretch_table()).astype(np.uint8)


@dataclass(frozen=True)
class View:
    """A camera: where it looks from and at, which way is up, its vertical view angle.

    The pictures of a series share one (`frame_view`), so they do not depend on how
    they are shared out among renderers; `project` says where a point lands in them.
    """

    focal: tuple[float, float, float]
    position: tuple[float, float, float]
    up: tuple[float, float, float]
    angle: float = 30.0

    def project(self, P: np.ndarray, size: tuple[int, int]) -> np.ndarray:
        """Pixel (column, row; row 0 at the top) of each point ``P`` in a picture of ``size``."""
        P = np.atleast_2d(np.asarray(P, dtype=np.float64))
        pos, focal = np.array(self.position), np.array(self.focal)
        fwd = focal - pos
        fwd /= np.linalg.norm(fwd)
        up = np.array(self.up) - (np.array(self.up) @ fwd) * fwd
        up /= np.linalg.norm(up)
        right = np.cross(fwd, up)
        d = P - pos
        depth = d @ fwd
        t = np.tan(np.radians(self.angle) / 2) * depth
        w, h = size
        x = (d @ right) / (t * w / h)  # -1 .. 1 across the picture
        y = (d @ up) / t
        return np.stack([(x + 1) / 2 * w, (1 - y) / 2 * h], axis=1)

    def as_dict(self) -> dict[str, Any]:
        """What a renderer is sent."""
        return {"focal": self.focal, "position": self.position, "up": self.up, "angle": self.angle}


def frame_view(
    lo: Sequence[float],
    hi: Sequence[float],
    turn: tuple[float, float] = (0.0, 0.0),
    size: tuple[int, int] = (800, 600),
) -> View:
    """The camera that frames the box ``lo``-``hi`` whole, seen from the side.

    It looks along the box's thinnest extent with its longest one up (the side of a
    limb, whatever the frame's convention), turned by ``turn`` = (azimuth, elevation)
    in degrees: about the up direction, then up over the box, at its centre. Its
    distance is the least that puts every corner of the box inside a picture of
    ``size`` with a view angle of 30 degrees, 4 % of the picture to spare each side.
    """
    lo, hi = np.asarray(lo, dtype=np.float64), np.asarray(hi, dtype=np.float64)
    ext = hi - lo
    centre = (lo + hi) / 2
    look, up = np.zeros(3), np.zeros(3)  # look: from the centre towards the camera
    look[int(np.argmin(ext))] = 1.0
    up[int(np.argmax(ext))] = 1.0
    az, el = np.radians(turn[0]), np.radians(turn[1])
    side = np.cross(up, look)
    look = np.cos(az) * look + np.sin(az) * side
    look = np.cos(el) * look + np.sin(el) * up
    up = up - (up @ look) * look
    up /= np.linalg.norm(up)
    right = np.cross(look, up)  # as the picture's columns run, seen from the camera
    corners = centre + (np.indices((2, 2, 2)).reshape(3, -1).T - 0.5) * ext
    c = corners - centre
    half = np.tan(np.radians(15.0)) * 0.92  # the picture's half height at distance 1
    aspect = size[0] / size[1]
    distance = max(
        float(np.max(c @ look + np.abs(c @ right) / (half * aspect))),
        float(np.max(c @ look + np.abs(c @ up) / half)),
        1e-9,
    )
    return View(
        tuple(float(v) for v in centre),  # type: ignore[arg-type]
        tuple(float(v) for v in centre + distance * look),  # type: ignore[arg-type]
        tuple(float(v) for v in up),  # type: ignore[arg-type]
    )


class RenderingError(RuntimeError):
    """No picture could be drawn (no off-screen backend, a renderer that failed or hung)."""


class Renderer:
    """A renderer process (``_picture_server.py``): started, then asked for pictures.

    It starts at once (VTK, an off-screen OpenGL context: about 0.4 s) and draws each
    request in turn; `close` ends it, as does the end of this process.

    Raises
    ------
    RenderingError
        If it cannot start: no working off-screen backend (what to install is said).
    """

    def __init__(self, timeout: float = 120.0) -> None:
        env = dict(os.environ)
        if not env.get("DISPLAY"):
            env.setdefault("VTK_DEFAULT_OPENGL_WINDOW", "vtkEGLRenderWindow")
        # a file: a chatty renderer cannot fill a pipe and stall
        self._err = tempfile.TemporaryFile("w+")  # noqa: SIM115  # closed by close()
        self._proc = subprocess.Popen(
            [sys.executable, str(_SERVER)],
            env=env,
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            stderr=self._err,
            text=True,
        )
        self._sel = selectors.DefaultSelector()
        self._sel.register(self._proc.stdout, selectors.EVENT_READ)  # type: ignore[arg-type]
        self._reply("ready", timeout, "start")  # on failure, it is closed

    def draw(self, request: dict[str, Any], timeout: float) -> None:
        """Draw a request (what `PictureTask.run` sends) into the file it names.

        Raises
        ------
        RenderingError
            With the renderer's reason, or if it ran past ``timeout`` seconds (it is
            then stopped).
        """
        import json

        try:
            self._proc.stdin.write(json.dumps(request) + "\n")  # type: ignore[union-attr]
            self._proc.stdin.flush()  # type: ignore[union-attr]
        except OSError:
            pass  # it has ended: _reply says why
        self._reply("done", timeout, "draw")

    def _reply(self, expect: str, timeout: float, doing: str) -> None:
        t0 = time.perf_counter()
        while True:
            left = timeout - (time.perf_counter() - t0)
            if left <= 0:
                self.close(kill=True)
                raise RenderingError(f"a renderer took more than {timeout:.0f} s to {doing}")
            if not self._sel.select(timeout=min(left, 1.0)):
                continue
            line = self._proc.stdout.readline()  # type: ignore[union-attr]
            if line.strip() == expect:
                return
            if line.startswith("error:"):
                raise RenderingError(line[6:].strip())
            if not line:  # it ended: a crash at its first render is a missing backend
                code = self._proc.wait()
                self._err.seek(0)
                why = self._err.read().strip().splitlines()[-1:] or [f"exit status {code}"]
                if code < 0:
                    why = [f"the renderer crashed (signal {-code})"]
                self.close()
                if doing == "start":
                    raise RenderingError(
                        "no working off-screen rendering backend: " + why[0] + _INSTALL
                    )
                raise RenderingError(f"a renderer stopped while drawing: {why[0]}")

    @property
    def alive(self) -> bool:
        return self._proc.poll() is None

    def close(self, kill: bool = False) -> None:
        """End the renderer: at the end of its input (or at once, ``kill``)."""
        if kill:
            self._proc.kill()
        with contextlib.suppress(OSError):
            self._proc.stdin.close()  # type: ignore[union-attr]  # end of input: it exits
        try:
            self._proc.wait(timeout=5)
        except subprocess.TimeoutExpired:
            self._proc.kill()
            self._proc.wait()
        with contextlib.suppress(OSError, ValueError, KeyError):
            self._sel.close()
        self._proc.stdout.close()  # type: ignore[union-attr]
        self._err.close()


# per thread (a Dask worker may run several tasks at once): its renderer, or why none starts
_local = threading.local()


def start_renderer() -> Renderer:
    """The renderer of this thread, started if not yet (tasks then find it ready).

    Raises
    ------
    RenderingError
        If it cannot start (and every later call, without trying again).
    """
    failed = getattr(_local, "failed", None)
    if failed is not None:
        raise RenderingError(failed)  # said once per process: no retry per task
    r = getattr(_local, "renderer", None)
    if r is None or not r.alive:
        try:
            r = _local.renderer = Renderer()
        except RenderingError as exc:
            _local.failed = str(exc)
            raise
    return r


def close_renderer() -> None:
    """End this thread's renderer, if it started one, and forget why one did not start.

    The next task starts another (a run calls this at its end; a worker process's
    renderer ends with it).
    """
    r = getattr(_local, "renderer", None)
    if r is not None:
        r.close()
    _local.renderer = _local.failed = None


@dataclass
class Pictures:
    """What a `PictureTask` drew: its pictures in 256 colours each, or why none.

    ``indices`` (n, h, w) index ``palettes`` (RGB bytes per picture); ``still`` is the
    picture ``PictureTask.still`` in full colour, when the task drew it.
    """

    first: int
    indices: np.ndarray | None = None
    palettes: list[bytes] = field(default_factory=list)
    still: np.ndarray | None = None
    error: str | None = None

    def __len__(self) -> int:
        return 0 if self.indices is None else len(self.indices)


@dataclass(frozen=True)
class PictureTask:
    """Pictures ``first``, ``first + 1``, ... of a GIF: one per time step of ``steps``.

    Parameters
    ----------
    folder : str
        The series' folder (absolute: the task may run in another process).
    view : View
        The series' camera (the same in every task of a series, so the pictures do
        not depend on how they are shared out).
    steps : tuple of (time, tuple of Shown)
        What each picture shows, labelled with its time.
    first : int
        Index of the first picture in the GIF.
    still : int or None
        Index of the picture also kept in full colour (the GIF's still).
    size : (int, int)
        Pixels.
    timeout : float
        Seconds before the renderer is stopped.
    """

    folder: str
    view: View
    steps: tuple[tuple[float, tuple[Shown, ...]], ...]
    first: int
    still: int | None
    size: tuple[int, int] = (800, 600)
    timeout: float = 600.0

    def request(self, out: Path) -> dict[str, Any]:
        """What a renderer is sent (`Renderer.draw`): it draws the pictures into ``out``."""
        return {
            "folder": self.folder,
            "view": self.view.as_dict(),
            "steps": [[t, [list(s) for s in shown]] for t, shown in self.steps],
            "size": list(self.size),
            "stretch_range": list(STRETCH_RANGE),
            "stretch_table": stretch_table().tolist(),
            "out": str(out),
        }

    def run(self, renderer: Renderer | None = None) -> Pictures:
        """Draw (with ``renderer``, default this thread's) and reduce to 256 colours."""
        try:
            r = renderer or start_renderer()
            with tempfile.TemporaryDirectory(prefix="musclewrap-pictures-") as tmp:
                out = Path(tmp) / "pictures.npy"
                r.draw(self.request(out), self.timeout)
                rgb = np.load(out)
        except RenderingError as exc:
            return Pictures(self.first, error=str(exc))
        indices, palettes = to_256_colours(rgb)
        still = None
        if self.still is not None and 0 <= self.still - self.first < len(rgb):
            still = rgb[self.still - self.first].copy()
        return Pictures(self.first, indices, palettes, still)


def to_256_colours(rgb: np.ndarray) -> tuple[np.ndarray, list[bytes]]:
    """Pictures (n, h, w, 3) as palette indices and a palette each (Pillow's fast octree)."""
    from PIL import Image

    indices = np.empty(rgb.shape[:3], dtype=np.uint8)
    palettes = []
    for i, picture in enumerate(rgb):
        q = Image.fromarray(picture).quantize(colors=256, method=Image.Quantize.FASTOCTREE)
        indices[i] = np.asarray(q)
        palettes.append(bytes(q.getpalette() or []))
    return indices, palettes


def label_files(
    files: Sequence[str],
    bones: Sequence[str],
    colours: dict[str, str],
    colour: str = "muscle",
) -> tuple[Shown, ...]:
    """What a time step shows: each file with its part and how it is drawn.

    Files under a folder of ``bones`` are bones (ivory); ``*_lines_*`` files are
    action lines (black); ``*_fibres_*`` files are left out (inside the muscle,
    hidden by it); every other folder is a muscle, coloured in the order the
    folders first come (``colours``, filled in as they come), or with ``colour =
    "stretch"`` by its ``area_stretch`` (`STRETCH_RANGE`).
    """
    shown = []
    for f in files:
        name, folder = Path(f).name, Path(f).parts[0]
        if "_fibres_" in name:
            continue
        if "_lines_" in name:
            shown.append((folder + "_lines", "line", f))
            continue
        if folder in bones:
            kind = _rgb(_BONE)
        elif colour == "stretch":
            kind = "stretch"
        else:
            kind = colours.setdefault(folder, _rgb(_PALETTE[len(colours) % len(_PALETTE)]))
        shown.append((folder, kind, f))
    return tuple(shown)


def _rgb(c: tuple[float, float, float]) -> str:
    return ",".join(f"{x:g}" for x in c)


def save_gif(
    pictures: Sequence[Pictures], gif: PathLike, duration_ms: int = 50, optimize: bool = False
) -> list[Path]:
    """Write the GIF of tasks' pictures (in order of ``first``) and its still as a PNG.

    Returns the files written (the GIF, and the PNG beside it when a task kept the
    still). Nothing is written if a task failed. ``optimize``: Pillow's palette
    optimisation (for the LHDL walk's 71 pictures 0.14 s more, for a GIF 14 % smaller:
    `benchmarks/speed/bench_pictures.py`).

    Raises
    ------
    RenderingError
        The first failed task's reason.
    """
    from PIL import Image

    for p in pictures:
        if p.error is not None:
            raise RenderingError(p.error)
    parts = sorted(pictures, key=lambda p: p.first)
    images = []
    for p in parts:
        assert p.indices is not None
        for idx, pal in zip(p.indices, p.palettes, strict=True):
            im = Image.frombytes("P", (idx.shape[1], idx.shape[0]), idx.tobytes())
            im.putpalette(pal)
            images.append(im)
    if not images:
        raise RenderingError("no pictures to write")
    gif = Path(gif)
    with atomic_path(gif) as tmp:
        images[0].save(
            tmp,
            format="GIF",
            save_all=True,
            append_images=images[1:],
            duration=duration_ms,
            loop=0,
            optimize=optimize,
        )
    out = [gif]
    still = next((p.still for p in parts if p.still is not None), None)
    if still is not None:
        png = gif.with_suffix(".png")
        with atomic_path(png) as tmp:
            Image.fromarray(still).save(tmp, format="PNG")
        out.append(png)
    return out


def render_series(
    pvd: PathLike,
    gif: PathLike,
    *,
    every: int = 1,
    size: tuple[int, int] = (800, 600),
    bones: tuple[str, ...] = (),
    colour: str = "muscle",
    turn: tuple[float, float] = (0.0, 0.0),
    view: View | None = None,
    timeout: float = 900.0,
    processes: int | None = None,
    progress: TextIO | None = None,
) -> Path:
    """Render every ``every``-th time step of a ``.pvd`` collection into a GIF.

    The middle picture is also written as a PNG beside it (same name). The
    pictures are shared out, in contiguous runs, among ``processes`` renderers;
    all share one camera (`frame_view` of the muscles' box over every time step
    drawn), so the pictures are the same whatever their number.

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
    colour : str, optional
        The muscles in one colour each (``"muscle"``) or by their ``area_stretch``
        (``"stretch"``).
    turn : (float, float), optional
        The camera's azimuth and elevation from the side view, degrees (`frame_view`).
    view : View, optional
        The camera instead (a scene run's is its summary's ``view``: the same pictures
        as its ``scene.gif``).
    timeout : float, optional
        Seconds before a renderer is stopped.
    processes : int, optional
        Renderers at once; default the CPU count, at most 4.
    progress : text stream, optional
        Where to say how many pictures were rendered.

    Returns
    -------
    Path
        The GIF.

    Raises
    ------
    RuntimeError
        If no off-screen rendering backend works here (with what to install), a
        renderer failed, or it ran past the time limit.
    """
    from concurrent.futures import ThreadPoolExecutor

    t0 = time.perf_counter()
    pvd = Path(pvd).resolve()
    steps = _timesteps(pvd)
    if not steps:
        raise RenderingError(f"{pvd}: the collection has no time steps")
    colours: dict[str, str] = {}
    shown = [(t, label_files(files, bones, colours, colour)) for t, files in steps[::every]]
    if view is None:
        view = frame_view(*muscles_box(pvd.parent, shown), turn, size)
    k = processes or min(os.cpu_count() or 1, 4)
    runs = contiguous_runs(len(shown), k)
    middle = len(shown) // 2
    tasks = [
        PictureTask(
            str(pvd.parent), view, tuple(shown[r.start : r.stop]), r.start, middle, size, timeout
        )
        for r in runs
    ]
    renderers: list[Renderer] = []
    failed: list[RenderingError] = []
    try:
        # threads: each waits for its own renderer process, which does the work
        with ThreadPoolExecutor(len(tasks)) as pool:
            for started in [pool.submit(Renderer) for _ in tasks]:
                try:
                    renderers.append(started.result())
                except RenderingError as exc:
                    failed.append(exc)
            if failed:
                raise failed[0]
            done = list(pool.map(lambda tr: tr[0].run(tr[1]), zip(tasks, renderers)))
    finally:
        for r in renderers:
            r.close()
    save_gif(done, gif)
    if progress is not None:
        n = sum(len(p) for p in done)
        progress.write(f"rendered {n} pictures in {time.perf_counter() - t0:.1f} s\n")
        progress.flush()
    return Path(gif)


def muscles_box(
    folder: Path, shown: Sequence[tuple[float, tuple[Shown, ...]]]
) -> tuple[np.ndarray, np.ndarray]:
    """The box round every muscle of every time step shown (or everything, without muscles)."""
    files = [f for _, parts in shown for _, kind, f in parts if kind not in ("line", _rgb(_BONE))]
    if not files:
        files = [f for _, parts in shown for _, _, f in parts]
    pts = np.vstack([read_mesh(folder / f)[0] for f in dict.fromkeys(files)])
    return pts.min(axis=0), pts.max(axis=0)


def _timesteps(pvd: Path) -> list[tuple[float, list[str]]]:
    steps: dict[float, list[str]] = {}
    for ds in ET.parse(pvd).getroot().iter("DataSet"):
        steps.setdefault(float(ds.get("timestep", "0")), []).append(ds.get("file", ""))
    return sorted(steps.items())
