"""The command line: what it writes, and what it refuses (exit status 2, no output file)."""

import json
import os
import re
import subprocess
import sys

import numpy as np
import pytest

from musclewrap.cli import main
from musclewrap.mesh import read_mesh, volume, write_mesh
from musclewrap.synthetic import capsule

REPORT_KEYS = {
    "n_vertices",
    "n_cage_vertices",
    "volume_rest",
    "volume_deformed",
    "relative_volume_error",
    "iterations",
    "converged",
    "reason",
    "skeleton_fit_mean",
    "seconds_prepare",
    "seconds_deform",
}


def _lines(path, lines):
    rows = ["line,x,y,z"] + [f"{n},{x!r},{y!r},{z!r}" for n, P in lines.items() for x, y, z in P]
    path.write_text("\n".join(rows) + "\n")
    return str(path)


@pytest.fixture()
def files(tmp_path):
    V, F = capsule(n_around=24, cap_rings=6, segments=20)
    write_mesh(tmp_path / "m.ply", V, F)
    rest = _lines(tmp_path / "rest.csv", {"a": [(0, 0, 5), (0, 0, 195)]})
    cur = _lines(tmp_path / "cur.csv", {"a": [(0, 0, 5), (0, 0, 100), (20, 0, 185)]})
    return tmp_path, str(tmp_path / "m.ply"), rest, cur


def test_deform_says_which_part_of_a_line_beyond_the_muscle_is_not_bound(files, capsys):
    """A rest line that runs on 120 mm past the capsule's end (a tendon the mesh does not
    hold): the tail is not bound, and the command says so and reports it."""
    tmp, mesh, _, _ = files
    rest = _lines(tmp / "rest_long.csv", {"a": [(0, 0, 5), (0, 0, 320)]})
    # the tail turned 60 degrees at z = 250, 50 mm past the belly (farther than the one mean
    # thickness, 37 mm, that stays bound), its length kept (arc-length matching)
    end = (70 * float(np.sin(np.radians(60))), 0.0, 250 + 70 * float(np.cos(np.radians(60))))
    cur = _lines(tmp / "cur_long.csv", {"a": [(0, 0, 5), (0, 0, 250), end]})
    out, rep = tmp / "long.vtp", tmp / "long.json"
    args = ["deform", mesh, "--rest", rest, "--current", cur, "-o", str(out)]
    assert main([*args, "--report", str(rep)]) == 0
    said = capsys.readouterr().out
    assert re.search(r"note: line 'a' is not bound over its first 0 % and last \d+ %", said)
    start, end, far = json.loads(rep.read_text())["lines_unbound"]["a"]
    assert start == 0.0 and 0.25 < end < 0.45 and far == pytest.approx(120.0, abs=1.0)
    # the belly's own stretch of the line did not move: neither did the muscle
    V0, _ = read_mesh(mesh)
    V, _ = read_mesh(out)
    assert np.abs(V - V0).max() <= 1e-6


def test_prepare_then_deform_writes_the_volume_it_reports(files, capsys):
    tmp, mesh, rest, cur = files
    prepared = str(tmp / "m.npz")
    assert main(["prepare", mesh, "-o", prepared, "--cage-size", "150"]) == 0
    for ext in (".vtp", ".vtk", ".ply", ".obj"):
        out, rep = tmp / f"out{ext}", tmp / f"r{ext}.json"
        args = ["deform", mesh, "--rest", rest, "--current", cur, "-o", str(out)]
        assert main([*args, "--report", str(rep), "--prepared", prepared]) == 0
        report = json.loads(rep.read_text())
        assert REPORT_KEYS <= set(report)
        assert report["converged"] and report["iterations"] <= 5
        assert abs(report["relative_volume_error"]) <= 1e-9
        assert report["coordinates_precision"] == "float64"
        V, F = read_mesh(out)
        # what the user reads back has the volume the report states
        assert volume(V, F) == pytest.approx(report["volume_deformed"], rel=1e-12)
        if ext in (".vtp", ".vtk"):  # each vertex's index in the input file
            import pyvista as pv

            ids = np.asarray(pv.read(out).point_data["input_id"])
            assert np.array_equal(ids, np.arange(len(V)))
    # a preparation of another mesh is refused
    V, F = capsule(n_around=20, cap_rings=6, segments=20)
    write_mesh(tmp / "other.ply", V, F)
    args = ["deform", str(tmp / "other.ply"), "--rest", rest, "--current", cur]
    assert main([*args, "-o", str(tmp / "x.vtp"), "--prepared", prepared]) == 2
    assert "prepared from another mesh" in capsys.readouterr().err
    assert not (tmp / "x.vtp").exists()


