"""The viewer's web page (trame): sliders and a time slider, the muscles wrapping live.

One page serves two sources:

- a scene (`musclewrap.scene.LiveScene`): every slider change is solved as a run
  solves that pose, in one solver thread that always takes the latest request (a
  drag is not queued behind itself), and the muscles, bones, lines and fibres are
  sent to the browser, where vtk.js draws them;
- a finished run's ``scene.pvd`` (`._playback.Series`): the time slider and
  play/pause step through its files.

The browser measures each update, from the slider's input event to the picture
drawn (two animation frames after the new geometry arrived), and writes the status
line: ``update N ms (median M ms of the last 10; queued Q, solve S, transfer X, render R)``
(queued: while the pose before was being solved; one pose at a time is asked for).
"""

from __future__ import annotations

import asyncio
import base64
import contextlib
import os
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ..constants import defaults
from ..mesh import apply_transform
from ..output import STRETCH_RANGE, stretch_colours, stretch_table
from ..run import LiveScene, PoseResult
from ._playback import Series, segments, triangles

__all__ = ["Viewer", "free_port", "open_source"]


def _rgb(c: np.ndarray) -> str:
    r, g, b = np.rint(255.0 * np.asarray(c)).astype(int)
    return f"rgb({r}, {g}, {b})"


#: the contact colouring: black (touching), red halfway, yellow at
#: ``defaults.view_contact_reach`` and beyond
_CONTACT_STOPS = np.array([[0.0, 0.0, 0.0], [0.9, 0.0, 0.0], [0.9, 0.9, 0.0]])


def contact_colours(distance: np.ndarray) -> np.ndarray:
    """Each distance's colour: (k, 3) uint8 (mesh units, clipped to ``defaults.view_contact_reach``)."""
    u = (
        np.clip(np.asarray(distance, dtype=np.float64), 0.0, defaults.view_contact_reach)
        / defaults.view_contact_reach
    )
    at = np.linspace(0.0, 1.0, len(_CONTACT_STOPS))
    rgb = np.column_stack([np.interp(u, at, _CONTACT_STOPS[:, k]) for k in range(3)])
    return np.rint(255.0 * rgb).astype(np.uint8)


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
        ", ".join(_rgb(_STRETCH[i]) for i in (0, len(_STRETCH) // 2, -1)),
        f"blue {STRETCH_RANGE[0]:.2f} (compressed), white 1, red {STRETCH_RANGE[1]:.2f} "
        "(stretched), in equal ratios",
    ),
    "contact": (
        f"contact (distance to {{what}}, 0-{defaults.view_contact_reach:g} mm)",
        ", ".join(_rgb(c) for c in _CONTACT_STOPS),
        f"black: touching {{what}}, yellow: {defaults.view_contact_reach:g} mm or more away",
    ),
}

_CSS = """
body { margin: 0; font-family: system-ui, sans-serif; font-size: 14px; }
.mw { display: flex; height: 100vh; }
.mw-side { width: 330px; padding: 10px 14px; overflow-y: auto; border-right: 1px solid #ccc; }
.mw-main { flex: 1; display: flex; flex-direction: column; min-width: 0; }
.mw-view { flex: 1; position: relative; min-height: 200px; }
.mw-row { margin: 6px 0 10px 0; }
.mw-row label { display: block; font-weight: 600; }
.mw-row input[type=range], .mw-row select { width: 100%; box-sizing: border-box; }
.mw-value { color: #444; font-variant-numeric: tabular-nums; }
.mw-status { padding: 6px 12px; border-top: 1px solid #ccc; background: #f6f6f6;
  font-variant-numeric: tabular-nums; white-space: pre-wrap; }
.mw-warn { padding: 6px 12px; background: #ffd54f; color: #000; font-weight: 600; }
.mw-legend { height: 12px; margin: 4px 0; border: 1px solid #999; }
button { margin: 4px 6px 4px 0; padding: 4px 10px; }
h1 { font-size: 16px; margin: 4px 0 10px 0; }
"""

