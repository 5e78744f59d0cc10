import numpy as np
import pytest

from musclewrap import Muscle
from musclewrap.cage import build_cage, cage_self_intersections
from musclewrap.conditions import LineError, check_lines, cotangent_laplacian, sample_lines
from musclewrap.constants import tol
from musclewrap.coordinates import mean_value_coordinates
from musclewrap.mesh import MeshError
from musclewrap.solver import cubic_root_near
from musclewrap.synthetic import CAPSULE_SCENARIOS, capsule, capsule_scenario

TET_V = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]])
TET_F = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])


def cube():
    V = np.array([[x, y, z] for x in (0.0, 1) for y in (0.0, 1) for z in (0.0, 1)])
    F = np.array(
        [
            [0, 1, 3],
            [0, 3, 2],
            [4, 6, 7],
            [4, 7, 5],
            [0, 4, 5],
            [0, 5, 1],
            [2, 3, 7],
            [2, 7, 6],
            [0, 2, 6],
            [0, 6, 4],
            [1, 5, 7],
            [1, 7, 3],
        ]
    )
    return V, F


def test_mvc_octahedron_centre_is_uniform():
    # symmetric cage and triangulation: every vertex weighs the same at the centre
    V = np.array([[1.0, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]])
    F = np.array(
        [[0, 2, 4], [2, 1, 4], [1, 3, 4], [3, 0, 4], [2, 0, 5], [1, 2, 5], [3, 1, 5], [0, 3, 5]]
    )
    W = mean_value_coordinates([[0.0, 0.0, 0.0]], V, F)
    assert np.allclose(W, 1 / 6, atol=1e-14)


def test_mvc_identities_random_points():
    V, F = cube()
    P = np.random.default_rng(0).uniform(0.05, 0.95, size=(500, 3))
    W = mean_value_coordinates(P, V, F)
    assert np.allclose(W.sum(axis=1), 1.0, atol=1e-13)
    assert np.abs(W @ V - P).max() < 1e-10
    assert (W > 0).all(), "MVC are positive inside a convex cage"


def test_mvc_special_cases():
    V, F = cube()
    P = np.array([V[3], V[F[2]].mean(axis=0), [0.5, 0.5, 0.0]])
    W = mean_value_coordinates(P, V, F)
    assert W[0, 3] == 1.0 and W[0].sum() == 1.0
    assert np.abs(W @ V - P).max() < 1e-12


def test_mvc_validates_input():
    V, F = cube()
    with pytest.raises(ValueError, match="shape"):
        mean_value_coordinates(np.zeros((3, 2)), V, F)
    with pytest.raises(ValueError, match="indices"):
        mean_value_coordinates(np.zeros((1, 3)), V, F + 10)


@pytest.mark.parametrize("k", [1, 3, 6, 7, 13])
def test_rows_dot_is_w_at_x(k):
    from musclewrap.coordinates import rows_dot

    rng = np.random.default_rng(k)
    W, X = rng.random((257, 300)), rng.normal(size=(300, k))
    assert np.allclose(rows_dot(W, X), W @ X, rtol=1e-12, atol=1e-12)
    with pytest.raises(ValueError, match="X must be \\(300, k\\)"):
        rows_dot(W, X[:299])


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


def test_cubic_root():
    assert cubic_root_near(np.array([1.0, -3.0, 0.0, 1.0]), 0.0, 0.3) == pytest.approx(
        0.34729635533386, rel=1e-12
    )
    # Newton stalls at the guess (zero slope): all roots, two of them complex
    t = cubic_root_near(np.array([3.0, -3.0, 0.0, 1.0]), 0.0, 1.0)
    assert t**3 - 3 * t + 3 == pytest.approx(0.0, abs=1e-12) and t < -2
    # a quadratic (both roots equally near the guess), and a line
    assert abs(cubic_root_near(np.array([-4.0, 0.0, 1.0, 0.0]), 0.0, 0.0)) == pytest.approx(2.0)
    assert cubic_root_near(np.array([-4.0, 2.0, 0.0, 0.0]), 0.0, 5.0) == pytest.approx(2.0)
    assert np.isnan(cubic_root_near(np.array([1.0, 0.0, 0.0, 0.0]), 0.0, 0.0))
    assert np.isnan(cubic_root_near(np.array([1.0, np.inf, 0.0, 0.0]), 0.0, 0.0))