def test_bad_input_is_refused_with_no_output_file(files, capsys):
    tmp, mesh, rest, cur = files
    V, F = read_mesh(mesh)
    write_mesh(tmp / "open.ply", V, F[1:])
    write_mesh(tmp / "metres.ply", V / 1000, F)
    cases = [
        # (mesh, rest, current, output, expected message)
        (
            str(tmp / "open.ply"),
            rest,
            cur,
            "o.vtp",
            "open.ply: not a closed 2-manifold.*3 boundary",
        ),
        (str(tmp / "nope.stl"), rest, cur, "o.vtp", "nope.stl: no such mesh file"),
        (mesh, _lines(tmp / "one.csv", {"a": [(0, 0, 5)]}), cur, "o.vtp", "two distinct points"),
        (
            mesh,
            rest,
            _lines(tmp / "nan.csv", {"a": [(0, 0, 5), (0, float("nan"), 9)]}),
            "o.vtp",
            "nan.csv",
        ),
        (
            mesh,
            rest,
            _lines(tmp / "b.csv", {"b": [(0, 0, 5), (0, 0, 195)]}),
            "o.vtp",
            "missing \\['a'\\], unexpected \\['b'\\]",
        ),
        (
            str(tmp / "metres.ply"),
            rest,
            cur,
            "o.vtp",
            "line 'a' lies .* away from the muscle.*units",
        ),
        (mesh, rest, cur, "o.xyz", "o.xyz: unknown output format"),
        (mesh, rest, cur, "m.ply", "m.ply: this is an input file.*never writes over its inputs"),
    ]
    for m, r, c, out, match in cases:
        before = sorted(p.name for p in tmp.iterdir())
        stamp = {p.name: p.read_bytes() for p in tmp.iterdir() if p.is_file()}
        args = ["deform", m, "--rest", r, "--current", c, "-o", str(tmp / out)]
        assert main([*args, "--report", str(tmp / "rep.json")]) == 2, match
        err = capsys.readouterr().err
        assert err.startswith("error: ") and "Traceback" not in err
        assert re.search(match, err), (match, err)
        # nothing written, nothing changed
        assert sorted(p.name for p in tmp.iterdir()) == before
        assert all(p.read_bytes() == stamp[p.name] for p in tmp.iterdir() if p.is_file())
    # the report can be neither an input nor the mesh output
    args = ["deform", mesh, "--rest", rest, "--current", cur, "-o", str(tmp / "a.vtp")]
    assert main([*args, "--report", cur]) == 2
    assert "cur.csv: this is an input file" in capsys.readouterr().err
    assert main([*args, "--report", str(tmp / "a.vtp")]) == 2
    assert "another output" in capsys.readouterr().err
    assert not (tmp / "a.vtp").exists()
    assert main(["prepare", mesh, "-o", mesh]) == 2


def test_a_pose_without_finite_positions_writes_nothing_even_when_allowed(files, capsys):
    tmp, mesh, rest, cur = files
    huge = _lines(tmp / "huge.csv", {"a": [(0, 0, 5), (0, 1e150, 1e154)]})
    args = ["deform", mesh, "--rest", rest, "--current", huge, "-o", str(tmp / "o.vtp")]
    for extra in ([], ["--allow-unconverged"]):
        assert main([*args, "--report", str(tmp / "r.json"), *extra]) == 3
        assert "numerically singular" in capsys.readouterr().err
        assert not (tmp / "o.vtp").exists()
        report = json.loads((tmp / "r.json").read_text())  # strict JSON: nulls, no NaN
        assert report["converged"] is False and report["relative_volume_error"] is None


def test_demo_writes_the_series(tmp_path, capsys):
    out = tmp_path / "demo"
    assert main(["demo", "-o", str(out), "--frames", "3"]) == 0
    names = {p.name for p in out.iterdir()}
    assert {"scene.pvd", "report.csv", "penetration.png", "medial", "lateral"} <= names
    assert {"femur", "tibia", "input"} <= names
    for m in ("medial", "lateral"):
        assert len(list((out / m).glob(f"{m}_0*.vtp"))) == 3
        assert len(list((out / m).glob(f"{m}_lines_*.vtp"))) == 3
    # the scene it ran is there to run again
    assert (out / "input" / "knee.toml").is_file()
    # the pictures of a scene run, or (no off-screen OpenGL here) a note saying why not
    captured = capsys.readouterr()
    err = captured.out + captured.err
    if "scene.gif not written" in err:
        assert "no working off-screen rendering backend" in err
        assert not (out / "scene.gif").exists()
    else:
        from PIL import Image

        with Image.open(out / "scene.gif") as im:
            assert im.n_frames == 3
        assert (out / "scene.png").stat().st_size > 0
    assert main(["demo", "-o", str(out), "--frames", "1"]) == 2