# The page's measuring: each slider input gets an id and a time; the server answers
# with the id it drew; two animation frames after the geometry arrives, the picture
# is on screen. One pose at a time is asked for: inputs that come while one is being
# solved wait, the latest replacing the one before, and go when its geometry arrives
# (its drawing then overlaps the next solve). So a drag sends one message a picture,
# not one an input event: 60 a second would keep the server's event loop from the
# solver's results.
_JS = r"""
(function () {
  const mw = (window.mw = window.mw || { n: 0, t: {}, sent: {}, totals: [], log: [], last: null });
  // A browser that draws in software (Chromium's SwiftShader, Mesa's llvmpipe) takes 2-3 times
  // as long to draw the scene antialiased (BENCHMARKS.md, "The live viewer"): there the view's
  // WebGL context is made without (before vtk.js makes it); ?antialias=1 or 0 in the address
  // decides instead. A graphics processor antialiases at little cost: it keeps it.
  if (mw.antialias === undefined) {
    let name = "";
    try {
      const probe = document.createElement("canvas").getContext("webgl");
      const info = probe && probe.getExtension("WEBGL_debug_renderer_info");
      name = probe ? String(probe.getParameter(info ? info.UNMASKED_RENDERER_WEBGL : probe.RENDERER)) : "";
      const lose = probe && probe.getExtension("WEBGL_lose_context");
      if (lose) lose.loseContext();
    } catch (e) { /* no WebGL: vtk.js says so */ }
    const asked = new URLSearchParams(window.location.search).get("antialias");
    mw.renderer = name;
    mw.software = /swiftshader|llvmpipe|softpipe|software/i.test(name);
    mw.antialias = asked === null ? !mw.software : asked !== "0";
    if (!mw.antialias) {
      const make = HTMLCanvasElement.prototype.getContext;
      HTMLCanvasElement.prototype.getContext = function (type, attrs) {
        if (type === "webgl2" || type === "webgl") attrs = Object.assign({}, attrs, { antialias: false });
        return make.call(this, type, attrs);
      };
    }
  }
  let inflight = null, pending = null;  // the input being solved (id, time sent), the next
  function send(p) {
    inflight = { id: p.id, at: performance.now() };
    mw.sent[p.id] = inflight.at;
    window.trame.trigger("mw_input", [p.source, p.value, p.id]);
  }
  document.addEventListener("input", (e) => {
    const el = e.target;
    if (!el || !el.dataset || !el.dataset.mw || !window.trame) return;
    const id = ++mw.n;
    mw.t[id] = performance.now();
    const p = { source: el.dataset.mw, value: parseFloat(el.value), id };
    // a pose asked for more than 3 s ago and not come back (a failed one): ask anyway
    if (inflight && performance.now() - inflight.at < 3000) pending = p; else send(p);
  }, true);
  function median(a) { const s = [...a].sort((x, y) => x - y); return s[Math.floor(s.length / 2)]; }
  function shown(s) {
    if (!s || !s.serial) return;
    const got = performance.now();
    // the pose asked for is here (or another's, which replaced it: play): the next one goes
    if (inflight && (!s.id || s.id >= inflight.id)) {
      inflight = null;
      if (pending) { const p = pending; pending = null; send(p); }
    }
    requestAnimationFrame(() => requestAnimationFrame(() => {
      const drawn = performance.now();
      const t0 = s.id && mw.t[s.id] !== undefined ? mw.t[s.id] : got;
      const sent = s.id && mw.sent[s.id] !== undefined ? mw.sent[s.id] : t0;
      for (const k of Object.keys(mw.t)) if (+k <= s.id) { delete mw.t[k]; delete mw.sent[k]; }
      const total = drawn - t0, render = drawn - got, queued = sent - t0;
      const transfer = Math.max(0, got - sent - s.server);
      mw.totals.push(total); if (mw.totals.length > 10) mw.totals.shift();
      mw.last = { serial: s.serial, id: s.id, total, render, transfer, queued, server: s.server,
                  solve: s.solve, drawn, count: (mw.last ? mw.last.count : 0) + 1 };
      mw.log.push(mw.last);  // the last pictures drawn, for a drag's rate
      if (mw.log.length > 1000) mw.log.shift();
      const el = document.getElementById("mw-update");
      if (el) {
        el.textContent = `update ${total.toFixed(0)} ms (median ${median(mw.totals).toFixed(0)} ms `
          + `of the last ${mw.totals.length}; queued ${queued.toFixed(0)}, solve `
          + `${s.solve.toFixed(0)}, transfer `
          + `${transfer.toFixed(0)}, render ${render.toFixed(0)} ms)`
          + (mw.software ? `; drawn in software, antialiasing ${mw.antialias ? "on" : "off"}` : "");
        el.dataset.serial = String(s.serial);
      }
    }));
  }
  // the server moves a slider's thumb only where the pose comes from elsewhere (a frame:
  // the coordinates' sliders, or play: the time slider); the slider the hand holds is the page's
  function thumbs(t) {
    if (!t || !t.values) return;
    for (const [id, v] of Object.entries(t.values)) {
      const el = document.getElementById(id);
      if (el) el.value = String(v);
    }
  }
  function hook() {
    if (!window.trame || !window.trame.state) { setTimeout(hook, 50); return; }
    window.trame.state.watch(["shown"], shown);
    window.trame.state.watch(["thumbs"], thumbs);
    // a pose there before this page came (a page loaded again, or after its first pose)
    thumbs(window.trame.state.get("thumbs"));
    shown(window.trame.state.get("shown"));
    window.trame.trigger("mw_hello");
  }
  hook();
})();
"""


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


