"""The embedded demo (two muscles wrapping over a knee), and what it is made of.

Moving bones without a model (``[lines] bodies``), the muscles' ``area_stretch``, and the
pictures' camera (`View`, `frame_view`, `picture_view`).
"""

import csv
import shutil

import numpy as np
import pytest

from musclewrap.cli import main
from musclewrap.constants import defaults
from musclewrap.mesh import mean_edge_length, read_mesh, volume
from musclewrap.output._render import STRETCH_RANGE, View, frame_view
from musclewrap.run._run import picture_view
from musclewrap.scene import SceneError, drive_scene, load_scene, run_scene
from musclewrap.solver import Muscle
from musclewrap.synthetic import knee_demo, write_knee_scene


def _rows(path):
    with open(path, newline="") as fh:
        return list(csv.DictReader(fh))


@pytest.fixture(scope="module")
def demo(tmp_path_factory):
    """`musclewrap demo` with 13 frames (0 to 90 deg, 7.5 deg apart), pictures drawn."""
    out = tmp_path_factory.mktemp("demo") / "out"
    assert main(["demo", "-o", str(out), "--frames", "13"]) == 0
    return out


def test_the_demo_wraps_with_contact_and_exact_volume(demo):
    rows = _rows(demo / "report.csv")
    assert len(rows) == 2 * 13 and {r["muscle"] for r in rows} == {"medial", "lateral"}
    assert all(r["converged"] == "True" for r in rows)
    assert max(abs(float(r["relative_volume_error"])) for r in rows) < 1e-12
    # the lines wrap round the condyles 3 mm over the bone: the solve alone drives each
    # muscle's back about 5 mm into them, the contact keeps it out ...
    before = [float(r["penetration_depth_before"]) for r in rows]
    assert max(before) > 4.0
    assert max(float(r["penetration_depth_max"]) for r in rows) < 0.05
    wrapped = [r for r in rows if float(r["frame"]) >= 2]
    assert all(int(r["contact_vertices"]) > 0 for r in wrapped)
    # ... and the two, side by side, out of each other to the rounds' tolerance (a twentieth
    # of a mean edge: 0.13 mm; 0.10 with the samples' windows, 0.03 without), without creases
    for m in ("medial", "lateral"):
        edge = mean_edge_length(*read_mesh(demo / "input" / f"{m}.vtp"))
        depth = max(float(r["muscle_overlap_max"]) for r in rows if r["muscle"] == m)
        assert depth <= defaults.muscle_overlap_depth * edge
    assert max(float(r["shape_change_max"]) for r in rows) < 0.3
    # each muscle's written volume is its rest volume, frame by frame
    for m in ("medial", "lateral"):
        V0, F0 = read_mesh(demo / "input" / f"{m}.vtp")
        for k in (0, 6, 12):
            V, F = read_mesh(demo / m / f"{m}_{k:04d}.vtp")
            assert abs(volume(V, F) / volume(V0, F0) - 1) < 1e-12


def test_the_demo_picture_frames_the_contact(demo):
    """scene.png (the middle frame, 45 deg) holds the muscles' contact with the condyles."""
    import igl
    import pyvista as pv
    from PIL import Image

    png = demo / "scene.png"
    if not png.exists():  # no off-screen OpenGL here: the run said why
        pytest.skip("no off-screen rendering here")
    scene = load_scene(demo / "input" / "knee.toml")
    bones = {b.name: read_mesh(b.mesh) for b in scene.bones}
    drive = drive_scene(scene, None, {n: V.mean(axis=0) for n, (V, _) in bones.items()})
    view = picture_view(scene, drive, {m.name: read_mesh(m.mesh) for m in scene.muscles})
    Vf, Ff = bones["femur"]
    picture = np.asarray(Image.open(png).convert("RGB")).astype(int)
    h, w, _ = picture.shape
    assert (w, h) == scene.image_size
    for m in ("medial", "lateral"):
        mesh = pv.read(demo / m / f"{m}_0006.vtp")
        V = np.asarray(mesh.points, dtype=np.float64)
        d2, _, _ = igl.point_mesh_squared_distance(V, Vf, Ff.astype(np.int64))
        contact = V[np.sqrt(d2) < 0.3]  # at the condyles (the contact's margin is 0)
        assert len(contact) >= 20
        px = view.project(contact, (w, h))
        # inside the picture with 5 % to spare each side, not at its edge
        assert (px[:, 0] > 0.05 * w).all() and (px[:, 0] < 0.95 * w).all()
        assert (px[:, 1] > 0.05 * h).all() and (px[:, 1] < 0.95 * h).all()
        # drawn there: the muscle or the bone in front of it, not the white background
        c = np.round(px.mean(axis=0)).astype(int)
        assert picture[c[1], c[0]].min() < 235
        # the file's stretch is what the picture colours: stretched at 45 deg, and squeezed
        # where the two muscles meet to about half the area (the lateral's least: 0.507 with
        # `nudge`'s fine steps, 0.491 with the plate's since 2026-12-04), under the colours'
        # range but not far under it
        s = np.asarray(mesh.point_data["area_stretch"])
        assert s.min() > STRETCH_RANGE[0] / 1.6 and 1.05 < np.median(s) < STRETCH_RANGE[1]
    # the muscles are coloured by stretch: red (stretched) pixels, and blue ones
    r, g, b = picture[..., 0], picture[..., 1], picture[..., 2]
    assert ((r - b > 60) & (r - g > 60)).sum() > 2000
    assert ((b - r > 40) & (b - g > 20)).sum() > 50
    # nothing is cut at the picture's edges but the bones running out of it
    edge = np.concatenate([picture[0], picture[-1], picture[:, 0], picture[:, -1]])
    assert not ((edge[:, 0] - edge[:, 2] > 60) | (edge[:, 2] - edge[:, 0] > 40)).any()


