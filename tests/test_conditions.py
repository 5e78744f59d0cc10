import numpy as np
import pytest

from musclewrap.conditions import LineError, check_lines, cotangent_laplacian, sample_lines
from musclewrap.synthetic import capsule, capsule_scenario


def test_laplacian_rows_and_planar_patch():
    V, F = capsule(n_around=16, cap_rings=5, segments=8)
    L = cotangent_laplacian(V, F)
    assert np.allclose(L.sum(axis=1), 0) and np.allclose(np.diag(L), -1)
    # interior vertices of a flat patch have zero Laplacian
    g = np.array([[x, y, 0.0] for y in range(5) for x in range(5)])
    Fp = []
    for y in range(4):
        for x in range(4):
            a = 5 * y + x
            Fp += [[a, a + 1, a + 6], [a, a + 6, a + 5]]
    from musclewrap.conditions._laplacian import cotangent_laplacian as lap

    Lp = lap(g, np.array(Fp))
    inner = [6, 7, 8, 11, 12, 13, 16, 17, 18]
    assert np.abs((Lp @ g)[inner]).max() < 1e-12


def test_lines_validation():
    with pytest.raises(LineError, match="two distinct points"):
        check_lines({"a": [[0, 0, 0]]})
    with pytest.raises(LineError, match="two distinct points"):
        check_lines({"a": [[0, 0, 0], [0, 0, 0]]})
    with pytest.raises(LineError, match="non-finite"):
        check_lines({"a": [[0, 0, 0], [np.nan, 0, 1]]})
    s = sample_lines(check_lines({"a": [[0, 0, 0], [0, 0, 10], [0, 0, 20]]}), spacing=1.0)
    with pytest.raises(LineError, match="missing"):
        s.evaluate({"b": np.array([[0.0, 0, 0], [1, 0, 0]])})
    with pytest.raises(LineError, match="missing \\[\\], unexpected \\['b'\\]"):
        s.evaluate(
            {"a": np.array([[0.0, 0, 0], [1, 0, 0]]), "b": np.array([[0.0, 0, 0], [1, 0, 0]])}
        )
    # a current line with another point count matches by arc length
    pts = s.evaluate({"a": np.array([[0.0, 0, 0], [0, 0, 40]])})
    assert np.allclose(pts[:, 2], 2 * s.evaluate({"a": np.array([[0.0, 0, 0], [0, 0, 20]])})[:, 2])


def test_rest_line_far_from_the_muscle_is_refused(small_muscle):
    z = [[0, 0, 5], [0, 0, 195]]
    with pytest.raises(LineError, match="line 'far' lies 4.98e\\+03 away from the muscle.*units"):
        small_muscle.bind({"a": z, "far": [[5000, 0, 5], [5000, 0, 195]]})
    # a line given in another frame (here 500 mm to the side)
    with pytest.raises(LineError, match="line 'a' lies .* away from the muscle"):
        small_muscle.bind({"a": [[0, 500, 5], [0, 500, 195]]})
    # lines in metres, the mesh in millimetres: inside the box, but a thousand times too short
    with pytest.raises(LineError, match="longest line measures 0.19 and the muscle 208.*units"):
        small_muscle.bind({"a": [[0, 0, 0.005], [0, 0, 0.195]]})
    # a line that leaves the muscle at its ends (tendons, attachments) is fine
    small_muscle.bind({"a": [[0, 0, -60], [0, 0, 260]]})


def test_a_tendon_beyond_the_muscle_turning_at_a_joint_leaves_the_muscle_alone(small_muscle):
    # the capsule's belly lies along z from 0 to 200; its path runs on through a tendon to
    # z = 320, turned 60 degrees at a "knee" 40 mm past the belly's end. Bound to its whole
    # path, the extrapolated coordinates of the tendon's samples drag the belly 33 mm and
    # crease it; bound up to one mean thickness (4 V / A, about 37 mm here) past its end,
    # the belly stays where its own stretch of the path is: at rest.
    V = small_muscle.V
    rest = {"axis": np.array([[0.0, 0.0, 0.0], [0.0, 0.0, 240.0], [0.0, 0.0, 320.0]])}
    a = np.radians(60.0)
    knee = [80.0 * np.sin(a), 0.0, 240.0 + 80.0 * np.cos(a)]
    cur = {"axis": np.array([[0.0, 0.0, 0.0], [0.0, 0.0, 240.0], knee])}
    d = small_muscle.bind(rest)
    from musclewrap.mesh import face_areas

    thickness = 4 * small_muscle.volume_rest / face_areas(V, small_muscle.F).sum()
    (start, end, far) = d.unbound["axis"]
    assert start == 0.0 and far == pytest.approx(120.0, abs=0.5)
    # cut past the last sample within one thickness of the pole (z = 200)
    kept_end = (1 - end) * 320.0
    assert 200.0 < kept_end <= 200.0 + 1.05 * thickness
    assert d.sampling.count < small_muscle.bind(rest, line_reach=None).sampling.count
    r = d.deform(cur)
    assert r.converged and np.abs(r.V - V).max() <= 1e-6
    whole = small_muscle.bind(rest, line_reach=None).deform(cur)
    assert np.abs(whole.V - V).max() > 20.0
    assert small_muscle.shape_change(whole.V).max() > 0.5
    # a path that stays within the muscle's reach is bound whole
    assert small_muscle.bind({"a": [[0, 0, -20], [0, 0, 220]]}).unbound == {}
    with pytest.raises(ValueError, match="line_reach must be positive"):
        small_muscle.bind(rest, line_reach=0.0)