def test_real_roots_of_a_cubic_with_roots_orders_of_magnitude_apart():
    # closed forms (and a companion matrix) lose the small roots of such a cubic; the
    # bracketed search keeps all three to rounding
    from musclewrap.mesh._cubic import _real_roots

    roots = np.array([-2e-4, 1e-4, 1e6])
    p = np.poly(roots)[::-1]  # increasing degree
    assert np.sort(_real_roots(*p)) == pytest.approx(roots, rel=1e-10)
    # a double root where the cubic vanishes exactly: (t - 1)^2 (t - 3)
    assert np.sort(_real_roots(-3.0, 7.0, -5.0, 1.0)) == pytest.approx(
        [1.0, 3.0, np.nan], nan_ok=True
    )
    # one real root and a complex pair: t^3 + t + 10 = (t + 2)(t^2 - 2t + 5)
    r = _real_roots(10.0, 1.0, 0.0, 1.0)
    assert r[0] == pytest.approx(-2.0, rel=1e-14) and np.isnan(r[1:]).all()


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


@pytest.fixture(scope="module")
def small_muscle():
    V, F = capsule(n_around=32, cap_rings=8, segments=30)
    return Muscle.from_mesh(V, F, cage_size=200)


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


def test_a_muscle_too_large_for_the_memory_is_refused_before_preparation(monkeypatch):
    import musclewrap.mesh._checks as sm

    V, F = capsule(n_around=32, cap_rings=8, segments=30)
    monkeypatch.setattr(sm, "available_memory", lambda: 2**20)  # 1 MiB left
    with pytest.raises(
        MeshError,
        match="big.stl: 2,880 faces need about 8 MiB .* and 1 MiB are available: decimate",
    ):
        Muscle.from_mesh(V, F, source="big.stl")
    monkeypatch.setattr(sm, "available_memory", lambda: None)  # unknown: no refusal
    sm.check_memory(10**9, "huge.stl")
    monkeypatch.undo()
    assert sm.available_memory() > 2**20  # this machine's /proc/meminfo is read


def test_line_that_folds_back_is_followed(small_muscle):
    d = small_muscle.bind({"a": [[0, 0, 5], [0, 0, 195]]})
    r = d.deform({"a": [[0, 0, 5], [0, 0, 150], [0, 10, 100]]})  # a U-turn at 150
    assert r.converged and abs(r.relative_volume_error) <= 1e-9
    assert r.skeleton_fit_mean < 1.0 and np.isfinite(r.V).all()


@pytest.mark.parametrize("method", ["sqp", "exact", "paper"])
def test_overflowing_pose_is_an_unconverged_result_not_an_exception(small_muscle, method):
    d = small_muscle.bind({"a": [[0, 0, 5], [0, 0, 195]]})
    for far in ([0, 1e150, 1e154], [0, 0, 1e200]):
        r = d.deform({"a": [[0, 0, 5], far]}, method=method)
        assert not r.converged and r.reason.startswith("numerically singular")
        assert np.isnan(r.V).all() and np.isnan(r.relative_volume_error)
    # the deformer is unharmed: the next pose solves as before
    r = d.deform({"a": [[0, 0, 5], [10, 0, 190]]}, method=method)
    assert r.converged and abs(r.relative_volume_error) <= 1e-9


def test_cage_encloses_and_is_clean(small_muscle):
    c = small_muscle.cage
    assert c.min_winding > 0.99 and c.min_distance > 0
    assert cage_self_intersections(c.C, c.CF) == 0
    # uniform remesh: well-shaped triangles spread along the whole capsule, not slivers
    # joining the two caps (what quadric decimation gives on a cylinder)
    assert c.method == "uniform" and c.min_angle_deg > 15.0
    z = c.C[:, 2]
    assert np.sum((z > 40) & (z < 160)) > 0.3 * len(z)