def _enc(a: np.ndarray, dtype: Any) -> dict[str, Any] | list[Any]:
    """An array in the form the page decodes (base64 of its bytes, with its type).

    An empty one as an empty list (vtk.js cannot decode an empty base64 string).
    """
    b = np.ascontiguousarray(a, dtype=dtype).ravel()
    if not b.size:
        return []
    return {
        "bvals": base64.b64encode(b.tobytes()).decode("ascii"),
        "dtype": str(b.dtype),
        "shape": [b.size],
    }


def _cells(F: np.ndarray) -> dict[str, Any] | list[Any]:
    """Cells (k, n) in VTK's legacy form: ``n, i0, ..., n, i0, ...``."""
    F = np.asarray(F)
    if not len(F):
        return _enc(np.zeros(0), np.uint32)
    return _enc(np.column_stack([np.full(len(F), F.shape[1]), F]), np.uint32)


def _points(P: np.ndarray) -> dict[str, Any] | list[Any]:
    P = np.where(np.isfinite(P), P, 0.0)
    return _enc(P, np.float32)


def _polylines(
    lines: list[np.ndarray],
) -> tuple[dict[str, Any] | list[Any], dict[str, Any] | list[Any]]:
    """Poly-lines as one point array and one cell array."""
    if not lines:
        return _points(np.zeros((0, 3))), _enc(np.zeros(0), np.uint32)
    P = np.vstack(lines)
    cells, o = [], 0
    for pts in lines:
        cells += [len(pts), *range(o, o + len(pts))]
        o += len(pts)
    return _points(P), _enc(np.array(cells), np.uint32)


