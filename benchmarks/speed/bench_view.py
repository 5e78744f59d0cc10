"""The live viewer in a real browser: time to the first picture, updates per second.

Starts ``musclewrap view SCENE --no-browser`` on a free loopback port, opens it in the OS's
Chromium (Playwright), and measures, as the page itself does (slider input event to the
picture drawn, two animation frames after the geometry arrived):

- the first picture: from the command's start (prepared muscles cached: run once before);
- a drag: the slider moved 1 step at a time through ``--sweep`` (each step waits for its
  picture): the updates per second are steps over the sweep's time; each update's parts
  (solve, transfer, render) as the status line gives them. The sweep runs twice: the first
  time the waypoints between the rest pose and the poses are solved as they come; the
  second ("warm") reuses them.
- a drag as a hand makes it: the slider's input events at 60 a second, each a 1/4 step
  further through the sweep (``--drag-seconds`` long), without waiting for pictures: the
  server solves the latest pose while the browser draws the last one. The updates per
  second are the pictures drawn over the drag's time; the update time the median of theirs.

    python benchmarks/speed/bench_view.py examples/lhdl_walk.toml --variants all bones
    python benchmarks/speed/bench_view.py examples/gait2392_walk.toml --coordinate hip_flexion_r
    python benchmarks/speed/bench_view.py examples/lhdl_walk.toml --phases
    python benchmarks/speed/bench_view.py examples/lhdl_walk.toml --colour contact

- a redraw alone: the page's scene drawn again with nothing changed (vtk.js's render,
  finished by reading back one pixel), 20 times, the median; again with the bones hidden,
  and again with the lighter surfaces the page draws while a slider moves; the first two again antialiased (a second page, ``?antialias=1``: this browser draws in software,
  where the page leaves antialiasing off) and in a smaller view (700 x 450 pixels of page).
  What the browser's drawing costs whatever the solve: the floor of an update here.
- plain WebGL: as many triangles as the scene has, drawn by a few lines of WebGL in a new page
  of the same browser and a canvas of the view's size (no vtk.js, no server), with and without
  antialiasing: the floor of any page drawing this scene in this browser.

``--colour contact``: the muscles coloured by contact through all of it (each pose's
distances to the bones and to the muscles kept apart computed on the server).

``--screenshot PNG [--set COORDINATE=VALUE ...]`` writes the page's picture instead (docs/view.png).

``--compare CHECKOUT ...``: only the first picture and the drag (after the sweep step by step),
of each checkout's viewer in turns, twice: what a change did, in one sitting.

``--profile-page`` (with ``--compare``: of each checkout): the page's own work per update over
the sweep, step by step, by Chrome's sampling profiler: the functions that took the most time
themselves, and the time within vtk.js's colour mapping.

``--phases`` times, without a browser, where the first picture's time and a pose's go: the
check (then again, its measures read back from the cache, and again taken anew), reading the scene (`LiveScene` without its check), the first pose, then per pose (medians
over every 10th frame, warm) the waypoints, the solve, the measures and the contact colours'
distances (then their part to the muscles with the grid's cells 1, 1/2 and 1/3 of the reach
wide), and each muscle's solve alone against its bones.
"""

from __future__ import annotations

import argparse
import contextlib
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parent.parent


def scene_variant(scene: Path, variant: str, tmp: Path) -> Path:
    """The scene as given ("all": bones and muscles kept apart) or with muscles passing."""
    if variant == "all":
        return scene
    text = scene.read_text()
    data = (scene.parent / "../../shared/data").resolve().as_posix()
    text = text.replace("../../shared/data", data)
    if "[collisions]" in text:
        text = text.replace("[collisions]", "[collisions]\nmuscles = false", 1)
    else:
        text += "\n[collisions]\nmuscles = false\n"
    p = tmp / f"{scene.stem}_{variant}.toml"
    p.write_text(text)
    return p


