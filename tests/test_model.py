import numpy as np
import pytest

from musclewrap.scene import (
    SceneError,
    read_motion,
)
from musclewrap.synthetic import capsule


# ------------------------------------------------------------------ motion files
def _mot(tmp_path, header, labels, rows):
    p = tmp_path / "m.mot"
    text = header + "endheader\n" + "\t".join(labels) + "\n"
    text += "\n".join("\t".join(str(v) for v in r) for r in rows) + "\n"
    p.write_text(text)
    return p


def test_read_motion_degrees_and_columns(tmp_path):
    p = _mot(
        tmp_path, "x\ninDegrees=yes\n", ["time", "a", "b", "b"], [[0, 1, 2, 3], [0.5, 4, 5, 6]]
    )
    m = read_motion(p)
    assert m.in_degrees and m.degrees_declared
    np.testing.assert_array_equal(m.time, [0, 0.5])
    np.testing.assert_array_equal(m.columns["a"], [1, 4])
    assert "b" in m.repeated and "b" not in m.columns


@pytest.mark.parametrize(
    ("text", "match"),
    [
        ("time\ta\n0\t1\n", "endheader"),
        ("endheader\na\tb\n0\t1\n", "no 'time' column"),
        ("endheader\ntime\ta\n0\t1\t2\n", "row 1 has 3 values"),
        ("endheader\ntime\ta\n0\tx\n", "non-numeric"),
        ("endheader\ntime\ta\n0\tnan\n", "NaN"),
        ("endheader\ntime\ta\n1\t1\n0\t1\n", "do not increase"),
        ("endheader\ntime\ta\n", "no frames"),
    ],
)
def test_read_motion_refuses_bad_files(tmp_path, text, match):
    p = tmp_path / "bad.mot"
    p.write_text(text)
    with pytest.raises(SceneError, match=match):
        read_motion(p)


def test_registration_similarity_and_landmarks():
    from musclewrap.model._register import (
        axes_rotation,
        fit_sphere,
        similarity,
        surface_centroid,
    )

    rng = np.random.default_rng(4)
    # a sphere's fitted centre and radius, and the centroid of a closed surface
    V, F = capsule(radius=7.0, length=0.0, n_around=48, cap_rings=24, segments=1)
    c, r, rms = fit_sphere(V + [1.0, 2.0, 3.0])
    assert np.allclose(c, V.mean(axis=0) + [1, 2, 3], atol=1e-6) and r == pytest.approx(7.0, 1e-3)
    assert rms < 0.05
    assert np.allclose(surface_centroid(V, F), V.mean(axis=0), atol=1e-9)
    # a known similarity is recovered from three landmarks, and from two with the axes
    R = axes_rotation(["y", "z", "x"])
    assert np.allclose(R @ [0.0, 1, 0], [1, 0, 0]) and np.linalg.det(R) == pytest.approx(1)
    P = rng.normal(size=(4, 3)) * 50
    Q = 1.17 * P @ R.T + [10.0, -20.0, 5.0]
    for k in (2, 3, 4):
        T = similarity(P[:k], Q[:k], R if k == 2 else None)
        assert np.allclose(P @ T[:3, :3].T + T[:3, 3], Q, atol=1e-9), k
    # two landmarks and no axes: the line through them is matched, not the turn about it
    T = similarity(P[:2], Q[:2], None)
    assert np.allclose(P[:2] @ T[:3, :3].T + T[:3, 3], Q[:2], atol=1e-9)