@dataclass
class _Request:
    kind: str  # "values" or "frame"
    values: dict[str, float] = field(default_factory=dict)
    frame: int | None = None
    id: int = 0


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
        self.live = isinstance(source, LiveScene)
        self.output = Path(output) if output is not None else Path("musclewrap_poses")
        self.server = server or get_server(f"musclewrap-{id(self)}", client_type="vue3")
        self.state, self.ctrl = self.server.state, self.server.controller
        self.n_frames = source.n_frames if self.live else len(source)
        self.times = source.times
        self.coords = source.coordinates if self.live else []
        self._want: _Request | None = None
        # the sliders as the user left them: a solved pose is not sent back to the slider the
        # user holds (a pose behind the hand would pull its thumb back)
        self._values: dict[str, float] = {}
        self._frame = 0
        self._writes = 0  # "Write this pose" clicks not yet served
        self._recolour = False  # the colour menu changed: the shown pose's colours due
        self._wake = threading.Event()
        self._stop = False
        self._serial = 0
        self._sent: dict[str, Any] = {}  # per bone: its transform (or file) last sent
        self._last: PoseResult | None = None
        self._loop: asyncio.AbstractEventLoop | None = None
        self._playing_task: asyncio.Task[Any] | None = None
        self._drawn = threading.Event()
        self._camera: dict[str, Any] | None = None  # the run's pictures' camera, once known
        self._names = self._part_names()
        self._init_state()
        self._build_ui()
        self.server.trigger("mw_input")(self._on_input)
        self.server.trigger("mw_write")(self._on_write)
        self.server.trigger("mw_play")(self._on_play)
        self.server.trigger("mw_camera")(self._set_camera)
        self.server.trigger("mw_hello")(self._on_hello)
        self.server.controller.on_server_ready.add(self._on_ready)
        self.state.change("colour")(self._on_colour)
        self._thread = threading.Thread(target=self._work, name="musclewrap-solver", daemon=True)

    # ------------------------------------------------------------------ parts
    def _part_names(self) -> dict[str, list[str]]:
        if self.live:
            src: LiveScene = self.source  # type: ignore[assignment]
            return {
                "muscle": [j.name for j in src.jobs],
                "bone": list(src.bone_body),
                "lines": [j.name for j in src.jobs],
                "fibres": [j.name for j in src.jobs] if src.scene.fibres is not None else [],
            }
        s: Series = self.source  # type: ignore[assignment]
        out: dict[str, list[str]] = {"muscle": [], "bone": [], "lines": [], "fibres": []}
        for name, kind in s.parts.items():
            out[kind].append(name)
        return out

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
        st.status = "solving the first pose ..." if self.live else "reading the first frame ..."
        st.warning = ""
        st.written = ""
        st.shown = {"serial": 0, "id": 0, "server": 0.0, "solve": 0.0}
        st.time_text = self._time_text(0)
        for i, c in enumerate(self.coords):
            self._values[c.name] = v = 0.5 * (c.low + c.high)
            st[f"q{i}_label"] = f"{v:.2f} {c.unit}"
        for kind, names in self._names.items():
            for i, _ in enumerate(names):
                # nothing yet (vtk.js leaves a null array alone)
                st[f"{kind}{i}_p"] = st[f"{kind}{i}_c"] = st[f"{kind}{i}_f"] = None
        # the triangles, once: only the points move (a scene's with its first pose: its
        # muscles' solvers are built in the solver thread, while the page loads)
        self._faces_due = self.live
        if not self.live:
            for kind, F in self._faces().items():
                st[kind] = _cells(F)

    def _faces(self) -> dict[str, np.ndarray]:
        """Each muscle's and bone's triangles, by the name of their state."""
        out = {}
        if self.live:
            src: LiveScene = self.source  # type: ignore[assignment]
            self._bone_meshes = src.bone_meshes()
            for i, n in enumerate(self._names["muscle"]):
                out[f"muscle{i}_f"] = src.muscle_faces(n)
            for i, b in enumerate(self._names["bone"]):
                out[f"bone{i}_f"] = self._bone_meshes[b][1]
            return out
        s: Series = self.source  # type: ignore[assignment]
        for kind in ("muscle", "bone"):
            for i, n in enumerate(self._names[kind]):
                first = next((k for k in range(len(s)) if n in s.files[k]), None)
                if first is not None:
                    out[f"{kind}{i}_f"] = triangles(s.part(first, n))  # type: ignore[arg-type]
        return out

    def _time_text(self, k: int) -> str:
        t = float(self.times[k]) if len(self.times) else 0.0
        return f"frame {k} of {self.n_frames - 1}, t = {t:.3f} s"

    # ------------------------------------------------------------------ the page
    def _build_ui(self) -> None:
        from trame.ui.html import DivLayout
        from trame.widgets import client, html
        from trame.widgets import vtk as vtkw

        title = (
            f"musclewrap view: {self.source.scene.name or self.source.scene.path.name}"
            if self.live
            else f"musclewrap view: {self.source.folder}"
        )
        with DivLayout(self.server) as layout:
            self.ui = layout
            client.Style(_CSS)
            client.Script(_JS)
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
                    if self.live:
                        html.Button("Write this pose", click="trigger('mw_write')", id="write")
                    with html.Div(classes="mw-row"):
                        html.Label("colour", for_="colour", __properties=[("for_", "for")])
                        offered = list(COLOURS) if self.live else ["stretch"]
                        what = self._kept_out_of()
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
                        html.Div("{{ status }}", id="mw-figures")

    def _kept_out_of(self) -> str:
        """What the contact colouring measures to: the bones, and the muscles kept apart."""
        if self.live and self.source.grouped:  # type: ignore[union-attr]
            return "a bone or another muscle"
        return "a bone"

    def _representations(self, vtkw: Any) -> None:
        for i, _ in enumerate(self._names["bone"]):
            with vtkw.VtkGeometryRepresentation(property=("bone_look",)):
                vtkw.VtkPolyData(f"bone{i}", points=(f"bone{i}_p",), polys=(f"bone{i}_f",))
        for i, _ in enumerate(self._names["muscle"]):
            with vtkw.VtkGeometryRepresentation():
                with vtkw.VtkPolyData(
                    f"muscle{i}", points=(f"muscle{i}_p",), polys=(f"muscle{i}_f",)
                ):
                    with vtkw.VtkPointData():
                        # RGB as they are (unsigned char colours are not mapped by vtk.js)
                        vtkw.VtkDataArray(
                            registration="setScalars", name="colour", type="Uint8Array",
                            number_of_components=("3",), values=(f"muscle{i}_c",),
                        )  # fmt: skip
        for kind in ("lines", "fibres"):
            for i, _ in enumerate(self._names[kind]):
                with vtkw.VtkGeometryRepresentation(property=(f"{kind}_look",)):
                    vtkw.VtkPolyData(
                        f"{kind}{i}", points=(f"{kind}{i}_p",), lines=(f"{kind}{i}_f",)
                    )

    # ------------------------------------------------------------------ events (server loop)
    def _on_ready(self, **_: Any) -> None:
        self._loop = asyncio.get_event_loop()
        if not self._thread.is_alive():
            self._thread.start()
        self.request(_Request("frame", frame=0))

    def _on_hello(self) -> None:
        # a page (a new one, or one loaded again) has its script running: the camera,
        # once the first pose is there (a page that came later than its geometry)
        if self._serial:
            self._camera_soon()

    def _on_input(self, name: str, value: float, ident: int = 0) -> None:
        if name == "__frame__":
            self._frame = int(round(value))
            self.request(_Request("frame", frame=self._frame, id=int(ident)))
            return
        self._values[name] = float(value)
        self.request(_Request("values", values=dict(self._values), id=int(ident)))

    def _on_write(self) -> None:
        self._writes += 1
        self._wake.set()

    def _on_play(self) -> None:
        self.state.playing = not self.state.playing
        if self.state.playing and self._playing_task is None:
            self._playing_task = asyncio.ensure_future(self._play())

    def _on_colour(self, colour: str, **_: Any) -> None:
        if colour not in COLOURS or self._last is None:
            return  # (the first pose comes in the colouring shown)
        # the colours in the solver thread (contact's distances take a few tens of ms)
        self._recolour = True
        self._wake.set()

    async def _play(self) -> None:
        try:
            while self.state.playing:
                k = self._frame = (self._frame + 1) % max(1, self.n_frames)
                self._drawn.clear()
                self.request(_Request("frame", frame=k))
                # the next frame once this one is sent (at most 30 a second)
                t = time.perf_counter()
                while not self._drawn.is_set() and self.state.playing:
                    await asyncio.sleep(0.005)
                await asyncio.sleep(max(0.0, 1 / 30 - (time.perf_counter() - t)))
        finally:
            self._playing_task = None

    def request(self, r: _Request) -> None:
        """Ask for a pose (the latest request wins)."""
        self._want = r
        self._wake.set()

    # ------------------------------------------------------------------ the solver thread
    def _work(self) -> None:
        while not self._stop:
            self._wake.wait()
            self._wake.clear()
            while self._writes:
                self._writes -= 1
                self._write()
            if self._recolour:
                self._recolour = False
                self._send(self._colours(self._last))
            r, self._want = self._want, None
            if r is None:
                continue
            try:
                self._show(r)
            except Exception as exc:  # noqa: BLE001  # shown on the page, the server goes on
                self._send({"warning": f"this pose failed: {exc}"})

    def _camera_soon(self) -> None:
        """The camera set 0.3 and 1 s from now (on the loop): once the page's view is up."""
        if self._loop is not None:
            self._loop.call_later(0.3, self._set_camera)
            self._loop.call_later(1.0, self._set_camera)

    def _set_camera(self) -> None:
        """The view to the run's pictures' camera (the side of the limb, the muscles framed)."""
        if self._camera is not None:
            self.view.set_camera(self._camera)

    def _show(self, r: _Request) -> None:
        t0 = time.perf_counter()
        if self._camera is None:
            # framed for a square view: whole in any view wider than it is tall
            v = self.source.view(size=(1, 1))
            self._camera = {
                "focalPoint": list(v.focal), "position": list(v.position), "viewUp": list(v.up),
                "viewAngle": v.angle, "centerOfRotation": list(v.focal),
            }  # fmt: skip
        if self.live:
            src: LiveScene = self.source  # type: ignore[assignment]
            res = src.solve(
                r.values if r.kind == "values" else None,
                frame=r.frame if r.kind == "frame" else None,
            )
            self._last = res
            t_solve = time.perf_counter() - t0
            update = self._live_state(res, r)
        else:
            update = self._series_state(int(r.frame or 0))
            t_solve = time.perf_counter() - t0
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
        self._send(update)
        if self.live and self._serial == 1:
            # the contact colours' distances once, after the first picture: their kernels
            # compiled (or read from Numba's cache) before the colour menu asks for them
            self.source.contact(self._last)  # type: ignore[union-attr]

    def _live_state(self, res: PoseResult, r: _Request) -> dict[str, Any]:
        up: dict[str, Any] = {}
        if self._faces_due:  # the triangles, with the first pose
            up.update({kind: _cells(F) for kind, F in self._faces().items()})
            self._faces_due = False
        for i, b in enumerate(self._names["bone"]):
            T = res.bones[b]
            if not np.array_equal(self._sent.get(b), T):  # a bone moved in the output frame
                V = self._bone_meshes[b][0]
                up[f"bone{i}_p"] = _points(apply_transform(T, V))
                self._sent[b] = T
        for i, n in enumerate(self._names["muscle"]):
            up[f"muscle{i}_p"] = _points(res.muscles[n])
            up[f"lines{i}_p"], up[f"lines{i}_f"] = _polylines(res.lines[n])
        for i, n in enumerate(self._names["fibres"]):
            P = res.fibres.get(n)
            up[f"fibres{i}_p"], up[f"fibres{i}_f"] = _polylines([] if P is None else list(P))
        up.update(self._colours(res))
        if r.frame is not None:
            up["time_text"] = self._time_text(r.frame)
        else:
            up["time_text"] = "a pose of the sliders (not a frame)"
        for i, c in enumerate(self.coords):
            v = float(res.values[c.name])
            up[f"q{i}_label"] = f"{v:.2f} {c.unit}"  # the pose shown
            if r.kind == "frame":  # the sliders go to the frame's pose
                self._values[c.name] = v
        unit = self.source.scene.mesh_unit  # type: ignore[union-attr]
        overlap = res.overlap
        up["status"] = (
            f"volume error {res.volume_error:.1e} (largest of {len(res.rows)} muscles) · deepest "
            f"in a bone {res.penetration:.3g} {unit}"
            + ("" if np.isnan(overlap) else f" · deepest in another muscle {overlap:.3g} {unit}")
            + f" · iterations {max(row['iterations'] for row in res.rows.values())}"
        )
        bad = res.unconverged
        up["warning"] = (
            "NOT CONVERGED at this pose: "
            + "; ".join(f"{n}: {why}" for n, why in bad.items())
            + " (the muscles shown are the solver's last iterate)"
            if bad
            else ""
        )
        return up

    def _colours(self, res: PoseResult) -> dict[str, Any]:
        """The muscles' colours of a pose (RGB), in the colouring the menu shows."""
        contact = self.state.colour == "contact"
        up: dict[str, Any] = {}
        for i, n in enumerate(self._names["muscle"]):
            if contact:
                rgb = contact_colours(self.source.contact(res)[n])  # type: ignore[union-attr]
            else:
                rgb = stretch_colours(res.stretch[n])
            up[f"muscle{i}_c"] = _enc(rgb, np.uint8)
        return up

    def _series_state(self, k: int) -> dict[str, Any]:
        s: Series = self.source  # type: ignore[assignment]
        up: dict[str, Any] = {"time_text": self._time_text(k)}
        for kind in ("muscle", "bone"):
            for i, n in enumerate(self._names[kind]):
                d = s.part(k, n)
                if d is None:
                    continue
                if kind == "bone" and self._sent.get(n) == s.files[k][n]:
                    continue  # the same file as shown: a bone that does not move
                self._sent[n] = s.files[k][n]
                up[f"{kind}{i}_p"] = _points(d["points"])
                if kind == "muscle":
                    c = d.get("point:area_stretch", np.ones(len(d["points"])))
                    up[f"muscle{i}_c"] = _enc(stretch_colours(c), np.uint8)
        for kind in ("lines", "fibres"):
            for i, n in enumerate(self._names[kind]):
                d = s.part(k, n)
                if d is None:
                    continue
                up[f"{kind}{i}_p"] = _points(d["points"])
                up[f"{kind}{i}_f"] = _cells(segments(d))
        up["status"] = f"playing back {s.folder / 'scene.pvd'} ({len(s)} frames; no solve)"
        return up

    def _write(self) -> None:
        src = self.source
        res = self._last
        if not self.live or res is None:
            return
        self.output.mkdir(parents=True, exist_ok=True)
        k = 0
        while (self.output / f"pose_{k:03d}").exists():
            k += 1
        folder = self.output / f"pose_{k:03d}"
        try:
            files = src.write(res, folder)  # type: ignore[union-attr]
        except OSError as exc:
            self._send({"written": f"could not write {folder}: {exc}"})
            return
        self._send({"written": f"wrote {len(files)} files to {folder.resolve()}"})

    def _send(self, update: dict[str, Any]) -> None:
        loop = self._loop
        if loop is not None:
            loop.call_soon_threadsafe(self._push, update)

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
