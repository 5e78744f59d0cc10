"""The viewer's web page (trame): sliders and a time slider, the muscles wrapping live.

One page over one protocol (`._sources.Source`) with two sources behind it:

- a scene (`._sources.LiveSource` over `musclewrap.run.LiveScene`): every slider change
  is solved as a run solves that pose, in one solver thread that always takes the latest
  request (a drag is not queued behind itself), and the muscles, bones, lines and fibres
  are sent to the browser, where vtk.js draws them;
- a finished run's ``scene.pvd`` (`._sources.Playback` over `._playback.Series`): the time
  slider and play/pause step through its files.

The page's own script and style are files of their own (``www/page.js``, ``www/page.css``);
the script is loaded before the page's app (it views the arrays' bytes as their types).

The browser measures each update, from the slider's input event to the picture
drawn (two animation frames after the new geometry arrived), and writes the status
line: ``update N ms (median M ms of the last 10; queued Q, solve S, transfer X, render R)``
(queued: while the pose before was being solved; one pose at a time is asked for).
"""

from __future__ import annotations

import asyncio
import contextlib
import os
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

from ..constants import defaults
from ..output import STRETCH_RANGE, stretch_table
from ..run import LiveScene
from ._playback import Series
from ._sources import LiveSource, Playback, Source
from ._state import CONTACT_STOPS, Request, css_rgb, time_text

__all__ = ["Viewer", "free_port", "open_source"]


_STRETCH = stretch_table()

