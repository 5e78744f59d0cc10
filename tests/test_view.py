"""The live viewer: a pose solved live equals the run's files; the page in a real browser.

The browser tests start ``musclewrap view`` on a free loopback port and drive the OS's
Chromium through Playwright's Python API (nothing downloaded).
"""

from __future__ import annotations

import json
import re
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from musclewrap.mesh import read_mesh
from musclewrap.scene import LiveScene, load_scene, run_scene, write_motion

EXAMPLES = Path(__file__).resolve().parent.parent / "examples"
pytestmark = pytest.mark.realdata


def _scene(data_dir: Path, tmp: Path, name: str = "lhdl_walk", edit=None) -> Path:
    src = (EXAMPLES / f"{name}.toml").read_text().replace("../../shared/data", data_dir.as_posix())
    if edit is not None:
        src = edit(src)
    p = tmp / f"{name}.toml"
    p.write_text(src)
    return p


def _run_pose(scene_path: Path, values: dict[str, float], out: Path) -> Path:
    """``musclewrap run`` of the scene on a one-row motion holding ``values``."""
    mot = out.parent / f"{out.name}.mot"
    write_motion(mot, np.array([0.0]), {c: np.array([v]) for c, v in values.items()})
    scene = load_scene(scene_path)
    import dataclasses

    scene = dataclasses.replace(scene, motions=(mot,))
    run_scene(scene, out, workers=1, render=False, progress=None)
    return out


def _same_files(a: Path, b: Path, names: list[str]) -> None:
    from musclewrap.view._playback import read_polydata

    for n in names:
        da, db = read_polydata(a / n), read_polydata(b / n)
        Va, Vb = da["points"], db["points"]
        size = float(np.ptp(Vb, axis=0).max())
        assert Va.shape == Vb.shape, n
        assert np.abs(Va - Vb).max() <= 1e-9 * size, (n, np.abs(Va - Vb).max())
        for k in ("polys", "lines", "point:area_stretch"):
            assert (k in da) == (k in db), (n, k)
            if k in da and k != "point:area_stretch":
                assert np.array_equal(da[k], db[k]), (n, k)


def test_a_pose_solved_live_equals_the_run_of_that_pose(data_dir, tmp_path):
    """Contact on (bones and muscles): a slider pose, a frame of the motion, and the same
    pose again after others (the waypoints kept) all give the run's files to 1e-9."""
    scene = _scene(data_dir, tmp_path)
    live = LiveScene(scene)
    assert [c.name for c in live.coordinates] == [
        "hip_flexion_r", "hip_adduction_r", "hip_rotation_r"
    ]  # fmt: skip
    flex = next(c for c in live.coordinates if c.name == "hip_flexion_r")
    assert (flex.low, flex.high, flex.unit) == (pytest.approx(-10), pytest.approx(90), "deg")
    values = {"hip_flexion_r": 57.25, "hip_adduction_r": -8.5, "hip_rotation_r": 6.0}
    r1 = live.solve(values)
    assert abs(r1.volume_error) < 1e-12 and not r1.unconverged
    live.write(r1, tmp_path / "live")
    names = [f"{m}/{m}_0000.vtp" for m in live.specs] + [
        f"{m}/{m}_lines_0000.vtp" for m in live.specs
    ]
    run = _run_pose(scene, values, tmp_path / "run")
    _same_files(tmp_path / "live", run, names + ["femur/femur.vtp"])
    pose = json.loads((tmp_path / "live" / "pose.json").read_text())
    assert pose["values"] == values
    _contact_colours_measure_bones_and_muscles(live, r1)
    # other poses, then this one again: the same
    live.solve(frame=40)
    r2 = live.solve(values)
    for n in live.specs:
        assert np.array_equal(r1.muscles[n], r2.muscles[n])
    # a frame of the motion: the run of that frame
    r3 = live.solve(frame=150)
    live.write(r3, tmp_path / "live150")
    run150 = tmp_path / "run150"
    run_scene(load_scene(scene), run150, frames="150:151", workers=1, render=False, progress=None)
    _same_files(tmp_path / "live150", run150, [f"{m}/{m}_0150.vtp" for m in live.specs])
    # a pose written after others were solved: still its own files (not the last pose's)
    live.write(r1, tmp_path / "live_later")
    _same_files(tmp_path / "live_later", run, names + ["femur/femur.vtp"])