def test_within_reach_keeps_each_lines_stretch_near_the_muscle():
    from musclewrap.conditions import LineSampling, within_reach

    t = np.linspace(0.0, 1.0, 11)
    s = LineSampling(names=("a", "b", "c"), params=(t, t, t))
    far = np.r_[9, 5, 1, 0, 0, 3, 0, 1, 2, 4, 8.0]  # "a": tails both sides, a gap inside
    away = np.full(11, 7.0)  # "b": nowhere within reach: kept whole
    touch = np.r_[np.full(7, 9.0), 2.0, np.full(3, 9.0)]  # "c": one sample within reach
    got, cut = within_reach(s, np.r_[far, away, touch], 2.0, keep=5)
    assert np.array_equal(got.params[0], t[2:9])  # the gap at 3 stays bound
    assert np.array_equal(got.params[1], t)
    assert np.array_equal(got.params[2], t[5:10])  # 5 kept around the nearest
    assert cut["a"] == pytest.approx((0.2, 0.2, 9.0))
    assert "b" not in cut and cut["c"] == pytest.approx((0.5, 0.1, 9.0))
    # the kept samples evaluate any current line at their old parameters
    line = {n: np.array([[0.0, 0, 0], [0, 0, 10.0]]) for n in "abc"}
    assert np.allclose(got.evaluate(line)[: len(got.params[0]), 2], 10 * t[2:9])


def test_quaternion_roundtrip_and_sign():
    from scipy.spatial.transform import Rotation

    from musclewrap.conditions import matrix_to_quaternion, quaternion_to_matrix

    R = Rotation.random(50, random_state=3).as_matrix()
    q = matrix_to_quaternion(R)
    assert np.allclose(np.linalg.norm(q, axis=1), 1.0)
    assert np.allclose(quaternion_to_matrix(q), R, atol=1e-12)
    assert np.allclose(quaternion_to_matrix(-3.0 * q), R, atol=1e-12)


def test_line_sampling_matches_numpy_interpolation():
    # the compiled arc-length sampling against np.interp on the normalized arc length
    from musclewrap.conditions import polyline_at

    rng = np.random.default_rng(3)
    for k in (2, 3, 7):
        P = np.cumsum(rng.normal(size=(k, 3)), axis=0)
        P = np.vstack([P[:1], P[:1], P])  # a repeated point, dropped by the check
        Q = check_lines({"a": P})["a"]
        assert len(Q) == k
        s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(Q, axis=0), axis=1))])
        s /= s[-1]
        t = np.concatenate([[-0.1, 0.0, 1.0, 1.2], rng.random(50), s])
        ref = np.column_stack([np.interp(t, s, Q[:, j]) for j in range(3)])
        got = polyline_at(Q, t)
        assert np.abs(got - ref).max() <= 1e-13 * np.abs(Q).max()
        assert np.array_equal(got[[1, 2]], Q[[0, -1]])