#: the two colourings: the menu's words, the legend's gradient and words. The colours are
#: mapped here and sent as RGB (vtk.js draws unsigned-char colours as they are): mapping a
#: value per vertex through vtk.js's diverging colour function took the page about 66 ms an
#: update on the gait2392 scene (a profile of the page, BENCHMARKS.md). The stretch is
#: coloured as the run's pictures colour it (`musclewrap.output._render.stretch_table`).
#: ("{what}": what the muscles are kept out of, `_kept_out_of`)
COLOURS = {
    "stretch": (
        "stretch (surface area over rest)",
        ", ".join(css_rgb(_STRETCH[i]) for i in (0, len(_STRETCH) // 2, -1)),
        f"blue {STRETCH_RANGE[0]:.2f} (compressed), white 1, red {STRETCH_RANGE[1]:.2f} "
        "(stretched), in equal ratios",
    ),
    "contact": (
        f"contact (distance to {{what}}, 0-{defaults.view_contact_reach:g} mm)",
        ", ".join(css_rgb(c) for c in CONTACT_STOPS),
        f"black: touching {{what}}, yellow: {defaults.view_contact_reach:g} mm or more away",
    ),
}

#: the page's style and script, files of their own served with the page
_WWW = Path(__file__).with_name("www")
_CSS = (_WWW / "page.css").read_text(encoding="utf-8")


#: the full surfaces' and the lighter ones' visibility, as `light` is False or True
_LOOKS = {
    False: ({"visibility": True}, {"visibility": False}),
    True: ({"visibility": False}, {"visibility": True}),
}


def _typed(name: str, kind: str) -> tuple[str]:
    """A binding of state ``name`` (an array's bytes) viewed as ``kind`` (f32, u32, u8)."""
    return (f"window.mw.typed({name}, '{kind}')",)


@dataclass(frozen=True)
class Frame:
    """The page in a notebook cell: drawn as an iframe of ``url``."""

    url: str
    height: int = 640

    def _repr_html_(self) -> str:
        return (
            f'<iframe src="{self.url}" width="100%" height="{self.height}" '
            'style="border: 1px solid #ccc" title="musclewrap view"></iframe>'
        )


def _slider(
    html: Any,
    label: str,
    key: str,
    span: tuple[float, float, float, float],
    source: str,
    shown: str,
) -> None:
    """A labelled range input (id ``key``; ``span``: low, high, step, start).

    Its input events go to the server as ``source`` (the page's script measures each one).
    Not bound to the state: Vue would set it back to the state's value on every redraw,
    behind the hand; the server moves it through the state ``thumbs`` where a pose comes
    from elsewhere.
    """
    lo, hi, step, start = span
    with html.Div(classes="mw-row"):
        html.Label(label, for_=key, __properties=[("for_", "for")])
        html.Input(
            type="range", id=key, min=f"{lo:.6g}", max=f"{hi:.6g}", step=f"{step:.6g}",
            value=f"{start:.6g}", aria_label=label, data_mw=source,
            __properties=[("aria_label", "aria-label"), ("data_mw", "data-mw")],
        )  # fmt: skip
        html.Span(shown, classes="mw-value")


def free_port() -> int:
    """A free TCP port on the loopback interface."""
    import socket

    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def open_source(path: str | os.PathLike[str], **kw: Any) -> LiveScene | Series:
    """A scene file (.toml) as a `LiveScene`, or a run's folder (with scene.pvd) as a `Series`."""
    p = Path(path)
    if p.is_dir():
        return Series.open(p)
    if not p.is_file():
        raise FileNotFoundError(f"{p}: no such scene file or run folder")
    return LiveScene(p, **kw)


class Viewer:
    """The viewer's trame app over a `LiveScene` or a run's `Series`.

    Parameters
    ----------
    source : LiveScene or Series
        What is shown.
    output : path, optional
        Where "Write this pose" writes (``pose_NNN/`` folders; default
        ``./musclewrap_poses``).
    server : trame server, optional
        Default: a new one (several viewers can live in one notebook).
    """

    def __init__(
        self,
        source: LiveScene | Series,
        *,
        output: str | os.PathLike[str] | None = None,
        server: Any = None,
    ) -> None:
        from trame.app import get_server

        self.source = source
        self.src: Source = LiveSource(source) if isinstance(source, LiveScene) else Playback(source)
        self.output = Path(output) if output is not None else Path("musclewrap_poses")
        self.server = server or get_server(f"musclewrap-{id(self)}", client_type="vue3")
        # the page's script, loaded before its app: the bindings view arrays through it
        self.server.enable_module(
            {"serve": {"__musclewrap": str(_WWW)}, "scripts": ["__musclewrap/page.js"]}
        )
        self.state, self.ctrl = self.server.state, self.server.controller
        self.n_frames = self.src.n_frames
        self.times = self.src.times
        self.coords = self.src.coordinates
        self._want: Request | None = None
        # the sliders as the user left them: a solved pose is not sent back to the slider the
        # user holds (a pose behind the hand would pull its thumb back)
        self._values: dict[str, float] = {}
        self._frame = 0
        self._writes = 0  # "Write this pose" clicks not yet served
        self._recolour = False  # the colour menu changed: the shown pose's colours due
        self._still_id = 0  # the sliders let go after this input: its pose in full
        self._last_id = 0  # the input id of the pose shown last
        self._wake = threading.Event()
        self._stop = False
        self._serial = 0
        self._loop: asyncio.AbstractEventLoop | None = None
        self._playing_task: asyncio.Task[Any] | None = None
        self._drawn = threading.Event()
        self._camera: dict[str, Any] | None = None  # the run's pictures' camera, once known
        self._names = self.src.names
        self._init_state()
        self._build_ui()
        self.server.trigger("mw_input")(self._on_input)
        self.server.trigger("mw_write")(self._on_write)
        self.server.trigger("mw_play")(self._on_play)
        self.server.trigger("mw_camera")(self._set_camera)
        self.server.trigger("mw_hello")(self._on_hello)
        self.server.trigger("mw_still")(self._on_still)
        self.server.controller.on_server_ready.add(self._on_ready)
        self.state.change("colour")(self._on_colour)
        self._thread = threading.Thread(target=self._work, name="musclewrap-solver", daemon=True)

    # ------------------------------------------------------------------ parts
    def _init_state(self) -> None:
        st = self.state
        st.colour = "stretch"
        st.part_names = self._names
        st.bone_look = {"color": [0.89, 0.86, 0.79]}
        st.lines_look = {"color": [0.1, 0.1, 0.1], "lineWidth": 2}
        st.fibres_look = {"color": [0.55, 0.1, 0.1], "lineWidth": 1}
        st.background = [1, 1, 1]
        st.thumbs = {"serial": 0, "values": {}}
        st.playing = False
        st.status = self.src.first_status
        st.warning = ""
        st.written = ""
        st.shown = {"serial": 0, "id": 0, "server": 0.0, "solve": 0.0}
        st.time_text = time_text(self.times, self.n_frames, 0)
        for i, c in enumerate(self.coords):
            self._values[c.name] = v = 0.5 * (c.low + c.high)
            st[f"q{i}_label"] = f"{v:.2f} {c.unit}"
        for kind, names in self._names.items():
            for i, _ in enumerate(names):
                # nothing yet (vtk.js leaves a null array alone); the lighter surfaces too
                for part in ("_p", "_c", "_f", "_lp", "_lc", "_lf"):
                    st[f"{kind}{i}{part}"] = None
        # the full surfaces shown, or the lighter ones while a slider moves
        st.light = False
        st.light_note = ""
        st.look_full, st.look_light = _LOOKS[False]
        # the triangles, once: only the points move (a live scene's with its first pose)
        for kind, F in self.src.faces().items():
            st[kind] = F

    # ------------------------------------------------------------------ the page
    def _build_ui(self) -> None:
        from trame.ui.html import DivLayout
        from trame.widgets import client, html
        from trame.widgets import vtk as vtkw

        title = self.src.title
        with DivLayout(self.server) as layout:
            self.ui = layout
            client.Style(_CSS)
            with html.Div(classes="mw"):
                with html.Div(classes="mw-side"):
                    html.H1(title)
                    for i, c in enumerate(self.coords):
                        _slider(
                            html, c.name, f"q{i}",
                            (c.low, c.high, (c.high - c.low) / 1000.0, self._values[c.name]), c.name,
                            f"{{{{ q{i}_label }}}}",
                        )  # fmt: skip
                    _slider(
                        html, "time", "frame", (0, max(0, self.n_frames - 1), 1, 0), "__frame__",
                        "{{ time_text }}",
                    )  # fmt: skip
                    html.Button(
                        "{{ playing ? 'Pause' : 'Play' }}", click="trigger('mw_play')", id="play"
                    )
                    html.Button("Reset view", click="trigger('mw_camera')", id="reset-view")
                    if self.src.can_write:
                        html.Button("Write this pose", click="trigger('mw_write')", id="write")
                    with html.Div(classes="mw-row"):
                        html.Label("colour", for_="colour", __properties=[("for_", "for")])
                        offered = self.src.colourings
                        what = self.src.kept_out_of
                        with html.Select(v_model=("colour",), id="colour"):
                            for key in offered:
                                html.Option(COLOURS[key][0].format(what=what), value=key)
                        for key in offered:
                            _, gradient, words = COLOURS[key]
                            words = words.format(what=what)
                            cond = f"colour == '{key}'"
                            html.Div(
                                classes="mw-legend",
                                style=f"background: linear-gradient(to right, {gradient})",
                                v_if=cond,
                            )
                            html.Div(words, v_if=cond, classes="mw-value")
                    html.Div("{{ written }}", id="written", classes="mw-value")
                with html.Div(classes="mw-main"):
                    html.Div("{{ warning }}", classes="mw-warn", id="warning", v_if="warning")
                    with html.Div(classes="mw-view"):
                        with vtkw.VtkView(ref="view", background=("background",)) as view:
                            self.view = view
                            self._representations(vtkw)
                    with html.Div(classes="mw-status", id="status"):
                        html.Div("update -", id="mw-update")
                        html.Div("{{ light_note }}", id="mw-light", v_if="light")
                        html.Div("{{ status }}", id="mw-figures")

    def _representations(self, vtkw: Any) -> None:
        # each surface twice: in full, and lighter while a slider moves (`Lighter`)
        for i, _ in enumerate(self._names["bone"]):
            for s, look in (("_", "look_full"), ("_l", "look_light")):
                with vtkw.VtkGeometryRepresentation(property=("bone_look",), actor=(look,)):
                    vtkw.VtkPolyData(
                        f"bone{i}{s.rstrip('_')}",
                        points=_typed(f"bone{i}{s}p", "f32"),
                        polys=_typed(f"bone{i}{s}f", "u32"),
                    )
        for i, _ in enumerate(self._names["muscle"]):
            for s, look in (("_", "look_full"), ("_l", "look_light")):
                with vtkw.VtkGeometryRepresentation(actor=(look,)):
                    with vtkw.VtkPolyData(
                        f"muscle{i}{s.rstrip('_')}",
                        points=_typed(f"muscle{i}{s}p", "f32"),
                        polys=_typed(f"muscle{i}{s}f", "u32"),
                    ):
                        with vtkw.VtkPointData():
                            # RGB as they are (unsigned char colours are not mapped by vtk.js)
                            vtkw.VtkDataArray(
                                registration="setScalars", name="colour", type="Uint8Array",
                                number_of_components=("3",), values=_typed(f"muscle{i}{s}c", "u8"),
                            )  # fmt: skip
        for kind in ("lines", "fibres"):
            for i, _ in enumerate(self._names[kind]):
                with vtkw.VtkGeometryRepresentation(property=(f"{kind}_look",)):
                    vtkw.VtkPolyData(
                        f"{kind}{i}",
                        points=_typed(f"{kind}{i}_p", "f32"),
                        lines=_typed(f"{kind}{i}_f", "u32"),
                    )

    # ------------------------------------------------------------------ events (server loop)
    def _on_ready(self, **_: Any) -> None:
        self._loop = asyncio.get_event_loop()
        if not self._thread.is_alive():
            self._thread.start()
        self.request(Request("frame", frame=0))

    def _on_hello(self) -> None:
        # a page (a new one, or one loaded again) has its script running: the camera,
        # once the first pose is there (a page that came later than its geometry)
        if self._serial:
            self._camera_soon()

    def _on_input(self, name: str, value: float, ident: int = 0, moving: bool = False) -> None:
        if name == "__frame__":
            self._frame = int(round(value))
            self.request(Request("frame", frame=self._frame, id=int(ident), moving=bool(moving)))
            return
        self._values[name] = float(value)
        self.request(
            Request("values", values=dict(self._values), id=int(ident), moving=bool(moving))
        )

    def _on_still(self, ident: int = 0) -> None:
        # the slider let go after input ``ident``: that pose, and any before, in full
        self._still_id = max(self._still_id, int(ident))
        self._wake.set()

    def _on_write(self) -> None:
        self._writes += 1
        self._wake.set()

    def _on_play(self) -> None:
        self.state.playing = not self.state.playing
        if self.state.playing and self._playing_task is None:
            self._playing_task = asyncio.ensure_future(self._play())

    def _on_colour(self, colour: str, **_: Any) -> None:
        if colour not in self.src.colourings or self._serial == 0:
            return  # (the first pose comes in the colouring shown)
        # the colours in the solver thread (contact's distances take a few tens of ms)
        self._recolour = True
        self._wake.set()

    async def _play(self) -> None:
        try:
            while self.state.playing:
                k = self._frame = (self._frame + 1) % max(1, self.n_frames)
                self._drawn.clear()
                self.request(Request("frame", frame=k))
                # the next frame once this one is sent (at most 30 a second)
                t = time.perf_counter()
                while not self._drawn.is_set() and self.state.playing:
                    await asyncio.sleep(0.005)
                await asyncio.sleep(max(0.0, 1 / 30 - (time.perf_counter() - t)))
        finally:
            self._playing_task = None

    def request(self, r: Request) -> None:
        """Ask for a pose (the latest request wins)."""
        self._want = r
        self._wake.set()

    # ------------------------------------------------------------------ the solver thread
    def _work(self) -> None:
        light_due = True
        while not self._stop:
            idle = not self._wake.wait(timeout=1.0)
            if idle and light_due and self._serial:
                # a second with nothing asked after the first picture: the lighter surfaces
                # (their colours too), for the first slider moved; not sooner, where the
                # browser is still drawing the first picture on the same cores
                light_due = False
                extra = self.src.lighter()
                if extra:
                    extra.update(self.src.colours(self.state.colour))
                    self._send(extra)
            if idle:
                continue
            self._wake.clear()
            while self._writes:
                self._writes -= 1
                self._write()
            if self._recolour:
                self._recolour = False
                self._send(self.src.colours(self.state.colour))
            r, self._want = self._want, None
            if r is not None:
                try:
                    self._show(r)
                except Exception as exc:  # noqa: BLE001  # shown on the page, the server goes on
                    self._send({"warning": f"this pose failed: {exc}"})
            if self._want is None and self._still_id >= self._last_id:
                self._show_still()  # (nothing where the pose shown is in full)

    def _camera_soon(self) -> None:
        """The camera set 0.3 and 1 s from now (on the loop): once the page's view is up."""
        if self._loop is not None:
            self._loop.call_later(0.3, self._set_camera)
            self._loop.call_later(1.0, self._set_camera)

    def _set_camera(self) -> None:
        """The view to the run's pictures' camera (the side of the limb, the muscles framed)."""
        if self._camera is not None:
            self.view.set_camera(self._camera)

    def _show(self, r: Request) -> None:
        t0 = time.perf_counter()
        if self._camera is None:
            # framed for a square view: whole in any view wider than it is tall
            v = self.src.view(size=(1, 1))
            self._camera = {
                "focalPoint": list(v.focal), "position": list(v.position), "viewUp": list(v.up),
                "viewAngle": v.angle, "centerOfRotation": list(v.focal),
            }  # fmt: skip
        if r.moving and r.id <= self._still_id:  # let go before its pose was solved
            r = replace(r, moving=False)
        update, t_solve = self.src.pose(r, self._values, self.state.colour)
        if update.get("light") and r.id <= self._still_id:  # let go while it was solved
            update.update(self.src.still())
        if r.kind == "frame":
            # the coordinates' sliders go to the frame's pose; the time slider too unless the
            # hand is on it
            moved = {f"q{i}": self._values[c.name] for i, c in enumerate(self.coords)}
            if not r.id:
                moved["frame"] = r.frame
            update["thumbs"] = {"serial": self._serial + 1, "values": moved}
        self._serial += 1
        update["shown"] = {
            "serial": self._serial,
            "id": r.id,
            "server": 1e3 * (time.perf_counter() - t0),
            "solve": 1e3 * t_solve,
        }
        update["look_full"], update["look_light"] = _LOOKS[bool(update.get("light"))]
        self._last_id = r.id
        self._send(update)
        if self._serial == 1:
            self.src.after_first()

    def _show_still(self) -> None:
        """The pose shown last, in full where it was shown lighter (a picture of its own)."""
        t0 = time.perf_counter()
        update = self.src.still()
        if not update:
            return
        update["look_full"], update["look_light"] = _LOOKS[False]
        self._serial += 1
        update["shown"] = {
            "serial": self._serial,
            "id": self._last_id,
            "server": 1e3 * (time.perf_counter() - t0),
            "solve": 0.0,
        }
        self._send(update)

    def _write(self) -> None:
        if not self.src.can_write or self._serial == 0:
            return  # a run played back, or no pose shown yet
        self.output.mkdir(parents=True, exist_ok=True)
        k = 0
        while (self.output / f"pose_{k:03d}").exists():
            k += 1
        folder = self.output / f"pose_{k:03d}"
        try:
            files = self.src.write(folder)
        except OSError as exc:
            self._send({"written": f"could not write {folder}: {exc}"})
            return
        if files is not None:
            self._send({"written": f"wrote {len(files)} files to {folder.resolve()}"})

    def _send(self, update: dict[str, Any]) -> None:
        loop = self._loop
        if loop is not None and not loop.is_closed():
            try:
                loop.call_soon_threadsafe(self._push, update)
            except RuntimeError:  # closed meanwhile (the server stopped): nobody to tell
                pass

    def _push(self, update: dict[str, Any]) -> None:
        """The state updated (on the server's loop)."""
        with self.state:
            self.state.update(update)
        if update.get("shown", {}).get("serial") == 1:
            self._camera_soon()  # the first geometry is on its way to the pages there
        self._drawn.set()

    # ------------------------------------------------------------------ running
    def show(self, port: int | None = None, *, height: int = 640) -> Frame:
        """In a notebook: serve the page on the notebook's event loop and show it in the cell.

        Returns an object the notebook draws as the page in an iframe (the cell's output);
        the server runs as a task of the running event loop until the kernel stops.
        """
        port = free_port() if port is None else port
        self.server.start(
            port=port, host="127.0.0.1", open_browser=False, exec_mode="task",
            show_connection_info=False,
        )  # fmt: skip
        return Frame(f"http://127.0.0.1:{port}/", height)

    def start(
        self,
        port: int | None = None,
        *,
        open_browser: bool = True,
        say: Callable[[str], None] = print,
        **kw: Any,
    ) -> None:
        """Serve the page at ``http://127.0.0.1:PORT/`` until interrupted (blocks)."""
        port = free_port() if port is None else port
        say(f"musclewrap view: http://127.0.0.1:{port}/")
        with contextlib.suppress(KeyboardInterrupt):
            self.server.start(
                port=port,
                host="127.0.0.1",
                open_browser=open_browser,
                show_connection_info=False,
                **kw,
            )
        self._stop = True
        self._wake.set()