def _contact_colours_measure_bones_and_muscles(live, r) -> None:
    """The contact colours' distances: the exact signed distance to the nearest bone or
    muscle kept apart (libigl over every face of each, the side by winding numbers)."""
    import igl

    from musclewrap.mesh import winding_numbers

    reach = 5.0
    got = live.contact(r)
    assert r.pairs and got is live.contact(r)  # computed once
    ms = r.solved[0]
    from musclewrap.mesh import apply_transform

    bones = {
        b: (apply_transform(r.bones[b], bone.V), bone.F) for b, bone in live.inputs.bones.items()
    }
    by_muscles = by_bones = 0
    for me, P in r.muscles.items():

        def signed(others, P=P):
            out = np.full(len(P), reach)
            for V, F in others:
                F = np.asarray(F, dtype=np.int64)
                d = np.sqrt(igl.point_mesh_squared_distance(P, V, F)[0])
                out = np.minimum(out, np.where(winding_numbers(P, V, F) != 0, -d, d))
            return np.clip(out, -reach, reach)

        to_muscles = signed([(V, ms[o].muscle.F) for o, V in r.muscles.items() if o != me])
        to_bones = signed(bones.values())
        np.testing.assert_allclose(got[me], np.minimum(to_muscles, to_bones), rtol=0, atol=1e-9)
        by_muscles += int((to_muscles < to_bones - 0.5).sum())
        by_bones += int((to_bones < to_muscles - 0.5).sum())
    # the muscles press on each other here, and on the bones: hundreds of vertices each
    assert by_muscles > 100 and by_bones > 100


def test_the_sides_kept_or_dropped_give_the_same_pose(data_dir, tmp_path):
    """A hard case of its own: the deep squat's hip flexion, where the sides of the bones
    matter (the femur past the ischium). A pose solved after others, again (its sides
    kept), and after more waypoints than are kept (its sides dropped): each the same, bit
    for bit, as the pose solved first in a new scene."""
    from musclewrap.run._live import _SIDES_KEPT

    scene = _scene(data_dir, tmp_path, "lhdl_squat")
    pose = {"hip_flexion_r": 105.0, "hip_adduction_r": -6.0}
    fresh = LiveScene(scene, check=False).solve(pose)
    assert not fresh.unconverged
    live = LiveScene(scene, check=False)
    sweep = [{"hip_flexion_r": float(v)} for v in range(0, 121, 6)]
    for q in sweep:
        live.solve(q)
    after = live.solve(pose)
    again = live.solve(pose)  # its sides kept
    for q in sweep[::-1]:
        live.solve(q)
    assert len(live._refs) == _SIDES_KEPT  # the pose's sides were dropped
    dropped = live.solve(pose)
    for n in fresh.muscles:
        for got in (after, again, dropped):
            assert np.array_equal(fresh.muscles[n], got.muscles[n]), n


def test_bad_poses_are_refused_by_name(data_dir, tmp_path):
    live = LiveScene(_scene(data_dir, tmp_path), check=False)
    with pytest.raises(ValueError, match="hip_flexion"):
        live.solve({"knee_angle_r": 10.0})
    with pytest.raises(ValueError, match="frame 211 is not a frame"):
        live.solve(frame=211)


def test_an_unconverged_pose_is_reported(data_dir, tmp_path):
    """One iteration allowed: the pose is shown with the solver's reason, never silently."""
    scene = _scene(data_dir, tmp_path, edit=lambda s: s.replace(
        'paths = ["psoas_r"]', 'paths = ["psoas_r"]\nmax_iterations = 1'
    ))  # fmt: skip
    live = LiveScene(scene, check=False)
    r = live.solve({"hip_flexion_r": 80.0})
    assert "psoas" in r.unconverged and r.unconverged["psoas"]