def test_the_demo_scene_runs_again_as_written(demo, tmp_path):
    """The scene the demo wrote runs alone to the same files (the demo is a plain scene)."""
    toml = demo / "input" / "knee.toml"
    out = tmp_path / "again"
    s = run_scene(load_scene(toml), out, frames="6:7", cache_dir=tmp_path / "c", progress=None)
    assert s.unconverged == 0
    for m in ("medial", "lateral"):
        a, _ = read_mesh(out / m / f"{m}_0006.vtp")
        b, _ = read_mesh(demo / m / f"{m}_0006.vtp")
        np.testing.assert_allclose(a, b, rtol=0, atol=1e-9 * 300)


def test_a_bone_on_a_moving_body_follows_its_poses(tmp_path):
    toml = write_knee_scene(tmp_path / "knee", 5)
    scene = load_scene(toml)
    assert scene.bodies_csv == tmp_path / "knee" / "bodies.csv"
    demo = knee_demo(5)
    bones = {b.name: read_mesh(b.mesh) for b in scene.bones}
    drive = drive_scene(scene, None, {n: V.mean(axis=0) for n, (V, _) in bones.items()})
    assert set(drive.to_output) == {"ground", "tibia"}
    for k in range(5):
        np.testing.assert_allclose(drive.to_output["tibia"][k], demo.tibia_pose(k), atol=1e-11)
    np.testing.assert_array_equal(drive.to_body["tibia"], np.eye(4))  # its own frame at rest
    # a mesh given in the scene's frame at another rest frame: its body's pose there undone
    text = toml.read_text().replace('body = "tibia"', 'body = "tibia"\nframe = "ground"')
    moved = tmp_path / "knee" / "moved.toml"
    moved.write_text(text.replace("[lines]\n", "[lines]\nrest_frame = 4\n"))
    d2 = drive_scene(load_scene(moved), None, {n: V.mean(axis=0) for n, (V, _) in bones.items()})
    np.testing.assert_allclose(d2.to_body["tibia"], np.linalg.inv(demo.tibia_pose(4)), atol=1e-11)
    # the muscles' frame to the tibia's at rest (the rest overlap, the contact's sides): its
    # pose at the rest frame undone, whichever frame its mesh is given in
    body = tmp_path / "knee" / "body.toml"
    body.write_text(toml.read_text().replace("[lines]\n", "[lines]\nrest_frame = 4\n"))
    for sc in (moved, body):
        d = drive_scene(load_scene(sc), None, {n: V.mean(axis=0) for n, (V, _) in bones.items()})
        T = d.rest_between("ground", "tibia")
        np.testing.assert_allclose(T, np.linalg.inv(demo.tibia_pose(4)), atol=1e-11)
    np.testing.assert_array_equal(d.to_body["tibia"], np.eye(4))  # given in its own frame
    # the bones' files of a run: the tibia's turned by its pose, the femur's still
    out = tmp_path / "out"
    run_scene(scene, out, cache_dir=tmp_path / "c", progress=None, render=False)
    T0, _ = read_mesh(out / "tibia" / "tibia_0000.vtp")
    T4, _ = read_mesh(out / "tibia" / "tibia_0004.vtp")
    np.testing.assert_allclose(T4, T0 @ demo.tibia_pose(4)[:3, :3].T, atol=1e-9)


@pytest.mark.parametrize(
    ("edit", "match"),
    [
        (lambda b: b.replace(",tibia,", ",shin,"), r"no poses of body 'tibia'.*shin"),
        (
            lambda b: "\n".join(b.splitlines()[:-1]) + "\n",
            r"body 'tibia' has no pose at frame\(s\) 4",
        ),
        (lambda b: b + b.splitlines()[1] + "\n", r"gives body 'tibia' at frame 0 again"),
        (
            lambda b: b.replace("0,0,tibia,1,0,0", "0,0,tibia,2,0,0", 1),
            r"rotation of 'tibia' at frame 0 is not a rotation",
        ),
        (
            lambda b: b.replace("0,0,tibia,1,0,0,0,1,0", "0,0,tibia,1,0,0,0,-1,0", 1),
            r"rotation of 'tibia' at frame 0 is not a rotation",
        ),
        (lambda b: b.replace("\n1,0.5,", "\n1,0.7,", 1), r"frame 1 at time 0.7, the line CSV's"),
        (lambda b: b.replace("\n1,0.5,tibia,", "\n1,0.5,tibia,x", 1), r"non-numeric"),
        (lambda b: b.replace("frame,time,body", "frame,body", 1), r"header must be"),
    ],
)
def test_bad_body_poses_are_refused_naming_the_file(tmp_path, edit, match):
    toml = write_knee_scene(tmp_path / "knee", 5)
    p = tmp_path / "knee" / "bodies.csv"
    p.write_text(edit(p.read_text()))
    scene = load_scene(toml)
    with pytest.raises(SceneError, match=match) as exc:
        drive_scene(scene, None, {"femur": np.zeros(3), "tibia": np.zeros(3)})
    assert "bodies.csv" in str(exc.value)