def test_cage_too_small_rejected():
    V, F = capsule(n_around=12, cap_rings=4, segments=5)
    with pytest.raises(ValueError, match="at least 20"):
        build_cage(V, F, size=5)


@pytest.mark.parametrize("name", CAPSULE_SCENARIOS)
@pytest.mark.parametrize("method", ["sqp", "exact"])
def test_capsule_scenarios_volume_exact(small_muscle, name, method):
    rest, cur = capsule_scenario(name)
    r = small_muscle.bind(rest).deform(cur, method=method)
    assert r.converged, r.reason
    assert abs(r.relative_volume_error) <= 1e-9


@pytest.mark.parametrize("name", CAPSULE_SCENARIOS)
def test_capsule_iterations_target(small_muscle, name):
    rest, cur = capsule_scenario(name)
    assert small_muscle.bind(rest).deform(cur).iterations <= 5


@pytest.mark.parametrize("name", ["bend", "bend_short", "bend_long"])
def test_capsule_bends_follow_line_without_spikes(small_muscle, name):
    rest, cur = capsule_scenario(name)
    r = small_muscle.bind(rest).deform(cur)
    assert r.skeleton_fit_mean <= 1.0
    assert small_muscle.shape_change(r.V).max() <= 0.5


def test_shape_change_measure(small_muscle):
    from scipy.spatial.transform import Rotation

    V = small_muscle.V
    R = Rotation.from_rotvec([0.1, 0.2, 0.3]).as_matrix()
    assert small_muscle.shape_change(V @ R.T + 5.0).max() < 1e-9
    bumped = V.copy()
    bumped[7] += 3.0 * (V[7] - V.mean(axis=0)) / np.linalg.norm(V[7] - V.mean(axis=0))
    change = small_muscle.shape_change(bumped)
    assert change.argmax() == 7 and change.max() > 0.5
    with pytest.raises(ValueError, match="shape"):
        small_muscle.shape_change(V[:-1])


def test_sqp_matches_exact_energy(small_muscle):
    rest, cur = capsule_scenario("bend_short")
    d = small_muscle.bind(rest)
    a, b = d.deform(cur), d.deform(cur, method="exact")
    assert a.energy == pytest.approx(b.energy, rel=1e-5)
    assert d.stationarity(b, cur) < tol.direction


def test_paper_method_converges(small_muscle):
    rest, cur = capsule_scenario("short")
    r = small_muscle.bind(rest).deform(cur, method="paper")
    assert abs(r.relative_volume_error) <= 1e-9 and len(r.history) == r.iterations


def test_rigid_motion_gives_rigid_mesh(small_muscle):
    from scipy.spatial.transform import Rotation

    R = Rotation.from_rotvec([0.3, -0.5, 0.7]).as_matrix()
    t = np.array([10.0, -4.0, 25.0])
    rest = {
        "a": np.array([[0.0, 0, 0], [2, 1, 100], [0, 3, 200]]),
        "b": np.array([[5.0, 0, 20], [5, 0, 180]]),
    }
    cur = {k: v @ R.T + t for k, v in rest.items()}
    ref = np.array([40.0, 10.0, 90.0])
    d = small_muscle.bind(rest, reference_point=ref)
    r = d.deform(cur, reference_point=R @ ref + t)
    dev = np.abs(r.V - (small_muscle.V @ R.T + t)).max()
    assert dev <= 1e-6 * 200, dev
    assert abs(r.relative_volume_error) <= 1e-9