def test_view_refuses_a_scene_check_refuses_with_runs_message(data_dir, tmp_path):
    """Before any server starts: the same message as ``musclewrap run``, exit 2."""
    scene = _scene(
        data_dir,
        tmp_path,
        "gait2392_walk",
        edit=lambda s: s.replace('paths = ["semiten_r"]', 'paths = ["vas_lat_r"]'),
    )
    cmd = [sys.executable, "-m", "musclewrap.cli"]
    run = subprocess.run(
        [*cmd, "run", str(scene), "-o", str(tmp_path / "o")],
        capture_output=True,
        text=True,
        timeout=600,
    )
    view = subprocess.run(
        [*cmd, "view", str(scene), "--no-browser"], capture_output=True, text=True, timeout=600
    )
    assert run.returncode == view.returncode == 2
    said = [x for x in run.stderr.splitlines() if x.startswith(("error:", "  "))]
    assert said and said[0].startswith("error: ") and "would make the run wrong" in said[0]
    assert said == [x for x in view.stderr.splitlines() if x.startswith(("error:", "  "))]
    assert "http://" not in view.stdout


def _serve(args: list[str], tmp_path: Path) -> tuple[subprocess.Popen[str], int]:
    from musclewrap.view._app import free_port

    port = free_port()
    with open(tmp_path / "server.log", "w") as log:  # the child keeps its own handle
        proc = subprocess.Popen(
            [sys.executable, "-m", "musclewrap.cli", "view", *args, "--port", str(port), "--no-browser"],
            stdout=log, stderr=subprocess.STDOUT, text=True, cwd=tmp_path,
        )  # fmt: skip
    return proc, port


def _page(pw, port: int, proc, tmp_path: Path, chromium: str):
    browser = pw.chromium.launch(executable_path=chromium, headless=True)
    page = browser.new_page(viewport={"width": 1200, "height": 800})
    # the page's script errors (vtk.js's included); a missing favicon's 405 is not one
    errors: list[str] = []
    page.on("pageerror", lambda e: errors.append(str(e)))
    page.on(
        "console",
        lambda m: (
            m.type == "error"
            and not m.text.startswith("Failed to load resource")
            and errors.append(m.text)
        ),
    )
    page.script_errors = errors
    t = time.monotonic()
    while True:
        if proc.poll() is not None:
            pytest.fail("the viewer exited: " + (tmp_path / "server.log").read_text())
        try:
            page.goto(f"http://127.0.0.1:{port}/", timeout=5000)
            break
        except Exception:  # noqa: BLE001  # not serving yet
            if time.monotonic() - t > 120:
                raise
            time.sleep(0.3)
    page.wait_for_function(
        "document.getElementById('mw-update') && document.getElementById('mw-update').dataset.serial",
        timeout=120_000,
    )
    return browser, page


# a state array's bytes (binary from the server: a Uint8Array on the page) as one number
_FINGERPRINT = """(part) => {
  const v = window.trame.state.get(part);
  let h = 2166136261;
  for (let i = 0; i < v.length; i++) h = Math.imul(h ^ v[i], 16777619) >>> 0;
  return `${h}:${v.length}`;
}"""


def _geometry(page, part: str = "muscle0_p") -> str:
    return page.evaluate(_FINGERPRINT, part)


def _serial(page) -> str:
    return page.eval_on_selector("#mw-update", "e => e.dataset.serial")


def _moved(page, before: str) -> None:
    """A picture after ``before``, in full (not the lighter one drawn while a slider moves)."""
    page.wait_for_function(
        f"document.getElementById('mw-update').dataset.serial != '{before}' "
        "&& !window.trame.state.get('light')",
        timeout=60_000,
    )


_HELD = """
async ([label, start, end, n]) => {
  const el = document.querySelector(`input[aria-label="${label}"]`), mw = window.mw;
  const pulled = [];
  for (let i = 1; i <= n; i++) {
    const v = String(start + (end - start) * i / n);
    el.value = v;
    el.dispatchEvent(new Event("input", { bubbles: true }));
    await new Promise((r) => setTimeout(r, 30));
    if (el.value !== v) pulled.push([v, el.value]);
  }
  const last = mw.n;
  while (!(mw.last && mw.last.id >= last)) await new Promise((r) => setTimeout(r, 5));
  return { pulled, drawn: mw.last.id };
}
"""


# the view's WebGL context (vtk.js's, behind trame's VtkView) made antialiased or not
_ANTIALIAS = (
    "window.trame.refs.view._.provides.view.openglRenderWindow.getContext()"
    ".getContextAttributes().antialias"
)