def test_moving_bones_need_their_poses(tmp_path):
    toml = write_knee_scene(tmp_path / "knee", 3)
    text = toml.read_text()
    bad = tmp_path / "knee" / "bad.toml"
    bad.write_text(text.replace('bodies = "bodies.csv"', ""))
    with pytest.raises(SceneError, match=r"body needs an OpenSim model .* or the bodies' poses"):
        load_scene(bad)
    bad.write_text(text.replace('csv = "lines.csv"', "").replace("[lines]", "[model]\n[lines]"))
    with pytest.raises(SceneError, match="needs"):
        load_scene(bad)
    bad.write_text(text.replace('body = "tibia"', 'body = "tibia"\nframe = "femur"'))
    with pytest.raises(SceneError, match=r"frame = 'femur': without a model"):
        drive_scene(load_scene(bad), None, {"femur": np.zeros(3), "tibia": np.zeros(3)})
    for view in ("[1]", "[0, 400]", '["a", 1]'):
        bad.write_text(text.replace("view = [-35, 12]", f"view = {view}"))
        with pytest.raises(SceneError, match=r"\[output\] view must be"):
            load_scene(bad)
    bad.write_text(text.replace('colour = "stretch"', 'colour = "rainbow"'))
    with pytest.raises(SceneError, match=r"\[output\] colour = 'rainbow'"):
        load_scene(bad)
    shutil.rmtree(tmp_path / "knee")


def test_area_stretch_is_one_when_rigid_and_the_square_of_a_scaling():
    from musclewrap.synthetic import capsule

    V, F = capsule(radius=10.0, length=60.0, n_around=16, cap_rings=4, segments=8)
    muscle = Muscle.from_mesh(V, F, cage_size=60)
    t = np.radians(33.0)
    R = np.array([[np.cos(t), -np.sin(t), 0], [np.sin(t), np.cos(t), 0], [0, 0, 1]])
    np.testing.assert_allclose(muscle.area_stretch(muscle.V @ R.T + 5.0), 1.0, atol=1e-12)
    np.testing.assert_allclose(muscle.area_stretch(1.2 * muscle.V), 1.44, rtol=1e-12)
    # lengthened along z at constant volume (x, y by 1/sqrt(1.21)): the sides by 1.1
    S = muscle.V * [1 / 1.1, 1 / 1.1, 1.21]
    side = np.abs(muscle.V[:, 2] - muscle.V[:, 2].mean()) < 15.0
    np.testing.assert_allclose(muscle.area_stretch(S)[side], 1.1, rtol=0.02)
    with pytest.raises(ValueError, match="shape"):
        muscle.area_stretch(muscle.V[:-1])


def test_the_view_frames_its_box_and_projects_like_a_camera():
    lo, hi = np.array([-10.0, -20.0, -200.0]), np.array([60.0, 30.0, 150.0])
    corners = lo + np.indices((2, 2, 2)).reshape(3, -1).T * (hi - lo)
    for turn in ((0.0, 0.0), (-35.0, 12.0), (60.0, -20.0)):
        for size in ((800, 600), (300, 900)):
            v = frame_view(lo, hi, turn, size)
            px = v.project(corners, size)
            w, h = size
            assert (px[:, 0] >= 0.039 * w).all() and (px[:, 0] <= 0.961 * w).all()
            assert (px[:, 1] >= 0.039 * h).all() and (px[:, 1] <= 0.961 * h).all()
            # tight: some corner reaches the 4 % margin on one axis
            gap = min(px[:, 0].min() / w, 1 - px[:, 0].max() / w)
            gap = min(gap, px[:, 1].min() / h, 1 - px[:, 1].max() / h)
            assert gap < 0.041
            np.testing.assert_allclose(v.project(np.array(v.focal), size)[0], (w / 2, h / 2))
    # seen from the side: the thinnest extent (y) is the line of sight, z up
    v = frame_view(lo, hi)
    d = np.array(v.position) - np.array(v.focal)
    assert abs(d[1]) == pytest.approx(np.linalg.norm(d)) and v.up == (0.0, 0.0, 1.0)
    # up in the picture is up in the scene
    top, bottom = v.project(np.array([[25.0, 5.0, 100.0], [25.0, 5.0, -100.0]]), (800, 600))
    assert top[1] < bottom[1]
    assert isinstance(v, View)