def test_deform_keeps_the_muscle_out_of_a_bone(files, capsys):
    import trimesh

    tmp, mesh, rest, cur = files
    # a slab x >= 15: the bent capsule (radius 20) reaches well into it
    box = trimesh.creation.box(bounds=np.array([[15.0, -300, -300], [400, 300, 500]]))
    write_mesh(tmp / "bone.vtp", np.asarray(box.vertices, float), np.asarray(box.faces))
    out, rep = tmp / "out.vtp", tmp / "r.json"
    args = ["deform", mesh, "--rest", rest, "--current", cur, "-o", str(out), "--report", str(rep)]
    assert main([*args, "--bone", str(tmp / "bone.vtp"), "--margin", "1"]) == 0
    report = json.loads(rep.read_text())
    assert report["converged"] and report["contact_vertices"] > 0
    assert report["penetration_depth_before"] > 5 and report["penetration_depth"] == 0
    V, F = read_mesh(out)
    assert V[:, 0].max() <= 14.0 + 0.1  # the slack: tol.contact of 6-7 mm edges
    assert abs(volume(V, F) / report["volume_rest"] - 1) <= 1e-9
    # an open bone has no inside: refused, naming the file, nothing written
    write_mesh(tmp / "open.vtp", np.asarray(box.vertices, float), np.asarray(box.faces)[:-1])
    out.unlink()
    assert main([*args, "--bone", str(tmp / "open.vtp")]) == 2
    assert "open.vtp: the bone is not closed" in capsys.readouterr().err
    assert not out.exists()


def test_version(capsys):

    from musclewrap import __version__

    with pytest.raises(SystemExit) as exc:
        main(["--version"])
    assert exc.value.code == 0
    assert capsys.readouterr().out.strip() == f"musclewrap {__version__}"
    # the installed command, as a user types it
    out = subprocess.run(
        [sys.executable, "-m", "musclewrap.cli", "--version"], capture_output=True, text=True
    )
    assert out.returncode == 0 and out.stdout.strip() == f"musclewrap {__version__}"


def test_a_first_run_says_once_that_it_compiles(files, capsys, monkeypatch):
    # after a pose has run, the kernels are in Numba's cache and nothing is said
    import musclewrap._jit as jit

    tmp, mesh, rest, cur = files
    assert main(["deform", mesh, "--rest", rest, "--current", cur, "-o", str(tmp / "a.vtp")]) == 0
    assert jit.kernels_cached()
    capsys.readouterr()
    assert main(["deform", mesh, "--rest", rest, "--current", cur, "-o", str(tmp / "b.vtp")]) == 0
    assert "compiling" not in capsys.readouterr().err
    # a cold cache (as after installing) is said once, before the work
    monkeypatch.setattr(jit, "kernels_cached", lambda: False)
    assert main(["deform", mesh, "--rest", rest, "--current", cur, "-o", str(tmp / "c.vtp")]) == 0
    err = capsys.readouterr().err
    assert err.count("compiling kernels, once") == 1


def test_a_first_runs_two_shares_compile_every_kernel_once():
    # the run's own process and the helper split `KERNELS` between them: each kernel in one
    # share, the pose's all in the helper's (the run's process prepares first)
    from musclewrap._jit import HELPED, HERE, KERNELS, run_compiles

    every = [(g, name) for g, ks in KERNELS.items() for _, name, _ in ks]
    ours = {k for k in every if run_compiles(*k)}
    assert not any(g == "pose" for g, _ in ours)
    assert {n for g, n in every if g == "contact"} >= set(HERE)
    assert {n for g, n in every if g == "preparation"} >= set(HELPED)
    assert ours == {
        (g, n)
        for g, n in every
        if g != "pose" and (n in HERE if g == "contact" else n not in HELPED)
    }