def _decoded(page, part: str) -> np.ndarray:
    """A part's positions as the page views them for vtk.js (float32)."""
    a = page.evaluate(
        "(part) => Array.from(window.mw.typed(window.trame.state.get(part), 'f32'))", part
    )
    return np.asarray(a, dtype=np.float64).reshape(-1, 3)


def _drawn_where(page, view, part: str, below: list[str]) -> float:
    """The share of part's points, where the run's camera puts them below every point of
    ``below``, that the page's picture has drawn (not background)."""
    import io

    from PIL import Image

    box = page.locator(".mw-view")
    img = np.asarray(Image.open(io.BytesIO(box.screenshot())).convert("L"))
    h, w = img.shape
    lowest = max(view.project(_decoded(page, b), (w, h))[:, 1].max() for b in below)
    xy = view.project(_decoded(page, part), (w, h))
    keep = (xy[:, 1] > lowest + 5) & (xy[:, 0] >= 0) & (xy[:, 0] < w) & (xy[:, 1] < h)
    assert keep.sum() > 20, keep.sum()
    px = img[xy[keep, 1].astype(int), xy[keep, 0].astype(int)]
    return float(np.mean(px < 250))


def test_dragging_hip_flexion_in_a_browser(data_dir, tmp_path, chromium):
    """The hip_flexion_r slider found by its label; moved, the muscles change, the status
    line says the update time, and the written pose equals run's files of that pose."""
    from playwright.sync_api import sync_playwright

    scene = _scene(data_dir, tmp_path)
    proc, port = _serve([str(scene), "-o", "poses"], tmp_path)
    try:
        with sync_playwright() as pw:
            browser, page = _page(pw, port, proc, tmp_path, chromium)
            # the first picture, from the run's pictures' camera (the limb's side, its long
            # axis up): the femur's shaft, below the muscles, drawn (seen from above, as
            # vtk.js's own camera looks along z, it hid under the pelvis)
            page.wait_for_timeout(1500)  # the camera is set 0.3 and 1 s after the geometry
            view = LiveScene(scene, check=False, prepare=False).view(size=(1, 1))
            muscles = [f"muscle{i}_p" for i in range(4)]
            assert _drawn_where(page, view, "bone0_p", muscles) > 0.9
            slider = page.get_by_label("hip_flexion_r")
            assert slider.count() == 1
            assert page.get_by_text("hip_flexion_r", exact=True).is_visible()
            before, serial = _geometry(page), _serial(page)
            slider.fill("45")
            _moved(page, serial)
            assert _geometry(page) != before
            status = page.inner_text("#status")
            assert re.search(
                r"update \d+ ms \(median \d+ ms of the last \d+; queued \d+, solve \d+, "
                r"transfer \d+, render \d+ ms\)",
                status,
            ), status
            assert re.search(r"volume error \S+ .* deepest in a bone [\d.]+ mm", status), status
            assert page.eval_on_selector("#q0", "e => e.value") == "45"
            page.get_by_role("button", name="Write this pose").click()
            page.wait_for_function(
                "document.getElementById('written').textContent.includes('wrote')", timeout=60_000
            )
            # the stretch/contact toggle recolours the muscles
            colours = _geometry(page, "muscle0_c")
            page.select_option("#colour", "contact")
            page.wait_for_function(f"({_FINGERPRINT})('muscle0_c') != '{colours}'", timeout=30_000)
            # to the bones and the muscles this scene keeps apart, as the legend says
            assert "touching a bone or another muscle" in page.inner_text(".mw-side")
            # a quick drag (an input every 30 ms, poses solved behind it): the thumb stays
            # where the hand put it, not pulled back by the older poses drawn meanwhile
            held = page.evaluate(_HELD, ["hip_flexion_r", 45, 30, 30])
            assert held["pulled"] == [], held
            assert page.eval_on_selector("#q0", "e => e.value") == "30"
            # while it moves the surfaces are drawn lighter, as the status line says; let go,
            # in full, and the lighter surface's vertices are the full one's own
            assert page.evaluate("window.trame.state.get('light')") is True
            assert re.search(r"drawn with [\d,]+ of [\d,]+ triangles while a slider moves",
                             page.inner_text("#status"))  # fmt: skip
            serial = _serial(page)
            page.eval_on_selector(
                "#q0", "e => e.dispatchEvent(new Event('change', {bubbles: true}))"
            )
            _moved(page, serial)
            assert "while a slider moves" not in page.inner_text("#status")
            full, light = _decoded(page, "muscle0_p"), _decoded(page, "muscle0_lp")
            assert 0 < len(light) < len(full)
            assert {tuple(r) for r in light} <= {tuple(r) for r in full}
            # a frame of the motion: the coordinates' thumbs go to its pose
            serial = _serial(page)
            page.get_by_label("time").fill("150")
            _moved(page, serial)
            shown = float(page.evaluate("window.trame.state.get('q0_label')").split()[0])
            page.wait_for_function(  # to the slider's step
                f"Math.abs(parseFloat(document.getElementById('q0').value) - {shown}) "
                "<= 0.51 * parseFloat(document.getElementById('q0').step)",
                timeout=10_000,
            )
            assert shown != 30.0
            # the page loaded again: the pose there, its status, the run's camera
            page.reload()
            page.wait_for_function(
                "document.getElementById('mw-update') && "
                "document.getElementById('mw-update').dataset.serial",
                timeout=60_000,
            )
            page.wait_for_timeout(1500)
            assert _drawn_where(page, view, "bone0_p", muscles) > 0.9
            # antialiased unless the browser draws in software (this one: SwiftShader), where
            # it costs 2-3 times the drawing; the status line says so; ?antialias=1 forces it
            soft = page.evaluate("window.mw.software")
            assert page.evaluate(_ANTIALIAS) is (not soft)
            assert ("drawn in software, antialiasing off" in page.inner_text("#status")) is soft
            page.goto(f"http://127.0.0.1:{port}/?antialias=1")
            page.wait_for_function("window.mw && window.mw.last", timeout=60_000)
            assert page.evaluate(_ANTIALIAS) is True
            assert page.script_errors == []
            browser.close()
    finally:
        proc.terminate()
        proc.wait(timeout=30)
    written = tmp_path / "poses" / "pose_000"
    values = json.loads((written / "pose.json").read_text())["values"]
    assert values["hip_flexion_r"] == 45.0
    run = _run_pose(scene, values, tmp_path / "run")
    names = [f"{m}/{m}_0000.vtp" for m in ("gluteus_maximus", "gluteus_medius", "iliacus", "psoas")]
    _same_files(written, run, names)