def test_a_whole_femur_gives_its_head_and_condyles_in_any_frame(data_dir):
    """Issue 47: the hip centre from a femur mesh's head, the knee from its condyles, found
    whichever way the mesh lies; OpenSim's femurs (in the femur's frame) put the head on the
    hip, the body's origin."""
    from musclewrap.errors import SceneError
    from musclewrap.mesh import read_mesh
    from musclewrap.model import femur_landmarks, landmark_point

    for name in ("femur_r.vtp", "r_femur.vtp"):
        V, F = read_mesh(data_dir / "opensim/Geometry" / name)[:2]
        head, knee, _ = femur_landmarks(V, F, name)
        assert np.linalg.norm(head) < 0.003, (name, head)  # metres
        assert abs(knee[1] + 0.40) < 0.015 and np.hypot(knee[0], knee[2]) < 0.015, (name, knee)
    V, F = read_mesh(data_dir / "lhdl/bones/LHDL_R_Femur.vtk")[:2]
    head, knee, said = femur_landmarks(V, F, "LHDL")
    assert "femoral head sphere r 23.1" in said
    rng = np.random.default_rng(7)
    for _ in range(3):  # turned and moved anyhow, the same points (to 0.1 mm: the vote's
        # cells lie along the mesh's axes)
        Q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
        Q *= np.sign(np.linalg.det(Q))
        shift = rng.normal(scale=500.0, size=3)
        h2, k2, _ = femur_landmarks(V @ Q.T + shift, F, "LHDL")
        assert np.linalg.norm(h2 - (head @ Q.T + shift)) < 0.1
        assert np.linalg.norm(k2 - (knee @ Q.T + shift)) < 1e-6
    assert np.allclose(landmark_point(V, F, "femoral_head", "hip", "LHDL")[0], head)
    assert np.allclose(landmark_point(V, F, "femur_distal", "knee", "LHDL")[0], knee)
    # half a femur (no condyles to tell from the head): said
    t = (V - V.mean(0)) @ np.linalg.eigh(np.cov(V.T))[1][:, -1]
    keep = np.flatnonzero(t < np.quantile(t, 0.5))
    with pytest.raises(SceneError, match="LHDL"):
        sub = np.full(len(V), -1)
        sub[keep] = np.arange(len(keep))
        Fk = sub[F][(sub[F] >= 0).all(axis=1)]
        femur_landmarks(V[keep], Fk, "LHDL")


# ------------------------------------------------------------------ a long bone's shaft fitted
def _tube_and_rod(hole_x):
    """A tube of muscle (hole radius 12, wall to 30, 200 long) whose hole runs ``hole_x``
    off the axis of a rod of bone (radius 10, 400 long) held at its two ends."""
    import trimesh

    tube = trimesh.creation.annulus(12.0, 30.0, 200.0, sections=64)
    tube.apply_translation([hole_x, 0.0, 0.0])
    Vt, Ft = trimesh.remesh.subdivide_to_size(tube.vertices, tube.faces, 4.0)
    rod = trimesh.creation.cylinder(10.0, 400.0, sections=48)
    Vr, Fr = trimesh.remesh.subdivide_to_size(rod.vertices, rod.faces, 8.0)
    return (np.asarray(Vr), np.asarray(Fr)), {"tube": (np.asarray(Vt), np.asarray(Ft))}