_DRAG = """
async ([label, lo, hi, seconds]) => {
  const el = document.querySelector(`input[aria-label="${label}"]`);
  const mw = window.mw, n0 = mw.last.count, ticks = Math.round(60 * seconds);
  const t0 = performance.now();
  for (let i = 1; i <= ticks; i++) {
    const u = i / ticks, v = lo + (hi - lo) * (u < 0.5 ? 2 * u : 2 - 2 * u);  // there and back
    el.value = String(v);
    el.dispatchEvent(new Event("input", { bubbles: true }));
    await new Promise((r) => setTimeout(r, Math.max(0, t0 + i * 1000 / 60 - performance.now())));
  }
  const last = mw.n;  // the last input's id: wait for its picture
  while (!(mw.last && mw.last.id >= last)) await new Promise((r) => setTimeout(r, 5));
  const t1 = mw.last.drawn;
  const shown = mw.log.filter((r) => r.drawn >= t0 && r.drawn <= t1);
  return { seconds: (t1 - t0) / 1000, pictures: mw.last.count - n0,
           totals: shown.map((r) => r.total), solves: shown.map((r) => r.solve) };
}
"""


# vtk.js's view behind trame's VtkView (its component provides it to its representations)
_REDRAW = """
async (n) => {
  const v = window.trame.refs.view._.provides.view;
  const gl = v.openglRenderWindow.getContext(), px = new Uint8Array(4);
  const actors = v.renderer.getActors();
  const triangles = actors.map((a) => {
    const d = a.getMapper() && a.getMapper().getInputData();
    return d && d.getPolys ? d.getPolys().getNumberOfCells() : 0;
  });
  function times() {
    const ts = [];
    for (let i = 0; i < n; i++) {
      const t = performance.now();
      v.renderWindow.render();
      gl.readPixels(0, 0, 1, 1, gl.RGBA, gl.UNSIGNED_BYTE, px);  // waits for the drawing
      ts.push(performance.now() - t);
    }
    return ts;
  }
  const all = times();
  // the surfaces drawn (in full) and the lighter ones drawn while a slider moves (hidden)
  const shown = actors.map((_, i) => i).filter((i) => actors[i].getVisibility());
  const full = shown.filter((i) => triangles[i] > 0);
  const light = actors.map((_, i) => i).filter((i) => !actors[i].getVisibility() && triangles[i] > 0);
  // the bones are the view's first representations with triangles
  const nb = window.trame.state.get("part_names").bone.length;
  const bones = full.slice(0, nb);
  bones.forEach((i) => actors[i].setVisibility(false));
  const nobones = times();
  bones.forEach((i) => actors[i].setVisibility(true));
  let lighter = [];
  if (light.length) {  // as drawn while a slider moves
    full.forEach((i) => actors[i].setVisibility(false));
    light.forEach((i) => actors[i].setVisibility(true));
    lighter = times();
    light.forEach((i) => actors[i].setVisibility(false));
    full.forEach((i) => actors[i].setVisibility(true));
  }
  v.renderWindow.render();
  const sum = (ix) => ix.reduce((s, i) => s + triangles[i], 0);
  return { all, nobones, lighter, triangles: sum(shown), bone_triangles: sum(bones),
           light_triangles: sum(light), size: v.openglRenderWindow.getSize() };
}
"""