def test_playing_back_a_finished_run_in_a_browser(tmp_path, chromium):
    """``musclewrap view OUTDIR``: the time slider (by its label) shows another frame of
    the run's own files; play steps on by itself; nothing is solved."""
    from playwright.sync_api import sync_playwright

    from musclewrap.synthetic import write_knee_scene

    toml = write_knee_scene(tmp_path / "input", 9)
    out = tmp_path / "out"
    run_scene(load_scene(toml), out, workers=1, render=False, progress=None)
    proc, port = _serve([str(out)], tmp_path)
    try:
        with sync_playwright() as pw:
            browser, page = _page(pw, port, proc, tmp_path, chromium)
            assert page.get_by_label("hip_flexion_r").count() == 0  # no sliders to solve
            assert page.get_by_role("button", name="Write this pose").count() == 0
            first, serial = _geometry(page), _serial(page)
            page.get_by_label("time").fill("8")
            _moved(page, serial)
            assert _geometry(page) != first
            assert "frame 8 of 8" in page.inner_text(".mw-side")
            assert "no solve" in page.inner_text("#status")
            assert re.search(r"update \d+ ms", page.inner_text("#status"))
            # the file of frame 8, as the page has it
            P = _decoded(page, "muscle0_p")
            m = page.evaluate("window.trame.state.get('part_names')")["muscle"][0]
            V, _ = read_mesh(out / m / f"{m}_0008.vtp")
            assert np.abs(P - V).max() <= 1e-6 * np.ptp(V, axis=0).max()
            serial = _serial(page)
            page.get_by_role("button", name="Play").click()
            _moved(page, serial)
            serial = _serial(page)
            _moved(page, serial)  # and on
            page.get_by_role("button", name="Pause").click()
            assert page.script_errors == []
            browser.close()
    finally:
        proc.terminate()
        proc.wait(timeout=30)