def test_window_means_against_quadrature_rigid_motions_and_ends():
    """A sample's window mean equals the integral of the path over its window (fine
    trapezoids); a rigid motion of the path moves it rigidly; a width 0 is the point."""
    from scipy.spatial.transform import Rotation

    from musclewrap.conditions import polyline_at, window_mean

    rng = np.random.default_rng(5)
    P = np.cumsum(rng.normal(size=(6, 3)), axis=0)
    t = rng.uniform(0.1, 0.9, 20)
    w = rng.uniform(0.0, 0.1, 20)
    got = window_mean(P, t, w)
    for ti, wi, g in zip(t, w, got, strict=True):
        u = np.linspace(ti - wi, ti + wi, 20001)
        ref = np.trapezoid(polyline_at(P, u), u, axis=0) / (2 * wi)
        assert np.abs(g - ref).max() < 1e-7
    assert np.abs(window_mean(P, t, np.zeros(20)) - polyline_at(P, t)).max() < 1e-13
    R, d = Rotation.random(random_state=5).as_matrix(), rng.normal(size=3)
    assert np.abs(window_mean(P @ R.T + d, t, w) - (got @ R.T + d)).max() < 1e-12
    # a straight path: the mean of a window is its centre's point
    S = np.array([[0.0, 0, 0], [0, 0, 3], [0, 0, 10]])
    assert np.allclose(window_mean(S, t, w), polyline_at(S, t), atol=1e-13)
    # the sampling narrows the windows to the ends: they stay the line's ends
    line = check_lines({"a": P})
    s = sample_lines(line, spacing=0.3, window=0.5)
    pts = s.evaluate(line)
    assert np.array_equal(pts[[0, -1]], P[[0, -1]])
    assert s.halfwidths[0].max() > 0 and np.all(s.halfwidths[0] <= s.params[0])


def test_a_path_point_sliding_past_a_sample_does_not_kink_its_way():
    """The psoas's stairs: a sample at a fixed arc length on a path whose corner slides
    past it turns its velocity at once (a kink through the poses); its window mean does
    not. Second differences along the slide: the point's jump against the mean's."""
    from musclewrap.conditions import polyline_at, window_mean

    t = np.array([0.5])
    pts, means = [], []
    for c in np.linspace(4.0, 6.0, 201):  # the corner slides along x past the sample
        P = np.array([[0.0, 0, 0], [c, 2.0, 0], [10.0, 0, 0]])
        pts.append(polyline_at(P, t)[0])
        means.append(window_mean(P, t, np.array([0.05]))[0])
    d2_point = np.abs(np.diff(np.array(pts), 2, axis=0)).max()
    d2_mean = np.abs(np.diff(np.array(means), 2, axis=0)).max()
    assert d2_point > 20 * d2_mean


def test_a_muscle_bound_with_windows_is_at_rest_at_rest_and_rigid_under_a_rigid_motion(
    small_muscle,
):
    """``line_window``: the current samples are the rest points at rest (the mesh stays),
    the rest points moved rigidly under a rigid motion, and no kink where the path's
    corner slides past a sample (second differences of the targets along the slide)."""
    from scipy.spatial.transform import Rotation

    rest = {"a": np.array([[0.0, 0, 0], [0, 3.0, 100], [0, 0, 200]])}
    d = small_muscle.bind(rest, line_window=1.0)
    plain = small_muscle.bind(rest, line_window=0.0)
    default = small_muscle.bind(rest)  # half a spacing either side: no stairs by default
    assert d.sampling.halfwidths is not None and plain.sampling.halfwidths is None
    assert default.sampling.halfwidths is not None
    assert np.array_equal(d.rest_samples, plain.rest_samples)
    assert np.abs(d._targets(rest, None)[1] - d.rest_samples).max() < 1e-12
    assert np.abs(d.deform(rest).V - small_muscle.V).max() < 1e-9
    R, t = Rotation.from_rotvec([0.2, -0.1, 0.3]).as_matrix(), np.array([5.0, -2, 7])
    moved = {"a": rest["a"] @ R.T + t}
    got = d._targets(moved, None)[1]
    assert np.abs(got - (d.rest_samples @ R.T + t)).max() < 1e-9
    # the corner slides along z past the samples
    kinks = []
    for b in (plain, d, default):
        s = [b._targets({"a": np.array([[0.0, 0, 0], [0, 8, c], [0, 0, 200]])}, None)[1]
             for c in np.linspace(95.0, 105.0, 201)]  # fmt: skip
        kinks.append(np.abs(np.diff(np.array(s), 2, axis=0)).max())
    assert kinks[0] > 10 * kinks[1] and kinks[0] > 10 * kinks[2]
    with pytest.raises(ValueError, match="line_window must be 0 or positive"):
        small_muscle.bind(rest, line_window=-1.0)