# The browser's own floor: a mesh of as many triangles drawn by plain WebGL (no vtk.js, no
# server, nothing else on the page): an indexed grid of triangles over the view, depth-tested,
# one light, cleared and drawn, finished by reading back one pixel; the median of ``reps``.
_FLOOR = """
([w, h, counts, aa, reps]) => {
  const c = document.createElement("canvas");
  c.width = w; c.height = h; document.body.appendChild(c);
  const gl = c.getContext("webgl2", { antialias: aa });
  const sh = (t, s) => { const x = gl.createShader(t); gl.shaderSource(x, s); gl.compileShader(x); return x; };
  const pr = gl.createProgram();
  gl.attachShader(pr, sh(gl.VERTEX_SHADER, `#version 300 es
    in vec3 p; out vec3 q; void main() { q = p; gl_Position = vec4(p, 1.0); }`));
  gl.attachShader(pr, sh(gl.FRAGMENT_SHADER, `#version 300 es
    precision highp float; in vec3 q; out vec4 o;
    void main() { vec3 n = normalize(cross(dFdx(q), dFdy(q)));
                  o = vec4(vec3(0.2 + 0.8 * abs(n.z)), 1.0); }`));
  gl.linkProgram(pr); gl.useProgram(pr); gl.enable(gl.DEPTH_TEST);
  const out = {}, px = new Uint8Array(4);
  for (const m of counts) {
    const side = Math.ceil(Math.sqrt(m / 2)) + 1, P = new Float32Array(3 * side * side), I = [];
    for (let i = 0; i < side; i++) for (let j = 0; j < side; j++) {
      const x = -0.9 + 1.8 * i / (side - 1), y = -0.9 + 1.8 * j / (side - 1);
      P.set([x, y, 0.2 * Math.sin(9 * x) * Math.cos(7 * y)], 3 * (i * side + j));
    }
    for (let i = 0; i + 1 < side; i++) for (let j = 0; j + 1 < side; j++) {
      const a = i * side + j, b = a + side;
      I.push(a, b, a + 1, b, b + 1, a + 1);
    }
    const idx = new Uint32Array(I.slice(0, 3 * m));
    const vb = gl.createBuffer(); gl.bindBuffer(gl.ARRAY_BUFFER, vb); gl.bufferData(gl.ARRAY_BUFFER, P, gl.STATIC_DRAW);
    const l = gl.getAttribLocation(pr, "p"); gl.enableVertexAttribArray(l); gl.vertexAttribPointer(l, 3, gl.FLOAT, false, 0, 0);
    const ib = gl.createBuffer(); gl.bindBuffer(gl.ELEMENT_ARRAY_BUFFER, ib); gl.bufferData(gl.ELEMENT_ARRAY_BUFFER, idx, gl.STATIC_DRAW);
    const ts = [];
    for (let r = 0; r < reps; r++) {
      const t = performance.now();
      gl.clear(gl.COLOR_BUFFER_BIT | gl.DEPTH_BUFFER_BIT);
      gl.drawElements(gl.TRIANGLES, idx.length, gl.UNSIGNED_INT, 0);
      gl.readPixels(0, 0, 1, 1, gl.RGBA, gl.UNSIGNED_BYTE, px);  // waits for the drawing
      ts.push(performance.now() - t);
    }
    ts.sort((a, b) => a - b);
    out[m] = ts[Math.floor(ts.length / 2)];
  }
  return { ms: out, renderer: gl.getParameter(gl.RENDERER) };
}
"""


def floor(page: Any, triangles: int, size: list[int], reps: int = 20) -> dict[str, Any]:
    """Plain WebGL's drawing of ``triangles`` (and of 1000) in a view of ``size``.

    In a new page of the same browser: medians (ms), with and without antialiasing.
    """
    blank = page.context.browser.new_page()
    try:
        got = {
            aa: blank.evaluate(_FLOOR, [size[0], size[1], [1000, triangles], aa, reps])
            for aa in (True, False)
        }
    finally:
        blank.close()
    return {"triangles": triangles, "size": size,
            **{f"aa_{aa}": {int(k): v for k, v in g["ms"].items()} for aa, g in got.items()}}  # fmt: skip


def redraw(page: object, n: int = 20) -> dict:
    """The scene drawn again, nothing changed: medians (ms), in full and lighter.

    With and without the bones, and drawn lighter as while a slider moves (NaN where
    the page has no lighter one).
    """
    got = page.evaluate(_REDRAW, n)  # type: ignore[attr-defined]
    return {
        "all_ms": statistics.median(got["all"]),
        "nobones_ms": statistics.median(got["nobones"]),
        "lighter_ms": statistics.median(got["lighter"]) if got["lighter"] else float("nan"),
        "triangles": got["triangles"],
        "bone_triangles": got["bone_triangles"],
        "light_triangles": got["light_triangles"],
        "size": got["size"],
    }


