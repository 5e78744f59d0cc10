import numpy as np
import pytest

from musclewrap import Muscle
from musclewrap.constants import tol
from musclewrap.mesh import MeshError
from musclewrap.solver import cubic_root_near
from musclewrap.synthetic import CAPSULE_SCENARIOS, capsule, capsule_scenario


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


def test_attached_areas_ride_on_the_bodies_of_their_paths_ends(small_muscle):
    """``attached``: the end caps held to the line's first and last points.

    A rigid motion of lines and bodies moves the muscle rigidly, volume exact; bent at
    mid-length (the second half's body turned 30 degrees), the insertion's cap follows
    its body's rigid motion far closer than without, and the origin's stays put; a path
    that runs on past the mesh leaves that end free; across a tendon the cap pivots with
    the line's end segment, not with the body.
    """
    from scipy.spatial.transform import Rotation

    from musclewrap.conditions import PathLines
    from musclewrap.fibres import attachment_areas

    mu = small_muscle
    rest, bent = capsule_scenario("bend")
    origin, insertion = attachment_areas(mu.V, rest)
    d = mu.bind(rest, attached=(origin, insertion))
    plain = mu.bind(rest)
    assert d.S.shape[0] == plain.S.shape[0] + len(origin) + len(insertion)

    R = Rotation.from_rotvec([0.3, -0.5, 0.2]).as_matrix()
    t = np.array([4.0, -2.0, 7.0])
    moved = PathLines(
        {k: np.asarray(v) @ R.T + t for k, v in rest.items()},
        {k: np.repeat(R[None], len(v), 0) for k, v in rest.items()},
    )
    r = d.deform(moved)
    assert r.converged, r.reason
    assert np.abs(r.V - (mu.V @ R.T + t)).max() < 1e-6 * np.ptp(mu.V)
    assert abs(r.relative_volume_error) < 1e-9

    a = np.radians(30.0)
    turn = Rotation.from_rotvec([0.0, a, 0.0]).as_matrix()
    P = bent["axis"]
    lines = PathLines({"axis": P}, {"axis": np.stack([np.eye(3), np.eye(3), turn])})
    end_rest, end_now = rest["axis"][-1], P[-1]
    ride = (mu.V[insertion] - end_rest) @ turn.T + end_now

    def off(res):  # noqa: ANN001, ANN202
        return (
            float(np.linalg.norm(res.V[insertion] - ride, axis=1).mean()),
            float(np.linalg.norm(res.V[origin] - mu.V[origin], axis=1).mean()),
        )

    held, free = d.deform(lines), plain.deform(lines)
    assert held.converged and free.converged
    assert abs(held.relative_volume_error) < 1e-9
    (ins_held, org_held), (ins_free, org_free) = off(held), off(free)
    assert ins_held < 0.5 * ins_free, (ins_held, ins_free)
    assert org_held < org_free
    # plain lines: the end samples' own rotations stand in for the bodies'
    flat = d.deform({"axis": P})
    assert flat.converged and off(flat)[0] < ins_free

    assert d.attached_held == (len(origin), len(insertion))
    # a tendon between the line's first point and the area (the rectus femoris below its
    # origin): the point's body turns 30 degrees but the line's first segment does not;
    # the area pivots with the segment, not with the body, and twists with the body
    # about the segment
    tendon = {"axis": np.array([[0.0, 0.0, -20.0], [0.0, 0.0, 200.0]])}
    d2 = mu.bind(tendon, attached=(origin, insertion))
    assert d2.attached_held == (len(origin), len(insertion))
    swing = Rotation.from_rotvec([0.0, np.radians(30.0), 0.0]).as_matrix()
    twist = Rotation.from_rotvec([0.0, 0.0, np.radians(30.0)]).as_matrix()
    for R, expect in ((swing, np.eye(3)), (twist, twist)):
        r = d2.deform(PathLines(tendon, {"axis": np.stack([R, np.eye(3)])}))
        assert r.converged, r.reason
        p0 = tendon["axis"][0]
        want = (mu.V[origin] - p0) @ expect.T + p0
        got = float(np.linalg.norm(r.V[origin] - want, axis=1).mean())
        body = (mu.V[origin] - p0) @ R.T + p0
        assert got < 1.0, got
        if R is swing:  # the body's rotation alone would have swung it 10 mm and more
            assert float(np.linalg.norm(body - want, axis=1).mean()) > 10.0
    # a path that runs on 200 past the muscle's end (a tendon the mesh does not hold): the
    # insertion's area is not on that bone, and is left free
    tendon = {"axis": np.array([[0.0, 0.0, 0.0], [0.0, 0.0, 400.0]])}
    long = mu.bind(tendon, attached=(origin, insertion))
    assert long.unbound and long.attached_held == (len(origin), 0)
    assert long.S.shape[0] == mu.bind(tendon).S.shape[0] + len(origin)
    with pytest.raises(ValueError, match="attached vertices must index the"):
        mu.bind(rest, attached=(origin, np.array([len(mu.V)])))