def test_path_rotations_in_windows_are_rigid_and_smooth():
    """Windowed path rotations: a rigid motion's rotation everywhere; across a joint they
    turn no faster than the unwindowed ones and never step."""
    from scipy.spatial.transform import Rotation

    from musclewrap.conditions import path_rotations

    t = np.linspace(0.0, 1.0, 41)
    h = np.minimum(np.minimum(np.full(41, 0.04), t), 1 - t)
    Q = Rotation.random(random_state=4).as_matrix()
    bent = np.cumsum(np.random.default_rng(4).normal(size=(7, 3)), axis=0)
    got = path_rotations({"b": bent}, {"b": np.repeat(Q[None], 7, 0)}, ("b",), (t,), (h,))
    assert np.abs(got - Q).max() < 1e-12
    P = np.array([[0.0, 0, 0], [0, 0, 10], [0, 0, 20], [0, 0, 30], [0, 0, 40]])
    R = Rotation.from_rotvec([0.0, np.radians(80.0), 0.0]).as_matrix()
    rots = np.array([np.eye(3), np.eye(3), R, R, R])
    got = path_rotations({"a": P}, {"a": rots}, ("a",), (t,), (h,))
    assert np.abs(got[t <= 0.2] - np.eye(3)).max() < 1e-12
    assert np.abs(got[t >= 0.55] - R).max() < 1e-12
    assert _angle(np.einsum("kab,kcb->kac", got[1:], got[:-1])).max() < 80.0 / 9


@pytest.mark.parametrize("seed", range(4))
def test_sample_rotations_are_a_rigid_motions_rotation_whatever_the_reference(seed):
    """Under a rigid motion every sample's rotation is the motion's: a straight skeleton
    with a reference point beside it, and a bent one without a reference."""
    from scipy.spatial.transform import Rotation

    from musclewrap.conditions import sample_rotations

    rng = np.random.default_rng(seed)
    R = Rotation.random(random_state=seed).as_matrix()
    t = rng.normal(size=3) * 10
    bent = np.cumsum(rng.normal(size=(20, 3)), axis=0)
    two = np.repeat([0, 1], 10)
    straight = np.c_[np.zeros(20), np.zeros(20), np.linspace(0.0, 100.0, 20)]
    cases = [
        (straight, np.zeros(20, dtype=int), np.array([30.0, 5.0, 50.0])),
        (bent, two, None),
    ]
    for S, line, ref in cases:
        kw = {} if ref is None else {"reference_rest": ref, "reference_current": R @ ref + t}
        got = sample_rotations(S, S @ R.T + t, line, **kw)
        assert np.abs(got - R).max() < 1e-9


def _angle(R):
    return np.degrees(np.arccos(np.clip((np.trace(R, axis1=-2, axis2=-1) - 1) / 2, -1, 1)))


def test_path_rotations_follow_each_points_body_and_slerp_across_a_joint():
    """Samples on a part of the path fixed in one body turn with it; on the segment that
    crosses the joint they turn gradually (half way: half the angle, about the same axis);
    the same rotation for every point gives that rotation everywhere."""
    from scipy.spatial.transform import Rotation

    from musclewrap.conditions import path_rotations

    P = np.array([[0.0, 0, 0], [0, 0, 10], [0, 0, 20], [0, 0, 30], [0, 0, 40]])
    R = Rotation.from_rotvec([0.0, np.radians(80.0), 0.0]).as_matrix()
    I3 = np.eye(3)
    rots = np.array([I3, I3, R, R, R])  # points 0-1 on one body, 2-4 on the other
    t = np.linspace(0.0, 1.0, 41)
    got = path_rotations({"a": P}, {"a": rots}, ("a",), (t,))
    assert np.abs(got[t <= 0.25] - I3).max() < 1e-12
    assert np.abs(got[t >= 0.5] - R).max() < 1e-12
    half = got[np.argmin(np.abs(t - 0.375))]
    assert abs(_angle(half) - 40.0) < 1e-9
    assert np.allclose(Rotation.from_matrix(half).as_rotvec()[[0, 2]], 0.0)
    # continuous along the path: neighbouring samples differ by a fraction of the turn
    assert _angle(np.einsum("kab,kcb->kac", got[1:], got[:-1])).max() < 80.0 / 9
    # a rigid motion: one rotation for all points, whatever the points
    Q = Rotation.random(random_state=3).as_matrix()
    bent = np.cumsum(np.random.default_rng(3).normal(size=(7, 3)), axis=0)
    got = path_rotations({"b": bent}, {"b": np.repeat(Q[None], 7, 0)}, ("b",), (t,))
    assert np.abs(got - Q).max() < 1e-12
    # a repeated point is dropped with its rotation, as check_lines drops it
    Pd = np.insert(P, 2, P[1], axis=0)
    rd = np.insert(rots, 2, rots[1], axis=0)
    again = path_rotations({"a": Pd}, {"a": rd}, ("a",), (t,))
    assert np.abs(again - path_rotations({"a": P}, {"a": rots}, ("a",), (t,))).max() < 1e-15