def redraw_antialiased(page: Any) -> dict:
    """`redraw` in a second page of the same server, antialiased (``?antialias=1``)."""
    other = page.context.browser.new_page(viewport=page.viewport_size)
    try:
        other.goto(page.url.split("?")[0] + "?antialias=1")
        other.wait_for_function("window.mw && window.mw.last", timeout=120_000, polling=10)
        other.wait_for_timeout(1500)  # the camera set
        return redraw(other)
    finally:
        other.close()


def drag(page: object, coordinate: str, sweep: tuple[float, float, float], seconds: float) -> dict:
    """Input events at 60 a second through the sweep and back; the pictures drawn meanwhile."""
    lo, hi, _ = sweep
    got = page.evaluate(_DRAG, [coordinate, lo, hi, seconds])  # type: ignore[attr-defined]
    return {
        "updates_per_s": got["pictures"] / got["seconds"],
        "update_ms": statistics.median(got["totals"]),
        "solve_ms": statistics.median(got["solves"]),
        "pictures": got["pictures"],
        "seconds": got["seconds"],
    }


@contextlib.contextmanager
def open_page(
    scene: Path, size: tuple[int, int] = (1200, 800), query: str = ""
) -> Iterator[tuple[Any, float]]:
    """``musclewrap view SCENE`` on a free port, its page in Chromium at its first picture.

    Yields the page and the seconds from the command's start to that picture. ``query``:
    the address's, e.g. ``?antialias=1``.
    """
    from playwright.sync_api import sync_playwright

    from musclewrap.view._app import free_port

    port = free_port()
    t0 = time.monotonic()
    proc = subprocess.Popen(
        [sys.executable, "-m", "musclewrap.cli", "view", str(scene), "--port", str(port), "--no-browser"],
        stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
    )  # fmt: skip
    try:
        with sync_playwright() as pw:
            exe = shutil.which("chromium") or shutil.which("chromium-browser")
            browser = pw.chromium.launch(executable_path=exe, headless=True)
            page = browser.new_page(viewport={"width": size[0], "height": size[1]})
            while True:
                try:
                    page.goto(f"http://127.0.0.1:{port}/{query}", timeout=5000)
                    break
                except Exception:  # noqa: BLE001  # not serving yet
                    if proc.poll() is not None:
                        raise SystemExit(f"the viewer exited ({proc.returncode})") from None
                    time.sleep(0.05)
            page.wait_for_function("window.mw && window.mw.last", timeout=120_000, polling=10)
            yield page, time.monotonic() - t0
            browser.close()
    finally:
        proc.terminate()
        proc.wait(timeout=30)


def set_slider(page: Any, coordinate: str, value: float) -> dict[str, Any]:
    """A slider moved (found by its label); the page's measure of that update."""
    before = page.evaluate("window.mw.last.serial")
    page.get_by_label(coordinate).fill(f"{value:g}")
    page.wait_for_function(f"window.mw.last.serial != {before}", timeout=60_000, polling="raf")
    return page.evaluate("window.mw.last")  # type: ignore[no-any-return]