def test_the_viewer_in_a_notebook_cell(tmp_path):
    """`Viewer.show` serves on the running event loop (as in Jupyter) and gives the cell an
    iframe of the page; the page answers there."""
    import asyncio
    import urllib.request

    from musclewrap.synthetic import write_knee_scene
    from musclewrap.view import viewer

    toml = write_knee_scene(tmp_path / "input", 5)
    out = tmp_path / "out"
    run_scene(load_scene(toml), out, workers=1, render=False, progress=None)
    app = viewer(out)

    async def cell() -> tuple[str, str]:
        frame = app.show()
        await asyncio.sleep(1.0)
        loop = asyncio.get_running_loop()
        got = await loop.run_in_executor(
            None, lambda: urllib.request.urlopen(frame.url, timeout=10).read().decode()
        )
        await app.server.stop()
        return frame._repr_html_(), got

    html, page = asyncio.run(cell())
    assert re.match(r'<iframe src="http://127\.0\.0\.1:\d+/"', html)
    assert "<html" in page.lower()


def test_a_line_csv_scene_is_posed_by_its_frames_as_run_does(tmp_path):
    """The knee demo (lines and the tibia's poses from CSV files, no model): no sliders, and
    a frame solved live gives the run's files of that frame."""
    from musclewrap.synthetic import write_knee_scene

    toml = write_knee_scene(tmp_path / "input", 61)
    live = LiveScene(toml)
    assert live.coordinates == []
    with pytest.raises(ValueError, match="posed by its frames only"):
        live.solve({})
    r = live.solve(frame=45)
    assert not r.unconverged
    live.write(r, tmp_path / "live")
    run_scene(
        load_scene(toml), tmp_path / "run", frames="45:46", workers=1, render=False, progress=None
    )
    _same_files(tmp_path / "live", tmp_path / "run", [f"{m}/{m}_0045.vtp" for m in live.specs])


def test_translations_and_more_coordinates_as_run_does(data_dir, tmp_path):
    """A hard case of its own: the gait2392 scene driving the pelvis's translations and tilt
    too (seven coordinates, the output in ground): a slider pose far from rest equals run's."""
    scene = _scene(
        data_dir,
        tmp_path,
        "gait2392_walk",
        edit=lambda s: s.replace(
            'coordinates = ["hip_flexion_r"',
            'coordinates = ["pelvis_tx", "pelvis_ty", "pelvis_tilt", "hip_flexion_r"',
        ).replace('output_frame = "pelvis"', 'output_frame = "ground"'),
    )
    live = LiveScene(scene)
    tx = next(c for c in live.coordinates if c.name == "pelvis_tx")
    assert (tx.unit, tx.rotational) == ("m", False)
    values = {"pelvis_tx": 0.4, "pelvis_ty": 0.95, "pelvis_tilt": -20.0, "hip_flexion_r": 70.0,
              "hip_adduction_r": 5.0, "hip_rotation_r": 0.0, "knee_angle_r": -90.0}  # fmt: skip
    r = live.solve(values)
    assert not r.unconverged
    live.write(r, tmp_path / "live")
    run = _run_pose(scene, values, tmp_path / "run")
    _same_files(tmp_path / "live", run, [f"{m}/{m}_0000.vtp" for m in live.specs])