def test_path_rotations_from_keys_change_continuously_as_a_key_reaches_another():
    """Rotation keys (every point of a path's set, `PathLines` ``keys``): a sample between
    two keys slerps between them; a key moved onto the next one's parameter (a via point
    projected past the path's end) gives the limit of the field, not a jump; the points'
    parameters on the line are their arc lengths, a point off it its projection's."""
    from scipy.spatial.transform import Rotation

    from musclewrap.conditions import path_rotations, set_point_params

    P = np.array([[0.0, 0, 0], [0, 0, 10], [0, 0, 40]])
    I3 = np.eye(3)
    R = Rotation.from_rotvec([0.0, np.radians(60.0), 0.0]).as_matrix()
    t = np.linspace(0.0, 1.0, 41)
    rots = np.array([I3, I3, R])

    def field(t3):
        keys = {"a": (np.array([0.0, 0.25, t3, 1.0]), np.array([I3, I3, I3, R]))}
        return path_rotations({"a": P}, {"a": rots}, ("a",), (t,), None, keys)

    # between the keys at 0.25 and 0.75 (both I3) nothing turns; from 0.75 to 1, to R
    got = field(0.75)
    assert np.abs(got[t <= 0.75] - I3).max() < 1e-12
    assert abs(_angle(got[np.argmin(np.abs(t - 0.875))]) - 30.0) < 1e-9
    # the third key reaching the last: the field tends to I3 below 1, R at 1
    near, at = field(1.0 - 1e-9), field(1.0)
    assert np.abs(near[:-1] - at[:-1]).max() < 1e-6
    assert np.abs(at[:-1] - I3).max() < 1e-12 and np.abs(at[-1] - R).max() < 1e-12
    # the same keys in windows: continuous too
    h = np.minimum(np.minimum(np.full(41, 0.05), t), 1 - t)
    keys = lambda t3: {"a": (np.array([0.0, 0.25, t3, 1.0]), np.array([I3, I3, I3, R]))}  # noqa: E731
    w1 = path_rotations({"a": P}, {"a": rots}, ("a",), (t,), (h,), keys(1.0 - 1e-9))
    w2 = path_rotations({"a": P}, {"a": rots}, ("a",), (t,), (h,), keys(1.0))
    assert np.abs(w1 - w2).max() < 1e-6
    # parameters: the line's own points at their arc lengths, an off-line point projected
    X = np.array([[0.0, 0, 0], [0, 0, 10], [3.0, 0, 25], [0, 0, 40], [0, 5, 50]])
    got = set_point_params(P, X)
    assert got == pytest.approx([0.0, 0.25, 0.625, 1.0, 1.0], abs=1e-15)
    # made non-decreasing in the set's order
    assert set_point_params(P, X[[0, 2, 1, 3]]).tolist() == pytest.approx([0, 0.625, 0.625, 1])


def test_path_rotations_name_a_line_without_one_rotation_per_point():
    from musclewrap.conditions import path_rotations

    P = np.array([[0.0, 0, 0], [0, 0, 10], [0, 0, 20]])
    with pytest.raises(LineError, match="line 'a' needs one finite 3x3 rotation per point"):
        path_rotations({"a": P}, {"a": np.repeat(np.eye(3)[None], 2, 0)}, ("a",), (np.r_[0.0, 1],))
    with pytest.raises(LineError, match="line 'a'"):
        path_rotations({"a": P}, {}, ("a",), (np.r_[0.0, 1.0],))


def test_path_lines_turn_the_muscle_with_its_bodies(small_muscle):
    """A muscle whose lines carry their points' rotations: a rigid motion of lines and
    bodies moves it rigidly; PathLines survive pickling (workers) with their rotations."""
    import pickle

    from scipy.spatial.transform import Rotation

    from musclewrap.conditions import PathLines

    rest, _ = capsule_scenario("bend_short")
    d = small_muscle.bind(rest)
    R = Rotation.from_rotvec([0.3, -0.5, 0.2]).as_matrix()
    t = np.array([4.0, -2.0, 7.0])
    cur = PathLines(
        {k: np.asarray(v) @ R.T + t for k, v in rest.items()},
        {k: np.repeat(R[None], len(v), 0) for k, v in rest.items()},
    )
    cur = pickle.loads(pickle.dumps(cur))
    assert set(cur.rotations) == set(rest)
    r = d.deform(cur)
    assert r.converged, r.reason
    assert np.abs(r.V - (small_muscle.V @ R.T + t)).max() < 1e-6 * np.ptp(small_muscle.V)