def test_the_kernels_build_no_arrays_by_numpys_constructors_or_reductions():
    """Inside a first run's kernels (and the compiled helpers beside them), no ``np.zeros``,
    ``np.full``, ``np.ones``, ``np.flatnonzero``, ``np.searchsorted`` or array
    ``min``/``max``/``mean``/``sum``: Numba compiles each such call's implementation again in
    every kernel that makes it (0.1-0.3 s each), which took a first run over 3x the second
    (`musclewrap._jit`, "element loops")."""
    import importlib
    import inspect
    import re

    from numba.core.registry import CPUDispatcher

    from musclewrap._jit import KERNELS

    banned = re.compile(
        r"np\.(?:zeros|full|ones|flatnonzero|searchsorted)\(|\.(?:min|max|mean|sum)\(\)"
    )
    found, seen = [], 0
    for m in sorted({m for ks in KERNELS.values() for m, _, _ in ks}):
        mod = importlib.import_module(f"musclewrap.{m}")
        for name, obj in vars(mod).items():
            if isinstance(obj, CPUDispatcher) and obj.py_func.__module__ == mod.__name__:
                seen += 1
                if banned.search(inspect.getsource(obj.py_func)):
                    found.append(f"{m}.{name}")
    assert seen >= 40 and not found, found


def test_a_source_rewritten_with_the_same_text_is_still_cached(files):
    # Numba keys its cache by the source's text: a checkout or a reinstall that rewrites a
    # kernel's file unchanged (a newer time) keeps its kernels, and a first run is not said
    import os
    import time

    import musclewrap._jit as jit
    from musclewrap.solver._proxy import _plain_iterations

    tmp, mesh, rest, cur = files
    assert main(["deform", mesh, "--rest", rest, "--current", cur, "-o", str(tmp / "a.vtp")]) == 0
    assert jit.kernels_cached()
    source = _plain_iterations.py_func.__code__.co_filename
    st = os.stat(source)
    try:
        later = time.time() + 100.0
        os.utime(source, (later, later))
        assert jit.kernels_cached()
    finally:
        os.utime(source, ns=(st.st_atime_ns, st.st_mtime_ns))


def test_pictures_are_the_same_from_one_or_several_renderers(tmp_path):
    # the frames are shared out among renderer processes, all with the series' camera:
    # the GIF is the same picture by picture
    from PIL import Image, ImageChops

    from musclewrap.output import render_series

    out = tmp_path / "demo"
    assert main(["demo", "-o", str(out), "--frames", "6", "--no-gif"]) == 0
    gifs = []
    for k in (1, 2):
        try:
            gifs.append(
                render_series(
                    out / "scene.pvd",
                    tmp_path / f"k{k}.gif",
                    bones=("femur", "tibia"),
                    colour="stretch",
                    processes=k,
                )
            )
        except RuntimeError as exc:
            pytest.skip(f"no off-screen rendering here: {exc}")
    frames = []
    for g in gifs:
        with Image.open(g) as im:
            frames.append([im.seek(i) or im.convert("RGB") for i in range(im.n_frames)])
    assert len(frames[0]) == len(frames[1]) == 6
    for a, b in zip(*frames, strict=True):
        assert ImageChops.difference(a, b).getbbox() is None
    assert (tmp_path / "k2.png").stat().st_size > 0


def test_a_first_run_compiles_every_kernel_a_demo_calls(tmp_path):
    """A first run says so and starts compiling a pose's kernels (`_jit.KERNELS`, "pose") in
    a second process; with all the listed kernels compiled, a demo in a new process compiles
    nothing more: every kernel it calls is listed, with the signature it is called with."""
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path / "numba")}
    first = (
        "import sys; from musclewrap._jit import compile_if_first_run, kernels_cached\n"
        "assert not kernels_cached()\n"
        "helper = compile_if_first_run(sys.stdout)\n"  # a pose's kernels, meanwhile
        "assert helper.wait() == 0 and kernels_cached()\n"
        "assert compile_if_first_run(sys.stdout) is None\n"  # cached: nothing said or done
        "from musclewrap._jit import compile_kernels; compile_kernels()\n"
    )
    r = subprocess.run([sys.executable, "-c", first], env=env, capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    assert r.stdout.count("compiling kernels, once") == 1
    demo = (
        "import sys\n"
        "from numba.core import event\n"
        "seen = []\n"
        "class Compiled(event.Listener):\n"
        "    def on_start(self, e): seen.append(e.data['dispatcher'].py_func.__qualname__)\n"
        "    def on_end(self, e): pass\n"
        "event.register('numba:compile', Compiled())\n"
        "from musclewrap.cli import main\n"
        # one worker: every kernel compiles in this process, where the listener sees it
        f"assert main(['demo', '-o', {str(tmp_path / 'demo')!r}, '--frames', '3', '--no-gif', "
        "'--workers', '1']) == 0\n"
        "print('compiled:', sorted(set(seen)))\n"
    )
    r = subprocess.run([sys.executable, "-c", demo], env=env, capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    assert "compiled: []" in r.stdout
    assert "compiling" not in r.stderr