def measure(
    scene: Path,
    coordinate: str,
    sweep: tuple[float, float, float],
    drag_seconds: float = 6.0,
    colour: str = "stretch",
) -> dict[str, object]:
    out: dict[str, object] = {}
    with open_page(scene) as (page, first):
        out["first_picture_s"] = first
        page.wait_for_timeout(1500)  # the camera set
        if colour != "stretch":
            page.select_option("#colour", colour)
            page.wait_for_timeout(1000)
        out["redraw"] = redraw(page)
        out["redraw_aa"] = redraw_antialiased(page)
        out["floor"] = floor(page, out["redraw"]["triangles"], out["redraw"]["size"])
        # the same in a smaller view: does the drawing go with the pixels or the triangles?
        page.set_viewport_size({"width": 700, "height": 450})
        page.wait_for_timeout(1000)
        out["redraw_small"] = redraw(page)
        page.set_viewport_size({"width": 1200, "height": 800})
        page.wait_for_timeout(1000)
        lo, hi, step = sweep
        values = [lo + i * step for i in range(int(round((hi - lo) / step)) + 1)]
        for run in ("first", "warm"):
            t = time.perf_counter()
            rows = [set_slider(page, coordinate, v) for v in values]
            dt = time.perf_counter() - t
            out[run] = {
                "updates_per_s": len(values) / dt,
                "update_ms": statistics.median(r["total"] for r in rows),
                "solve_ms": statistics.median(r["solve"] for r in rows),
                "transfer_ms": statistics.median(r["transfer"] for r in rows),
                "render_ms": statistics.median(r["render"] for r in rows),
                "max_ms": max(r["total"] for r in rows),
            }
        out["drag"] = drag(page, coordinate, sweep, drag_seconds)
    return out


def screenshot(
    scene: Path, png: Path, values: list[str], size: tuple[int, int], colour: str = "stretch"
) -> None:
    """The page at the poses ``values`` (``COORDINATE=VALUE``, in turn), written to ``png``.

    Antialiased, as a browser with a graphics processor draws it (this one draws in software).
    """
    with open_page(scene, size, "?antialias=1") as (page, _):
        if colour != "stretch":
            page.select_option("#colour", colour)
        for item in values:
            name, _, value = item.partition("=")
            set_slider(page, name, float(value))
        page.wait_for_timeout(1500)  # the camera set, the picture drawn
        page.screenshot(path=str(png))
    print(f"wrote {png}")


@contextlib.contextmanager
def measures_anew() -> Iterator[None]:
    """The check's cached measures (`musclewrap._cache.cached_measure`) taken anew meanwhile."""
    from musclewrap import _cache
    from musclewrap.model import _fit
    from musclewrap.run import _verify

    kept = _cache.cached_measure

    def anew(cache_dir: Any, kind: str, parts: Any, build: Any) -> Any:
        return kept(None, kind, parts, build)

    _fit.cached_measure = _verify.cached_measure = anew  # type: ignore[assignment]
    try:
        yield
    finally:
        _fit.cached_measure = _verify.cached_measure = kept  # type: ignore[assignment]


def phases(scene: Path) -> None:
    import numpy as np

    from musclewrap.scene import LiveScene, check_scene, load_scene

    sc = load_scene(scene)
    t = time.perf_counter()
    check_scene(sc)
    print(f"check {time.perf_counter() - t:.2f} s (the first in this process, as a start's)")
    t = time.perf_counter()
    check_scene(sc)
    print(f"  again: {time.perf_counter() - t:.2f} s (its measures read back from the cache)")
    with measures_anew():
        t = time.perf_counter()
        check_scene(sc)
    print(f"  again, its measures taken anew: {time.perf_counter() - t:.2f} s")
    t = time.perf_counter()
    live = LiveScene(sc, check=False)
    print(
        f"reading, preparations and probes (LiveScene without check) {time.perf_counter() - t:.2f} s"
    )
    t = time.perf_counter()
    r = live.solve(frame=0)
    parts = ", ".join(f"{k} {1e3 * v:.0f} ms" for k, v in r.seconds.items())
    print(f"first pose {time.perf_counter() - t:.2f} s ({parts})")
    frames = range(0, live.n_frames, 10)
    for k in frames:  # the waypoints solved
        live.solve(frame=k)
    got = []
    for k in frames:
        res = live.solve(frame=k)
        t = time.perf_counter()
        live.contact(res)  # the contact colours' distances (to bones and muscles kept apart)
        got.append({**res.seconds, "contact colours": time.perf_counter() - t})
    print(
        f"a pose, warm, median of {len(got)}: "
        + ", ".join(f"{k} {1e3 * np.median([g[k] for g in got]):.1f} ms" for k in got[0])
    )
    contact_cells(live, frames)
    for name, m in live._prepare().items():
        alone = []
        for k in frames:
            live.solve(frame=k)
            t = time.perf_counter()
            m.solve_frame(0)
            alone.append(time.perf_counter() - t)
        print(
            f"  {name} ({len(m.muscle.V)} vertices) alone against its bones: {1e3 * np.median(alone):.1f} ms"
        )