def test_the_colours_sent_are_the_runs_pictures():
    """The page's colours are mapped here, as RGB: the stretch in equal ratios (1 white, a
    ratio and its inverse equally far either side), as the run's pictures colour it; the
    contact from black (touching or inside) through red to yellow at the reach."""
    from musclewrap.output._render import STRETCH_RANGE, stretch_colours, stretch_table
    from musclewrap.view._state import contact_colours

    lo, hi = STRETCH_RANGE
    table = np.rint(255 * stretch_table()).astype(np.uint8)
    got = stretch_colours(np.array([lo, hi, 1.0, np.nan, 0.1, 10.0]))
    np.testing.assert_array_equal(got[:2], table[[0, -1]])  # the range's ends
    np.testing.assert_array_equal(got[2], got[3])  # NaN (a failed pose) as 1
    assert got[2].min() >= 240  # 1: white
    np.testing.assert_array_equal(got[4:], got[:2])  # beyond the range: its ends
    s = np.geomspace(lo, hi, 41)

    def entry(rgb):  # each colour's entry of the table
        return np.abs(rgb[:, None, :].astype(int) - table[None].astype(int)).sum(2).argmin(1)

    a, b = stretch_colours(s), stretch_colours(1 / s)
    assert (a[:, 2] > a[:, 0]).sum() == (b[:, 0] > b[:, 2]).sum() == 20  # blue below 1, red above
    assert (np.abs(entry(a) + entry(b) - 255) <= 1).all()  # a ratio and its inverse equally far
    np.testing.assert_array_equal(
        contact_colours(np.array([-3.0, 0.0, 2.5, 5.0, 50.0])),
        [[0, 0, 0], [0, 0, 0], [230, 0, 0], [230, 230, 0], [230, 230, 0]],
    )


def test_the_lighter_surfaces_are_the_full_ones_vertices():
    """While a slider moves the page draws `Lighter` surfaces: some of the full surface's
    own vertices (none moved), closed triangles over them, about the budget's share of
    the triangles for every part alike; none where the scene is within the budget."""
    from musclewrap.mesh import check_mesh
    from musclewrap.synthetic import capsule
    from musclewrap.view._state import lighter_parts

    V, F = capsule(radius=10.0, length=60.0, n_around=48, cap_rings=12, segments=40)
    V2, F2 = V * 2.0 + 100.0, F.copy()
    total = len(F) + len(F2)
    light = lighter_parts({"muscle0": (V, F), "bone0": (V2, F2)}, total // 4)
    for (P, T), L in zip([(V, F), (V2, F2)], light.values(), strict=True):
        assert L.full == len(T)
        assert 0.2 * len(T) <= len(L.faces) <= 0.3 * len(T)
        assert len(np.unique(L.keep)) == len(L.keep)
        np.testing.assert_array_equal(L.faces.min(), 0)
        assert L.faces.max() == len(L.keep) - 1
        c = check_mesh(P[L.keep], L.faces)
        assert c.boundary_edges == 0  # closed, as the full one
        assert abs(c.volume - check_mesh(P, T).volume) < 0.05 * check_mesh(P, T).volume
    assert lighter_parts({"muscle0": (V, F), "bone0": (V2, F2)}, total) == {}


def test_drawn_keeps_the_full_positions_back_while_a_slider_moves():
    """`Drawn`: a moving pose sends the lighter positions only; `still` sends the full ones
    of the last pose; a bone (a token) is sent only where it moved, and one that moved and
    came back while the slider moved is not sent again."""
    from musclewrap.synthetic import capsule
    from musclewrap.view._state import Drawn

    V, F = capsule()  # 30,144 triangles: twice that is over the budget
    d = Drawn()
    up = {}
    d.begin(False)
    d.put(up, "muscle0", V)
    d.put(up, "bone0", V + 100.0, "at rest")
    assert set(up) == {"muscle0_p", "bone0_p"}
    made = d.make_light({"muscle0": (V, F), "bone0": (V, F)}, {"muscle0": (V, None)})
    assert {"muscle0_lf", "bone0_lf", "muscle0_lp", "light_note"} <= set(made)
    keep = d.light["muscle0"].keep
    for token, P in (("moved", V + 1.0), ("at rest", V + 2.0)):
        up = {}
        assert d.begin(True)
        d.put(up, "muscle0", P)
        d.put(up, "bone0", V + 100.0, token)
        assert "muscle0_p" not in up and "bone0_p" not in up
        np.testing.assert_array_equal(
            np.frombuffer(up["muscle0_lp"], np.float32).reshape(-1, 3), (P[keep]).astype(np.float32)
        )
    up = d.still()
    assert set(up) == {"light", "muscle0_p"} and up["light"] is False  # the bone came back
    np.testing.assert_array_equal(
        np.frombuffer(up["muscle0_p"], np.float32), (V + 2.0).astype(np.float32).ravel()
    )
    assert d.still() == {}  # the page has them now