def test_save_load_roundtrip_and_corruption(small_muscle, tmp_path):
    p = small_muscle.save(tmp_path / "m.npz")
    m2 = Muscle.load(p)
    assert np.array_equal(m2.W, small_muscle.W)
    raw = bytearray(p.read_bytes())
    raw[len(raw) // 2] ^= 0xFF
    bad = tmp_path / "bad.npz"
    bad.write_bytes(bytes(raw))
    with pytest.raises(ValueError, match="bad.npz"):
        Muscle.load(bad)


def test_input_id_follows_a_soup_and_survives_save_load(tmp_path):
    # an STL-like soup (every triangle with its own vertices): each fine vertex knows the
    # first input vertex it came from, the map survives save/load, a clean mesh is identity
    V, F = capsule(n_around=16, cap_rings=4, segments=8)
    soup_V, soup_F = V[F].reshape(-1, 3), np.arange(3 * len(F)).reshape(-1, 3)
    m = Muscle.from_mesh(soup_V, soup_F, cage_size=100)
    assert len(m.V) == len(V) and m.input_id.shape == (len(V),)
    assert np.array_equal(soup_V[m.input_id], m.V)
    assert np.all(np.diff(m.input_id) > 0)  # first appearance
    m2 = Muscle.load(m.save(tmp_path / "soup.npz"))
    assert np.array_equal(m2.input_id, m.input_id)
    clean = Muscle.from_mesh(V, F, cage_size=100)
    assert np.array_equal(clean.input_id, np.arange(len(V)))


def test_quaternion_roundtrip_and_sign():
    from scipy.spatial.transform import Rotation

    from musclewrap.conditions import matrix_to_quaternion, quaternion_to_matrix

    R = Rotation.random(50, random_state=3).as_matrix()
    q = matrix_to_quaternion(R)
    assert np.allclose(np.linalg.norm(q, axis=1), 1.0)
    assert np.allclose(quaternion_to_matrix(q), R, atol=1e-12)
    assert np.allclose(quaternion_to_matrix(-3.0 * q), R, atol=1e-12)


def test_verify_cage_reports_unenclosed_vertices(small_muscle):
    from musclewrap.cage import verify_cage

    c = small_muscle.cage
    assert verify_cage(small_muscle.V, c.C, c.CF, margin=0.0) == []
    shrunk = c.C.mean(axis=0) + 0.5 * (c.C - c.C.mean(axis=0))
    problems = verify_cage(small_muscle.V, shrunk, c.CF, margin=0.0)
    assert any("outside the cage" in p for p in problems)


def test_quadric_coarsening_builds_valid_cage():
    V, F = capsule(n_around=32, cap_rings=8, segments=30)
    c = build_cage(V, F, size=200, coarsening="quadric")
    assert c.method == "quadric" and c.min_winding > 0.99
    with pytest.raises(ValueError, match="coarsening"):
        build_cage(V, F, coarsening="other")


def test_volume_hessian_reduced_matches_finite_differences():
    from musclewrap.mesh import volume_gradient, volume_hessian_reduced

    V, F = capsule(n_around=12, cap_rings=4, segments=5)
    rng = np.random.default_rng(0)
    W = rng.random((len(V), 7))
    W /= W.sum(axis=1, keepdims=True)
    x = np.linalg.lstsq(W, V, rcond=None)[0]
    K = volume_hessian_reduced(W @ x, F, W)
    assert np.array_equal(K, K.T)
    w, e = rng.normal(size=x.shape), 1e-5
    fd = (W.T @ volume_gradient(W @ (x + e * w), F) - W.T @ volume_gradient(W @ (x - e * w), F)) / (
        2 * e
    )
    assert np.allclose(
        (K @ w.ravel()).reshape(x.shape), fd, rtol=1e-7, atol=1e-9 * np.abs(fd).max()
    )


def test_newton_fallback_reaches_the_plain_fixed_point(small_muscle):
    from musclewrap.mesh import volume_cubic, volume_gradient

    rest, cur = capsule_scenario("bend_short")
    d = small_muscle.bind(rest)
    mu = small_muscle
    _, s_cur, d_L = d._targets(cur, None)
    x_ls = d._solve(d._rhs(d_L, s_cur))
    c = x_ls.mean(axis=0)
    P_ls = mu.proxy_W @ (x_ls - c)

    def plain(x, lam):
        u = d._solve(mu.proxy_W_T @ volume_gradient(mu.proxy_W @ (x - c), mu.proxy_F))
        P_u = mu.proxy_W @ u
        lam = cubic_root_near(volume_cubic(P_ls, -P_u, mu.proxy_F), mu.proxy_volume_rest, lam)
        return x_ls - lam * u, lam

    x1, lam = plain(x_ls, 0.0)  # one plain step: on the volume, far from stationary
    x_star = x1
    for _ in range(60):  # the plain fixed point converges on this capsule
        x_star, lam = plain(x_star, lam)
    x_n, lam_n, its, ok = d._newton(x1, x_ls, c, 40)
    assert ok and its <= 12
    scale = np.abs(x_star - x_ls).max()
    assert np.abs(x_n - x_star).max() <= 1e-6 * scale
    assert lam_n == pytest.approx(lam, rel=1e-6)


@pytest.mark.parametrize("scenario", ["bend", "bend_short", "rot"])
def test_single_precision_proxy_products_match_double(small_muscle, scenario, double_proxy):
    # the default solve steers its direction with float32 copies of the proxy's
    # matrices; the same iteration in float64 lands on the same mesh to ~1e-9 of its size
    mu = small_muscle
    rest, cur = capsule_scenario(scenario)
    d = mu.bind(rest)
    r32 = d.deform(cur)
    r64 = double_proxy(d).deform(cur)
    assert r32.converged and r64.converged
    size = np.linalg.norm(mu.V.max(0) - mu.V.min(0))
    assert np.abs(r32.V - r64.V).max() <= 1e-8 * size
    assert r32.iterations == r64.iterations


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


def test_newton_path_through_deform_reaches_the_same_mesh(small_muscle, monkeypatch):
    # two plain iterations only: the default solve goes on with Newton's method from the
    # plain iterate of least energy and must land where the plain iteration converges
    import dataclasses

    import musclewrap.solver._deformer as solver

    rest, cur = capsule_scenario("bend_short")
    d = small_muscle.bind(rest)
    plain = d.deform(cur)
    monkeypatch.setattr(
        solver, "defaults", dataclasses.replace(solver.defaults, plain_iterations=2)
    )
    newton = d.deform(cur)
    assert plain.converged and newton.converged, newton.reason
    assert newton.iterations > 3  # two plain steps, Newton's, and the fine pass
    assert abs(newton.relative_volume_error) <= 1e-12
    size = np.linalg.norm(np.ptp(small_muscle.V, axis=0))
    assert np.abs(newton.V - plain.V).max() <= 1e-6 * size  # 1.9e-7 measured


def test_an_unsettled_direction_falls_back_to_the_exact_iteration(small_muscle, monkeypatch):
    """Where the proxy's direction does not settle, the default solve goes on with the
    exact iteration from the start, lands where the default solve does, and says so."""
    rest, cur = capsule_scenario("bend_short")
    d = small_muscle.bind(rest)
    plain = d.deform(cur)
    proxy = type(d)._solve_proxy

    def unsettled(self, x_ls, max_iterations):  # noqa: ANN001, ANN202
        x, V, its, _, _ = proxy(self, x_ls, 2)
        return x, V, its, False, "direction not stationary after 2 iterations"

    monkeypatch.setattr(type(d), "_solve_proxy", unsettled)
    r = d.deform(cur)
    assert r.converged, r.reason
    assert r.reason == (
        "converged by the exact iteration (direction not stationary after 2 iterations "
        "on the proxy)"
    )
    assert abs(r.relative_volume_error) <= 1e-12
    # near the default solve's mesh (the fine gradient's fixed point is not the proxy's:
    # 0.011 mm apart on this 208 mm capsule, 5e-5 of its size)
    assert np.abs(r.V - plain.V).max() <= 2e-4 * np.linalg.norm(np.ptp(small_muscle.V, axis=0))


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