def contact_cells(live: Any, frames: range) -> None:
    """The contact colours' distances to the muscles by the grid's cell width.

    `muscle_gaps` with cells 1, 1/2 and 1/3 of the reach wide, medians over ``frames``
    (the same distances, only the time differs).
    """
    import numpy as np

    from musclewrap.constants import defaults
    from musclewrap.contact import muscle_gaps

    poses = [live.solve(frame=k) for k in frames]
    for part in (1.0, 0.5, 1 / 3):
        ts = []
        for r in poses:
            surfaces = {n: (V, r.solved[0][n].muscle.F) for n, V in r.muscles.items()}
            t = time.perf_counter()
            muscle_gaps(
                surfaces, r.pairs, defaults.view_contact_reach, part * defaults.view_contact_reach
            )
            ts.append(time.perf_counter() - t)
        print(f"  contact colours, to the muscles alone, cells {part:.2f} of the reach: "
              f"{1e3 * np.median(ts):.1f} ms")  # fmt: skip


def compare(scene: Path, checkouts: list[Path], coordinate: str, sweep: tuple, seconds: float,
            rounds: int = 2) -> None:  # fmt: skip
    """The first picture and a hand's drag of each checkout's viewer, in turns, ``rounds`` times.

    Each checkout's ``src`` is put first on the viewer's ``PYTHONPATH``; the poses of
    ``sweep`` are solved step by step first (the waypoints), then the drag. One sitting:
    the host's speed drifts between sittings by 2-3 times.
    """
    import os

    lo, hi, step = sweep
    values = [lo + i * step for i in range(int(round((hi - lo) / step)) + 1)]
    print(
        f"{scene}: first picture, then a {seconds:g} s drag of {coordinate} {lo:g}-{hi:g} and back"
    )
    for _ in range(rounds):
        for c in checkouts:
            os.environ["PYTHONPATH"] = str(c.resolve() / "src")
            with open_page(scene) as (page, first):
                page.wait_for_timeout(1500)
                for v in values:
                    set_slider(page, coordinate, v)
                d = drag(page, coordinate, sweep, seconds)
            print(
                f"  {str(c):<24} first picture {first:5.2f} s  drag {d['updates_per_s']:5.2f} "
                f"pictures/s, update {d['update_ms']:4.0f} ms, solve {d['solve_ms']:4.0f} ms "
                f"({d['pictures']} pictures in {d['seconds']:.1f} s)", flush=True,
            )  # fmt: skip