def test_a_rod_in_a_tube_off_its_axis_moves_its_middle_into_the_hole():
    """The rod's sections where the tube is move, whole, into its hole (8 off: a margin of
    2 each side, the price zero only there); its held ends stay; the tube's vertices that
    lay in the rod lie outside it after."""
    import igl

    from musclewrap.mesh import self_intersecting_faces
    from musclewrap.model import fit_shaft

    (V, F), tube = _tube_and_rod(8.0)
    f = fit_shaft(V, F, tube, np.array([[0.0, 0.0, -200.0], [0.0, 0.0, 200.0]]))
    mid = f.move(np.array([[0.0, 0.0, 0.0], [5.0, -3.0, 0.0], [0.0, 0.0, 200.0]]))
    np.testing.assert_allclose(mid[0], [8.0, 0.0, 0.0], atol=1.0)
    np.testing.assert_allclose(mid[1], mid[0], atol=1e-9)  # a section moves as a whole
    np.testing.assert_allclose(mid[2], 0.0, atol=1e-9)  # held
    assert f.held[0] and f.held[-1] and not f.held[len(f.held) // 2]
    n, deep = f.before["tube"]
    assert n > 50 and deep > 5.0
    assert f.after["tube"][1] <= 1e-9
    np.testing.assert_allclose(f.V, V + f.move(V))
    assert self_intersecting_faces(f.V, F) == 0
    s = igl.signed_distance(tube["tube"][0], f.V, F)[0]
    assert s.min() > -1e-9  # touching at most (the tube's ends)


def test_a_rod_clear_of_its_tube_stays_where_it_is():
    from musclewrap.model import fit_shaft

    (V, F), tube = _tube_and_rod(0.0)
    f = fit_shaft(V, F, tube, np.zeros((0, 3)))
    assert f.moved == 0.0 and not f.before
    np.testing.assert_array_equal(f.V, V)


def test_a_rod_held_along_its_whole_length_stays_however_deep_the_tube_is():
    from musclewrap.model import fit_shaft

    (V, F), tube = _tube_and_rod(8.0)
    held = np.c_[np.zeros(81), np.zeros(81), np.linspace(-200.0, 200.0, 81)]
    f = fit_shaft(V, F, tube, held)
    assert f.held.all() and f.moved == 0.0
    assert f.after["tube"] == f.before["tube"]


# ------------------------------------------------------------ the posture of the meshes
def _ball_on_a_plate(height):
    """A ball (radius 10) above a plate 10 thick whose top is at y = 5, and the motion of a
    hip 100 to its left: coordinate 0 turns the ball about z there (up, for a positive
    angle: 100 mm a radian), coordinate 1 about the ball's own vertical axis (nothing
    changes: the price is flat along it)."""
    import trimesh

    ball = trimesh.creation.icosphere(subdivisions=4, radius=10.0)
    ball.apply_translation([0.0, height, 0.0])
    plate = trimesh.creation.box(extents=(80.0, 10.0, 80.0))
    centre = np.array([0.0, height, 0.0])

    def turn(angle, axis, point):
        T = trimesh.transformations.rotation_matrix(angle, axis, point)
        return np.asarray(T)

    def place(dq):
        # the ball's frame into the plate's: turned by the hip, then about itself
        return [turn(dq[0], [0, 0, 1], [-100.0, 0.0, 0.0]) @ turn(dq[1], [0, 1, 0], centre)]

    meshes = {"ball": (np.asarray(ball.vertices), np.asarray(ball.faces))}
    return meshes, [(np.asarray(plate.vertices), np.asarray(plate.faces))], place


def test_a_ball_in_a_plate_is_turned_out_of_it_about_the_hip_and_no_further():
    """The ball's bottom 3 mm in the plate: clear of it by the margin (2) once the hip turns
    it up by 5 mm, 2.87 deg: the fit's grid (0.5 deg) gives 3; the turn about the ball's own
    axis changes nothing and stays at zero."""
    from musclewrap.model import fit_posture

    meshes, bones, place = _ball_on_a_plate(12.0)
    f = fit_posture(meshes, bones, place, ["hip", "spin"])
    np.testing.assert_allclose(np.degrees(f.change), [3.0, 0.0], atol=1e-9)
    assert f.price[0] > 0 and f.price[1] == 0.0
    n, deep = f.before["ball"]
    assert n > 10 and 2.5 < deep < 3.5
    assert f.after == {"ball": (0, 0.0)}
    assert f.coordinates == ("hip", "spin")


def test_a_ball_clear_of_its_plate_keeps_its_posture():
    from musclewrap.model import fit_posture

    meshes, bones, place = _ball_on_a_plate(20.0)
    f = fit_posture(meshes, bones, place, ["hip", "spin"])
    np.testing.assert_array_equal(f.change, [0.0, 0.0])
    assert f.price == (0.0, 0.0) and not f.before


@pytest.mark.parametrize("assembled", [False, True])
def test_a_constrained_models_pose_does_not_depend_on_the_poses_before(data_dir, assembled):
    """Rajagopal 2016 couples each patella's angle to its knee's. OpenSim's assembly
    tracked from the pose it last assembled, so the same pose set after others moved every
    coordinate by up to 1e-9 rad and a frame depended on the frames run with it. Couplers
    are now set exactly, and a model that needs the assembly gets a fresh solver each time
    (``assembled``: Rajagopal forced through it): the same bytes whatever came before."""
    from musclewrap.model._opensim import OpenSimModel

    model = OpenSimModel(data_dir / "opensim" / "models" / "Rajagopal2016.osim")
    model._constrained = assembled
    rng = np.random.default_rng(3)
    legs = ("hip_flexion_r", "hip_adduction_r", "knee_angle_r", "knee_angle_l")
    poses = [{**model.default_pose(), **dict(zip(legs, rng.uniform(0.05, 1.0, 4), strict=True))}]
    poses += [
        {**poses[0], **dict(zip(legs, rng.uniform(0.05, 1.0, 4), strict=True))} for _ in range(4)
    ]

    def seen():
        q = {c: model._coords[c].getValue(model.state) for c in model.coordinate_names}
        return q, {p: model.path_points(p, "ground") for p in ("glmax1_r", "recfem_r", "vasmed_r")}

    model.set_pose(poses[0])
    alone_q, alone = seen()
    for pose in poses[1:]:
        model.set_pose(pose)
    model.set_pose(poses[0])
    after_q, after = seen()
    assert alone_q == after_q
    assert all(np.array_equal(alone[p], after[p]) for p in alone)
    assert alone_q["knee_angle_r_beta"] == pytest.approx(poses[0]["knee_angle_r"], abs=1e-9)
    if not assembled:  # set exactly: the driven coordinates are the pose's own
        assert all(alone_q[c] == poses[0][c] for c in model.coordinate_names if "beta" not in c)