def test_the_deepest_vertex_per_cage_vertex_compiled_as_sorted():
    """`_deepest_per_group` with one a group (compiled, no sort) picks what the sort picks: the
    smallest gap per group, the earlier row on a tie, a NaN only where nothing else is, in the
    order of the groups."""
    from musclewrap.solver._step import _deepest_per_group

    rng = np.random.default_rng(3)
    for n, groups in ((1, 1), (50, 7), (2000, 300)):
        gap = np.round(rng.normal(size=n), 1)  # ties
        gap[rng.integers(0, n, size=n // 10)] = np.nan
        group = rng.integers(0, groups, size=n)
        order = np.lexsort((gap, group))
        start = np.ones(n, dtype=bool)
        start[1:] = group[order[1:]] != group[order[:-1]]
        assert np.array_equal(_deepest_per_group(gap, group, 1), order[start])
    assert len(_deepest_per_group(np.zeros(0), np.zeros(0, dtype=np.int64), 1)) == 0


def test_the_cage_step_forms_the_gram_matrix_over_its_active_set_only():
    """`cage_push` takes the active set's block of the conditions' Gram matrix as it needs it:
    the same step as the whole matrix formed once (the scale of its softness the mean of the
    whole diagonal), on random conditions, with joins and leaves."""
    from musclewrap.constants import defaults
    from musclewrap.solver._step import _deepest_per_group, cage_push

    rng = np.random.default_rng(5)
    n, m = 400, 40
    W = rng.random((n, m))
    W /= W.sum(axis=1, keepdims=True)
    M = rng.normal(size=(m, m))
    Hinv = np.linalg.inv(M @ M.T + m * np.eye(m))
    g = rng.normal(size=(m, 3))
    Hg = Hinv @ g
    group = np.argmax(W, axis=1)
    idx = np.arange(n)
    gap = rng.normal(0.2, 0.3, size=n)
    N = rng.normal(size=(n, 3))
    N /= np.linalg.norm(N, axis=1, keepdims=True)
    slack = 0.01

    def whole() -> np.ndarray:  # the step as it was: the Gram matrix of every candidate
        pool = _deepest_per_group(gap, group[idx], 1)
        Wr, r, Nn = W[idx[pool]], slack - gap[pool], N[pool]
        Y = Wr @ Hinv
        G = (Y @ Wr.T) * (Nn @ Nn.T)
        c = np.einsum("ij,ij->i", Nn, Wr @ Hg)
        soft = defaults.contact_softness * float(np.mean(np.diag(G)))
        active, dx = r > 0, np.zeros((m, 3))
        for _ in range(4):
            a = np.flatnonzero(active)
            k = len(a)
            A = np.empty((k + 1, k + 1))
            A[:k, :k] = G[np.ix_(a, a)] + soft * np.eye(k)
            A[:k, k] = A[k, :k] = c[a]
            A[k, k] = float(np.sum(g * Hg))
            sol = np.linalg.solve(A, np.append(r[a], 0.0))
            dx = Y[a].T @ (sol[:k, None] * Nn[a]) + sol[k] * Hg
            lin = np.einsum("ij,ij->i", Nn, Wr @ dx)
            join, leave = ~active & (lin < r - slack), np.zeros_like(active)
            leave[a] = sol[:k] < 0
            if not join.any() and not leave.any():
                break
            active = (active | join) & ~leave
        return dx

    got = cage_push(W, Hinv, g, Hg, idx, gap, N, group, slack=slack)
    ref = whole()
    assert np.abs(ref).max() > 0
    assert np.allclose(got, ref, rtol=1e-10, atol=1e-12 * np.abs(ref).max())