def profile_page(
    scene: Path, coordinate: str, sweep: tuple, checkouts: list[Path] | None = None
) -> None:
    """The page's own work per update: Chrome's sampling profiler over the sweep, step by step.

    After one pass to solve the waypoints, the sweep again under the profiler (through
    Playwright's CDP session); per update, the functions that took the most time themselves,
    and the time spent within vtk.js's colour mapping (``mapScalars`` and what it calls).
    ``checkouts``: each one's viewer in turn (its ``src`` first on ``PYTHONPATH``).
    """
    import collections
    import os

    lo, hi, step = sweep
    values = [lo + i * step for i in range(int(round((hi - lo) / step)) + 1)]
    for c in checkouts or [None]:
        if c is not None:
            os.environ["PYTHONPATH"] = str(c.resolve() / "src")
        with open_page(scene) as (page, _):
            page.wait_for_timeout(1500)
            for v in values:
                set_slider(page, coordinate, v)
            cdp = page.context.new_cdp_session(page)
            cdp.send("Profiler.enable")
            cdp.send("Profiler.setSamplingInterval", {"interval": 200})
            cdp.send("Profiler.start")
            for v in values:
                set_slider(page, coordinate, v)
            prof = cdp.send("Profiler.stop")["profile"]
        nodes = {n["id"]: n for n in prof["nodes"]}
        parent = {k: n["id"] for n in prof["nodes"] for k in n.get("children", [])}
        own: collections.Counter[str] = collections.Counter()
        within = 0.0
        for sample, dt in zip(prof["samples"], prof["timeDeltas"], strict=True):
            f = nodes[sample]["callFrame"]
            own[f["functionName"] or "(anonymous)"] += dt
            k, names = sample, set()
            while k is not None:
                names.add(nodes[k]["callFrame"]["functionName"])
                k = parent.get(k)
            if any(n.endswith("mapScalars") for n in names):
                within += dt
        n = len(values)
        print(f"{c or 'this checkout'}: the page's work per update, {n} updates")
        print(f"  within vtk.js's colour mapping (mapScalars): {within / 1e3 / n:.1f} ms")
        for name, dt in own.most_common(12):
            print(f"  {dt / 1e3 / n:7.1f} ms  {name}")


def host_reference() -> str:
    """The host's speed now, in two measures: BLAS's and single-threaded Python's.

    The median ms of one float64 ``W @ X`` (15 074 x 300 times 300 x 3, numpy: the product
    BENCHMARKS.md measures every pose against, 4-11.5 ms across runs) and the seconds of a
    plain Python loop of 10 million additions (most of a pose's time is Python's and
    single-threaded kernels': a host can be slow there and not in BLAS).
    """
    import numpy as np

    rng = np.random.default_rng(0)
    W, X = rng.random((15074, 300)), rng.random((300, 3))
    ts = []
    for _ in range(40):
        t = time.perf_counter()
        W @ X
        ts.append(time.perf_counter() - t)
    t, s = time.perf_counter(), 0
    for i in range(10_000_000):
        s += i
    loop = time.perf_counter() - t
    return (
        f"W @ X (15074 x 300, 3 columns) {1e3 * statistics.median(ts[5:]):.2f} ms, "
        f"a Python loop of 10 million additions {loop:.2f} s"
    )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("scene", type=Path)
    ap.add_argument("--coordinate", default="hip_flexion_r")
    ap.add_argument(
        "--sweep", type=float, nargs=3, default=(0.0, 60.0, 1.0), metavar=("FROM", "TO", "STEP")
    )
    ap.add_argument("--variants", nargs="+", default=["all"], choices=("all", "bones"))
    ap.add_argument("--drag-seconds", type=float, default=6.0, help="the drag's length")
    ap.add_argument("--colour", default="stretch", choices=("stretch", "contact"),
                    help="the muscles' colouring through the measures")  # fmt: skip
    ap.add_argument("--phases", action="store_true", help="where the time goes (no browser)")
    ap.add_argument("--profile-page", action="store_true",
                    help="the page's own work per update (with --compare: each checkout's)")  # fmt: skip
    ap.add_argument("--compare", type=Path, nargs="+", metavar="CHECKOUT",
                    help="the first picture and the drag alone, of these checkouts in turns")  # fmt: skip
    ap.add_argument("--screenshot", type=Path, metavar="PNG", help="the page's picture instead")
    ap.add_argument("--set", action="append", default=[], metavar="COORDINATE=VALUE",
                    help="with --screenshot: the sliders moved first")  # fmt: skip
    ap.add_argument("--size", type=int, nargs=2, default=(1100, 640), metavar=("W", "H"),
                    help="with --screenshot: the page's size")  # fmt: skip
    a = ap.parse_args()
    print(f"host reference: {host_reference()}")
    if a.phases:
        phases(a.scene)
        print(f"host reference again: {host_reference()}")
        return
    if a.profile_page:
        with tempfile.TemporaryDirectory() as tmp:
            for v in a.variants:
                sc = scene_variant(a.scene.resolve(), v, Path(tmp))
                profile_page(sc, a.coordinate, tuple(a.sweep), a.compare)
        return
    if a.compare:
        with tempfile.TemporaryDirectory() as tmp:
            for v in a.variants:
                sc = scene_variant(a.scene.resolve(), v, Path(tmp))
                compare(sc, a.compare, a.coordinate, tuple(a.sweep), a.drag_seconds)
        print(f"host reference again: {host_reference()}")
        return
    if a.screenshot:
        screenshot(a.scene, a.screenshot, a.set, tuple(a.size), a.colour)
        return
    # the muscles prepared and cached first (a run of one frame)
    subprocess.run(
        [sys.executable, "-m", "musclewrap.cli", "run", str(a.scene), "--frames", "0:1", "--no-gif",
         "-o", tempfile.mkdtemp()], check=True, capture_output=True,
    )  # fmt: skip
    print(f"{a.scene}: {a.coordinate} {a.sweep[0]:g} to {a.sweep[1]:g} by {a.sweep[2]:g}")
    print("contact     first picture  sweep  updates/s  update ms  solve  transfer  render  max ms")
    with tempfile.TemporaryDirectory() as tmp:
        for v in a.variants:
            r = measure(
                scene_variant(a.scene.resolve(), v, Path(tmp)), a.coordinate, tuple(a.sweep),
                a.drag_seconds, a.colour,
            )  # fmt: skip
            for run in ("first", "warm"):
                x = r[run]
                print(
                    f"{'bones+muscles' if v == 'all' else 'bones':<12}{r['first_picture_s']:>10.2f} s  "
                    f"{run:<6}{x['updates_per_s']:>9.1f}{x['update_ms']:>11.0f}{x['solve_ms']:>7.0f}"
                    f"{x['transfer_ms']:>10.0f}{x['render_ms']:>8.0f}{x['max_ms']:>8.0f}"
                )
            d = r["drag"]
            print(
                f"{'':<12}{'':>12}  drag  {d['updates_per_s']:>9.1f}{d['update_ms']:>11.0f}"
                f"{d['solve_ms']:>7.0f}   ({d['pictures']} pictures in {d['seconds']:.1f} s)"
            )
            w = r["redraw"]
            print(
                f"{'':<12}redraw alone, nothing changed: {w['all_ms']:.0f} ms ({w['triangles']} "
                f"triangles, {w['size'][0]}x{w['size'][1]} pixels); without the bones "
                f"({w['bone_triangles']} triangles) {w['nobones_ms']:.0f} ms; lighter, as while "
                f"a slider moves ({w['light_triangles']} triangles) {w['lighter_ms']:.0f} ms"
            )
            w = r["redraw_aa"]
            print(
                f"{'':<12}the same antialiased (?antialias=1): {w['all_ms']:.0f} ms; without "
                f"the bones {w['nobones_ms']:.0f} ms"
            )
            f = r["floor"]
            print(
                f"{'':<12}plain WebGL, {f['triangles']} triangles in {f['size'][0]}x{f['size'][1]}: "
                f"{f['aa_True'][f['triangles']]:.0f} ms antialiased, "
                f"{f['aa_False'][f['triangles']]:.0f} ms not (1000 triangles: "
                f"{f['aa_True'][1000]:.0f} and {f['aa_False'][1000]:.0f} ms)"
            )
            w = r["redraw_small"]
            print(
                f"{'':<12}the same in a {w['size'][0]}x{w['size'][1]} view: {w['all_ms']:.0f} ms; "
                f"without the bones {w['nobones_ms']:.0f} ms"
            )
    print(f"host reference again: {host_reference()}")


if __name__ == "__main__":
    main()
