import numpy as np
import pytest

from musclewrap.contact import Obstacle
from musclewrap.mesh import mean_edge_length
from musclewrap.synthetic import capsule


# ------------------------------------------------------------------ obstacles
def test_obstacle_matches_a_sphere():
    V, F = capsule(radius=10.0, length=0.0, n_around=96, cap_rings=48, segments=1)
    probe = Obstacle(V, F)
    rng = np.random.default_rng(1)
    d = rng.normal(size=(400, 3))
    d /= np.linalg.norm(d, axis=1)[:, None]
    r = rng.uniform(0.0, 20.0, 400)
    centre = V.mean(axis=0)  # the capsule with no cylinder is a sphere about its middle
    Q = centre + d * r[:, None]
    n, depth = probe.measure(Q)
    # the polygonal sphere's inscribed radius is within 0.02 of 10
    inside = r < 10.0 - 0.03
    outside = r > 10.0 + 0.03
    amb = ~(inside | outside)
    assert inside.sum() <= n <= inside.sum() + amb.sum()
    assert depth == pytest.approx(10.0 - r[inside].min(), abs=0.05)
    assert probe.measure(Q[outside]) == (0, 0.0)


def test_a_coarse_bones_grid_is_as_fine_as_its_budget_allows():
    # A model's bone has triangles of 20-70 mm (gait2392's pelvis): a grid of half an edge
    # put the contact's interpolated distance 2.6 mm off the exact one at a muscle deep in
    # it. A cube of twelve triangles, 60 mm a side: the grid's distance near its surface
    # and inside (where the exact one creases along the diagonal planes) within 0.5 mm.
    import trimesh

    box = trimesh.creation.box(extents=[60.0, 60.0, 60.0])
    probe = Obstacle(np.asarray(box.vertices), np.asarray(box.faces))
    assert probe.h < 1.0
    rng = np.random.default_rng(3)
    Q = rng.uniform(-36.0, 36.0, size=(4000, 3))
    idx, phi, _ = probe.interpolate(Q, 6.0)
    exact = probe.signed(Q[idx])[0]
    assert len(idx) > 1000 and (exact < 0).sum() > 500
    assert np.abs(phi - exact).max() < 0.5


def _brute_force(probe, Q):
    """Closest-point query with the pseudo-normal side on every point."""
    phi = probe._signed(Q)[0]
    inside = phi < 0
    return int(inside.sum()), float(-phi[inside].min()) if inside.any() else 0.0


def test_obstacle_query_sides_directions_and_bounds():
    # the compiled pseudo-normal side against winding numbers; the outward directions and
    # closest points against each other; the lower bounds a query fills never above the
    # exact distance
    import igl

    V, F = capsule(radius=8.0, length=40.0, n_around=40, cap_rings=12, segments=16)
    rng = np.random.default_rng(7)
    # on the surface's vertices, edges and faces, and off it on both sides
    on = V[rng.integers(0, len(V), 300)]
    Q = np.vstack([on + rng.normal(scale=s, size=on.shape) for s in (1e-3, 0.1, 1.0, 4.0)])
    probe = Obstacle(V, F, max_grid_nodes=20_000)
    lower = np.empty(len(Q))
    idx, phi, C, N = probe.query(Q, np.inf, lower)
    assert np.array_equal(idx, np.arange(len(Q)))
    inside = igl.fast_winding_number(V, F, Q) > 0.5
    clear = np.abs(phi) > 1e-6
    assert np.array_equal((phi < 0)[clear], inside[clear])
    assert np.allclose(np.linalg.norm(N, axis=1), 1.0)
    assert np.allclose(C + phi[:, None] * N, Q, atol=1e-9)
    assert np.array_equal(lower, phi)  # every point took the exact query
    lower = np.empty(len(Q))
    idx, phi, _, _ = probe.query(Q, 0.5, lower)
    exact = probe._signed(Q)[0]
    assert np.all(lower <= exact) and np.array_equal(idx, np.flatnonzero(exact < 0.5))


def test_vertices_near_match_brute_force():
    V, F = capsule(radius=8.0, length=40.0, n_around=40, cap_rings=12, segments=16)
    probe = Obstacle(V, F, max_grid_nodes=20_000)
    k = probe.convexity
    # a cylinder of radius 8 bends about 1/8 across, not along; its caps about as much
    assert 0.1 < np.median(k) < 0.2
    rng = np.random.default_rng(5)
    Q = V[rng.integers(0, len(V), 50)] + rng.normal(scale=2.0, size=(50, 3))
    for radius, sharp in ((1.5, 0.1), (3.0, 0.0), (0.5, 0.12)):
        got, nearest = probe.vertices_near(Q, radius, sharp)
        D = np.linalg.norm(V[:, None] - Q[None], axis=2)
        d = D.min(axis=1)
        assert np.array_equal(got, np.flatnonzero((d <= radius) & (k > sharp)))
        assert np.allclose(D[got, nearest], d[got])
    assert len(probe.vertices_near(Q[:0], 1.0, 0.0)[0]) == 0


def test_obstacle_grid_is_exact_and_cached(tmp_path):
    # a long capsule: deep points, points near the surface, and far points
    V, F = capsule(radius=8.0, length=40.0, n_around=40, cap_rings=12, segments=16)
    rng = np.random.default_rng(3)
    lo, hi = V.min(axis=0) - 5, V.max(axis=0) + 5
    Q = lo + rng.random((3000, 3)) * (hi - lo)
    near = V[rng.integers(0, len(V), 1000)] + rng.normal(scale=0.3, size=(1000, 3))
    probe = Obstacle(V, F, max_grid_nodes=20_000)
    for pts in (Q, near, Q[:5], np.vstack([Q, near])):
        assert probe.measure(pts) == _brute_force(probe, pts)
    # the grid goes to the cache and comes back identical; a damaged file is rebuilt
    a = Obstacle.cached(V, F, tmp_path)
    (path,) = tmp_path.glob("bone-probe-*.npz")
    b = Obstacle.cached(V, F, tmp_path)
    assert np.array_equal(a._lo_sd, b._lo_sd) and a.measure(Q) == b.measure(Q)
    path.write_bytes(path.read_bytes()[:-100])
    c = Obstacle.cached(V, F, tmp_path)
    assert c.measure(Q) == _brute_force(c, Q)


# ------------------------------------------------------------------ the contact finish
def _box(lo, hi):
    """A closed, outward box mesh (12 triangles)."""
    import trimesh

    b = trimesh.creation.box(bounds=np.array([lo, hi], dtype=float))
    return np.asarray(b.vertices, dtype=np.float64), np.asarray(b.faces, dtype=np.int64)


@pytest.fixture(scope="module")
def capsule_muscle():
    from musclewrap.solver import Muscle

    # radius 20, along +z from 0 to 200
    V, F = capsule(n_around=48, cap_rings=10, segments=50)
    return Muscle.from_mesh(V, F, cage_size=200)


@pytest.fixture(scope="module")
def bent(capsule_muscle):
    rest = {"a": [[0.0, 0.0, 0.0], [0.0, 0.0, 200.0]]}
    d = capsule_muscle.bind(rest)
    # the far half bent 30 degrees toward +y
    a = np.radians(30)
    cur = {"a": [[0.0, 0.0, 0.0], [0, 0, 100.0], [0, 100 * np.sin(a), 100 + 100 * np.cos(a)]]}
    return d, cur


@pytest.mark.parametrize("margin", [0.0, 1.5])
def test_capsule_pressed_into_a_plane(bent, margin):
    from musclewrap.mesh import volume

    d, cur = bent
    free = d.deform(cur)
    # a half-space x >= 12 (a large box): the muscle reaches x = 20, 8 into it
    box = Obstacle(*_box([12.0, -300, -300], [400, 300, 500]))
    res = d.deform(cur, obstacles=[box], margin=margin)
    assert res.converged, res.reason
    assert abs(volume(res.V, d.muscle.F) / d.muscle.volume_rest - 1) <= 1e-12
    assert abs(res.relative_volume_error) <= 1e-12
    from musclewrap.constants import tol
    from musclewrap.mesh import mean_edge_length

    edge = tol.contact * mean_edge_length(d.muscle.V, d.muscle.F)  # the finish's slack
    # every vertex keeps the margin from the plane, the contact vertices lie on it
    assert res.V[:, 0].max() <= 12.0 - margin + 2 * edge
    on = np.abs(res.V[:, 0] - (12.0 - margin)) <= 2 * edge + 1e-9
    assert on.sum() == res.contact_vertices > 50
    assert res.penetration_depth_before == pytest.approx(free.V[:, 0].max() - 12.0, abs=1e-6)
    # what the finish accepts inside: the slack, and it says so exactly
    inside = res.V[:, 0] > 12.0
    assert res.penetration_vertices == inside.sum()
    assert res.penetration_depth == pytest.approx(max(0.0, res.V[:, 0].max() - 12.0), abs=1e-9)
    assert res.penetration_depth <= edge
    # the rest of the muscle takes the lost volume: it grows elsewhere, by little
    assert res.contact_moved <= 9.0 + margin
    assert d.muscle.shape_change(res.V).max() <= 0.5 + 0.2 * margin


def test_capsule_pressed_into_a_sphere(bent):
    d, cur = bent
    centre = np.array([0.0, -28.0, 60.0])  # 8 into the capsule's side (radius 20 + 15 - 28)
    S, SF = capsule(radius=15.0, length=0.0, n_around=64, cap_rings=32, segments=1)
    S = S - S.mean(axis=0) + centre
    res = d.deform(cur, obstacles=[Obstacle(S, SF)], margin=0.5)
    assert res.converged, res.reason
    assert abs(res.relative_volume_error) <= 1e-12
    r = np.linalg.norm(res.V - centre, axis=1)
    # the polygonal sphere lies within 0.02 of radius 15
    assert r.min() >= 15.0 + 0.5 - 0.05
    assert res.contact_vertices > 0 and res.penetration_depth_before > 5


def _inside(P, F, B):
    """How deep the points ``B`` lie inside the surface ``P, F`` (independent: libigl)."""
    import igl

    inside = igl.winding_number(P, F, B) > 0.5
    if not inside.any():
        return 0.0, 0
    return float(np.sqrt(igl.point_mesh_squared_distance(B[inside], P, F)[0]).max()), int(
        inside.sum()
    )


@pytest.mark.parametrize("radius", [3.0, 1.0])
def test_a_rod_does_not_poke_through_between_vertices(bent, radius):
    # a rod across the capsule's side, 4 into it: sharper than the muscle's edges (about
    # 3.2) can follow, so projecting the muscle's vertices out of it alone leaves the rod
    # inside the muscle between them (5.1 deep without contact); the rod's vertices found
    # inside the muscle push its triangles past them, relaxed with their neighbours. Also
    # a rod of radius 1, which passes between the muscle's vertices with none of them in it
    d, cur = bent
    R, RF = capsule(radius=radius, length=80.0, n_around=48, cap_rings=6, segments=80)
    # along y (a reflection of the z axis: the faces turned back outward), 4 into the side
    R = (R - R.mean(axis=0))[:, [0, 2, 1]] + [19.0 - 4.0 + radius, 0.0, 60.0]
    RF = np.ascontiguousarray(RF[:, ::-1])
    res = d.deform(cur, obstacles=[Obstacle(R, RF)], margin=0.0)
    assert res.converged, res.reason
    assert abs(res.relative_volume_error) <= 1e-12
    free = d.deform(cur)
    assert _inside(free.V, d.muscle.F, R)[0] > 4.0
    depth, _ = _inside(res.V, d.muscle.F, R)
    assert depth <= 1.0
    # the run's own measure, exact from a tenth of an edge on (below it, an upper bound)
    edge = mean_edge_length(d.muscle.V, d.muscle.F)
    assert depth - 1e-6 <= res.bone_inside_depth <= max(depth + 1e-6, 0.1 * edge)
    assert d.muscle.shape_change(res.V).max() <= 0.5


def _farthest_on_bottom(P, xs, ys):
    """The point of a slab's bottom face (z = 0) farthest from its vertices, on a grid of
    ``np.linspace(*xs)`` by ``np.linspace(*ys)``: ``x, y`` and that distance."""
    bottom = P[np.abs(P[:, 2]) < 1e-9]
    g = np.stack(np.meshgrid(np.linspace(*xs), np.linspace(*ys)), -1).reshape(-1, 2)
    gap = np.linalg.norm(g[:, None, :] - bottom[None, :, :2], axis=2).min(axis=1)
    x, y = g[np.argmax(gap)]
    return x, y, gap.max()


def _inside_found(P, PF, placed, edge):
    """`bone_vertices_inside` of the closed surface ``P, PF``, pushes from a tenth of ``edge``."""
    from musclewrap.contact import Near, bone_vertices_inside, vertex_faces
    from musclewrap.mesh import vertex_adjacency

    A = vertex_adjacency(PF, len(P))
    return bone_vertices_inside(
        P, PF, placed, Near(P, placed, 0.0), edge=edge,
        adjacency=(A.indptr.astype(np.int64), A.indices.astype(np.int64)),
        faces=vertex_faces(PF, len(P)), deep=0.1 * edge,
    )  # fmt: skip


def test_a_bone_between_a_stretched_muscles_vertices_is_found():
    # The run looks for a bone's vertices inside the muscle among those convex enough to
    # stand out of a triangle whose vertices lie on the bone. Where the triangles are
    # stretched (here 10 x 2 against a mean edge of 2: a muscle pulled at an extreme pose),
    # a flatter bone stands as deep: a sphere of radius 10 (convexity 0.1, under the
    # 0.18 that triangles of 1.5 mean edges need) pressed up between the slab's vertices,
    # every one of them outside it. Each found vertex and the deepest against brute force.
    import igl

    from musclewrap.contact import Placed

    P, PF = _plate([0.0, 0.0, 0.0], [10.0, 10.0, 4.0], 2.0)
    P[:, 0] *= 5.0  # the slab's triangles stretched fivefold along x
    edge = 2.0
    x, y, gap = _farthest_on_bottom(P, [10, 40, 301], [2, 8, 61])
    R = 10.0
    rise = 0.8 * gap**2 / (2.0 * R)  # the cap's top above the face, its rim below
    S, SF = capsule(radius=R, length=0.0, n_around=192, cap_rings=96, segments=1)
    S = S - S.mean(axis=0) + [x, y, rise - R]
    bone = Obstacle(S, SF)
    placed = [Placed(bone, name="sphere")]
    assert bone.signed(P)[0].min() > 0.0  # every slab vertex outside the bone
    truth = igl.winding_number(P, PF, S) > 0.5
    assert truth.sum() >= 3
    deepest = np.sqrt(igl.point_mesh_squared_distance(S[truth], P, PF)[0]).max()
    assert deepest > 0.1 * edge  # deep enough to be pushed
    (found,) = _inside_found(P, PF, placed, edge)
    assert set(found.rows) == set(np.flatnonzero(truth))
    assert found.deepest == pytest.approx(deepest, abs=1e-9)


def test_a_coarse_bones_corner_deep_between_a_muscles_vertices_is_found():
    # A model's bone has a few hundred vertices (gait2392's pelvis 125, edges of 22 mm):
    # the corner of its large flat triangles can stand deeper in a muscle than 1.5 of the
    # muscle's edges from every one of its vertices (the pectineus on gait2392's running
    # trial: 3.3 mm, reported 0), and its curvature toward its far neighbours is flat.
    # A sharp pyramid (edges of 30 mm) pokes its apex 3.5 mm up into a slab of edge 2.
    import igl

    from musclewrap.contact import Placed

    P, PF = _plate([0.0, 0.0, 0.0], [20.0, 20.0, 10.0], 2.0)
    edge = mean_edge_length(P, PF)
    x, y, _ = _farthest_on_bottom(P, [6, 14, 81], [6, 14, 81])
    S = np.array(
        [[x, y, 3.5]] + [[x + a, y + b, -26.5] for a, b in [(-3, -3), (3, -3), (3, 3), (-3, 3)]]
    )
    SF = np.array([[0, 1, 2], [0, 2, 3], [0, 3, 4], [0, 4, 1], [1, 3, 2], [1, 4, 3]])
    bone = Obstacle(S, SF)
    placed = [Placed(bone, name="pyramid")]
    assert bone.signed(P)[0].min() > 0.0  # every slab vertex outside the bone
    assert np.linalg.norm(P - S[0], axis=1).min() > 1.5 * edge  # the apex far from them all
    truth = igl.winding_number(P, PF, S) > 0.5
    assert list(np.flatnonzero(truth)) == [0]
    (found,) = _inside_found(P, PF, placed, edge)
    assert list(found.rows) == [0]
    assert found.deepest == pytest.approx(3.5, abs=1e-9)


# ------------------------------------------------------------------ sides, on a path
def _plate(lo, hi, spacing):
    """A closed box with vertices every ``spacing`` or less on its faces."""
    import trimesh

    b = trimesh.creation.box(bounds=np.array([lo, hi], dtype=float))
    Vb, Fb = trimesh.remesh.subdivide_to_size(b.vertices, b.faces, spacing)
    m = trimesh.Trimesh(Vb, Fb, process=True)
    return np.asarray(m.vertices, dtype=np.float64), np.asarray(m.faces, dtype=np.int64)


def _swing(d, obstacle, angles, axis, sides=True):
    """The capsule's far half turned toward ``axis`` through ``angles`` (degrees) in turn.

    Each pose takes its sides from the one before, as a scene's frames take theirs from
    their waypoints (the intermediate poses without the fine finish); ``sides=False``:
    every vertex out of the obstacle the nearest way instead.
    """
    from musclewrap.contact import Placed, SideReference

    placed = [Placed(obstacle, name="bone")]
    ref = SideReference(d.muscle.V, placed)
    res = None
    for i, theta in enumerate(angles):
        t = np.radians(theta)
        far = [0.0, 0.0, 100.0] + 100.0 * (np.sin(t) * np.asarray(axis) + [0, 0, np.cos(t)])
        lines = {"a": [[0.0, 0.0, 0.0], [0.0, 0.0, 100.0], list(far)]}
        last = i == len(angles) - 1
        res = d.deform(lines, obstacles=placed, sides=ref if sides else None, finish=last)
        ref = SideReference(res.V, placed)
    return res


def test_a_capsule_pressed_through_a_thin_plate_stays_on_its_side(capsule_muscle):
    # A plate 3 thick, 2 from the capsule's side at rest; the far half of the line turns
    # toward it by 6 deg (the line stays 11 short of it), which would carry the surface 6
    # past its near face, through it. Taken out the nearest way, the vertices past the
    # plate's middle leave by its far face and the plate stands inside the muscle; from the
    # way they came, they stay on the near face.
    d = capsule_muscle.bind({"a": [[0.0, 0.0, 0.0], [0.0, 0.0, 200.0]]})
    P, PF = _plate([22.0, -40.0, 110.0], [25.0, 40.0, 230.0], 2.0)
    plate = Obstacle(P, PF)
    span = lambda V: (V[:, 2] > 110.0) & (V[:, 2] < 230.0) & (np.abs(V[:, 1]) < 40.0)  # noqa: E731
    res = _swing(d, plate, [2.0, 4.0, 6.0], (1.0, 0.0, 0.0))
    assert res.converged, res.reason
    assert abs(res.relative_volume_error) <= 1e-12
    edge = mean_edge_length(d.muscle.V, d.muscle.F)
    assert res.V[span(res.V), 0].max() <= 22.0 + 0.05 * edge  # on the near face
    assert _inside(res.V, d.muscle.F, P)[0] <= 0.1  # the plate is not in the muscle
    assert d.muscle.shape_change(res.V).max() <= 0.5
    near = _swing(d, plate, [2.0, 4.0, 6.0], (1.0, 0.0, 0.0), sides=False)
    assert (near.V[span(near.V), 0] > 25.0).sum() > 50  # past the plate
    assert _inside(near.V, d.muscle.F, P)[0] > 1.0


def test_a_capsule_bent_over_a_sphere_as_its_line_swings_past(capsule_muscle):
    # a ball of radius 8 beside the capsule at the bend, 2 from it; the far half turns
    # toward it by 60 deg (its line passes the ball, the surface goes over it)
    d = capsule_muscle.bind({"a": [[0.0, 0.0, 0.0], [0.0, 0.0, 200.0]]})
    S, SF = capsule(radius=8.0, length=0.0, n_around=48, cap_rings=24, segments=1)
    S = S - S.mean(axis=0) + [0.0, 30.0, 100.0]
    res = _swing(d, Obstacle(S, SF), [10.0, 20.0, 30.0, 40.0, 50.0, 60.0], (0.0, 1.0, 0.0))
    assert res.converged, res.reason
    assert abs(res.relative_volume_error) <= 1e-12
    assert _inside(res.V, d.muscle.F, S)[0] <= 0.5  # nothing enclosed
    r = np.linalg.norm(res.V - [0.0, 30.0, 100.0], axis=1)
    assert r.min() >= 8.0 - 0.05  # no muscle vertex in the ball (its polygon's radius)
    assert d.muscle.shape_change(res.V).max() <= 0.5


def test_a_capsule_bent_over_a_box_edge(capsule_muscle):
    # a block beside the capsule's lower half, 2 from it, its top edge at the bend; the far
    # half turns over the edge by 60 deg
    d = capsule_muscle.bind({"a": [[0.0, 0.0, 0.0], [0.0, 0.0, 200.0]]})
    B, BF = _plate([22.0, -40.0, -50.0], [80.0, 40.0, 100.0], 3.0)
    res = _swing(d, Obstacle(B, BF), [10.0, 20.0, 30.0, 40.0, 50.0, 60.0], (1.0, 0.0, 0.0))
    assert res.converged, res.reason
    assert abs(res.relative_volume_error) <= 1e-12
    assert _inside(res.V, d.muscle.F, B)[0] <= 1.0  # the edge does not cut into the muscle
    assert _inside(B, BF, res.V)[0] <= 0.05  # nor the muscle into the block
    assert d.muscle.shape_change(res.V).max() <= 0.5


def test_attachment_patches_keep_only_those_near_a_line_end():
    from musclewrap.contact import attachment_patches
    from musclewrap.mesh import vertex_adjacency

    V, F = capsule(radius=8.0, length=100.0, n_around=24, cap_rings=6, segments=20)
    A = vertex_adjacency(F, len(V))
    z = V[:, 2] - V[:, 2].min()
    # two patches on the side x > 6: one at the start of the line, one in the middle
    start = np.flatnonzero((V[:, 0] > 6) & (z < 25))
    middle = np.flatnonzero((V[:, 0] > 6) & (np.abs(z - 58) < 8))
    lines = {"a": [[0.0, 0.0, V[:, 2].min() + 2.0], [0.0, 0.0, V[:, 2].max() - 2.0]]}
    kept = attachment_patches(A, V, np.concatenate([start, middle]), lines)
    assert np.array_equal(kept, np.sort(start))
    # a larger reach takes the middle patch too; none: nothing
    assert len(attachment_patches(A, V, np.concatenate([start, middle]), lines, 0.9)) == len(
        start
    ) + len(middle)
    assert len(attachment_patches(A, V, np.zeros(0, np.int64), lines)) == 0


def test_no_contact_gives_the_result_without_obstacles(bent):
    d, cur = bent
    far = Obstacle(*_box([100.0, 100, 100], [150, 150, 150]))
    a, b = d.deform(cur), d.deform(cur, obstacles=[far], margin=2.0)
    assert np.array_equal(a.V, b.V) and b.contact_vertices == 0 and b.converged


def test_lines_dragging_the_muscle_deep_into_a_bone(bent):
    from musclewrap.contact import Placed

    d, _ = bent
    # the whole muscle dragged 15 into a slab that it cannot leave sideways within the margin
    cur = {"a": [[0.0, 0.0, 0.0], [15.0, 0.0, 200.0]]}
    slab = Obstacle(*_box([12.0, -300, -300], [400, 300, 500]))
    # placed by a transform: the slab's frame is the muscle's shifted by 5 along x
    T = np.eye(4)
    T[0, 3] = 5.0
    res = d.deform(cur, obstacles=[Placed(slab, T, name="slab")], margin=0.0)
    assert res.converged, res.reason
    assert res.V[:, 0].max() <= 7.0 + 0.05
    assert res.penetration_depth_before > 20
    assert abs(res.relative_volume_error) <= 1e-12


def test_contact_that_cannot_be_met_is_reported(bent):
    from musclewrap.contact import Placed

    d, cur = bent
    # two slabs 1 apart across the muscle, with a margin of 2: no place keeps it from both
    a = Obstacle(*_box([0.5, -300, -300], [400, 300, 500]))
    b = Obstacle(*_box([-400.0, -300, -300], [-0.5, 300, 500]))
    res = d.deform(cur, obstacles=[Placed(a, name="left"), Placed(b, name="right")], margin=2.0)
    assert not res.converged
    assert "contact not met" in res.reason and ("left" in res.reason or "right" in res.reason)
    # still volume-exact
    assert abs(res.relative_volume_error) <= 1e-9


def test_a_vertex_that_slid_inside_a_shell_leaves_it_the_nearest_way():
    # A spherical shell 3 thick (a cartilage's cap of 2-4 mm round a bone the scene lacks).
    # A vertex that was inside it by its inner face and slid 60 deg round it to just under
    # its outer face: its way from then starts inside, so it "entered" at its start's
    # closest point, whose tangent plane puts it 8.6 in front: it must still go out (the
    # nearest way, 0.3), not be left inside. One that came through the outer face and went
    # past the middle still goes back the way it came (2.5, not the 0.5 to the inner face).
    from musclewrap.contact import Placed, SideReference, on_their_side

    So, Fo = capsule(radius=23.0, length=0.0, n_around=96, cap_rings=48, segments=1)
    Si, Fi = capsule(radius=20.0, length=0.0, n_around=96, cap_rings=48, segments=1)
    c = So.mean(axis=0)
    V = np.vstack([So - c, Si - Si.mean(axis=0)])
    F = np.vstack([Fo, Fi[:, ::-1] + len(So)])
    shell = Obstacle(V, F)
    placed = [Placed(shell, name="shell")]
    t = np.radians(60.0)
    then = np.array([[0.0, 0.0, 20.2], [0.0, 0.0, 23.5]])
    now = np.array([22.7 * np.array([np.sin(t), 0.0, np.cos(t)]), [0.0, 0.0, 20.5]])
    phi, C, N = shell.signed(now)
    assert (phi < 0).all()  # both inside the shell now
    ref = SideReference(then, placed)
    phi2, _, N2, turned = on_their_side(placed[0], ref, 0, np.arange(2), now, phi, C, N)
    # the polygonal spheres lie within 0.05 of the round ones
    assert phi2[0] == pytest.approx(-0.3, abs=0.05)
    assert np.allclose(N2[0], [np.sin(t), 0.0, np.cos(t)], atol=0.05)
    assert list(turned) == [1]
    assert phi2[1] == pytest.approx(-2.5, abs=0.05)
    assert np.allclose(N2[1], [0.0, 0.0, 1.0], atol=0.05)


def test_a_vertex_inside_the_bone_then_has_no_side_it_came_from():
    # A plate 4 thick. A vertex that lay 1 inside it then (a rest overlap kept: the VHF
    # gluteus maximus in Rajagopal's generic sacrum) and is now past its middle leaves it
    # the nearest way (0.5 down): it came through neither face. One that was above it and
    # came through the top goes back up the way it came (3.5), as before.
    from musclewrap.contact import Placed, SideReference, on_their_side

    plate = Obstacle(*_box([-50.0, -50.0, -2.0], [50.0, 50.0, 2.0]))
    placed = [Placed(plate, name="plate")]
    then = np.array([[0.0, 0.0, 1.0], [5.0, 0.0, 3.0]])
    now = np.array([[0.0, 0.0, -1.5], [5.0, 0.0, -1.5]])
    phi, C, N = plate.signed(now)
    ref = SideReference(then, placed)
    assert list(ref.inside(0, np.arange(2))) == [True, False]
    phi2, _, N2, turned = on_their_side(placed[0], ref, 0, np.arange(2), now, phi, C, N)
    assert list(turned) == [1]
    assert phi2[1] == pytest.approx(-3.5) and np.allclose(N2[1], [0.0, 0.0, 1.0])
    assert phi2[0] == pytest.approx(-0.5) and np.allclose(N2[0], [0.0, 0.0, -1.0])


def test_a_kept_overlap_lets_a_vertex_as_deep_as_its_neighbours_within_two_rings():
    """`kept_allowance`: a vertex may go as deep into the bone as the deepest of its
    neighbours within ``defaults.kept_overlap_rings`` rings did at rest (the rim of the
    overlap slides onto vertices that were outside); without ``F``, as deep as itself."""
    from musclewrap.contact import Placed, kept_allowance
    from musclewrap.mesh import vertex_adjacency

    V, F = capsule(radius=10.0, length=40.0, n_around=32, cap_rings=8, segments=24)
    box = Obstacle(*_box([-50.0, -50.0, -50.0], [50.0, -8.0, 150.0]))  # 2 into one side
    pl = Placed(box, name="box")
    own = kept_allowance(pl, V, 0.0)
    spread = kept_allowance(pl, V, 0.0, F, rings=2)
    inside = np.isfinite(own)
    assert inside.any() and own[inside].min() == pytest.approx(-2.0, abs=0.01)
    assert (spread <= own).all()
    A = vertex_adjacency(F, len(V)).tocsr()
    rim = np.flatnonzero(~inside & np.isfinite(spread))
    for i in np.concatenate([rim, np.flatnonzero(~np.isfinite(spread))[:100]]):
        one = A.indices[A.indptr[i] : A.indptr[i + 1]]
        two = np.unique(np.concatenate([A.indices[A.indptr[j] : A.indptr[j + 1]] for j in one]))
        assert spread[i] == np.min(np.concatenate([[own[i]], own[one], own[two]]))
    assert np.isfinite(spread).sum() > inside.sum()  # the rim's two rings joined it


# ------------------------------------------------------------------ scenes
def _scene_text(data_dir, extra=""):
    lhdl = data_dir / "lhdl"
    return f"""name = "hip"
[units]
mesh = "mm"
model = "m"
[model]
osim = "{lhdl / "model" / "LHDL_hip_r.osim"}"
motion = "{data_dir / "opensim" / "motions" / "subject01_walk1_ik.mot"}"
coordinates = ["hip_flexion_r", "hip_adduction_r", "hip_rotation_r"]
rest_pose = {{ hip_flexion_r = 1.576, hip_adduction_r = -4.727, hip_rotation_r = -5.29 }}
output_frame = "pelvis"
angle_unit = "deg"
[muscles.psoas]
mesh = "{lhdl / "muscles" / "LHDL_R_Psoas.vtk"}"
paths = ["psoas_r"]
body = "pelvis"
reference = "femur"
[bones.femur]
mesh = "{lhdl / "bones" / "LHDL_R_Femur.vtk"}"
body = "femur_r"
[bones.iliac]
mesh = "{lhdl / "bones" / "LHDL_R_Iliac.vtk"}"
body = "pelvis"
[output]
gif = false
paper_frames = 0
{extra}"""


@pytest.mark.realdata
def test_collision_settings_are_checked(data_dir, tmp_path):
    from musclewrap.scene import SceneError, load_scene

    toml = tmp_path / "s.toml"
    for extra, match in [
        ("[collisions]\nmargin = -1\n", "margin must be >= 0"),
        ("[collisions]\nrest_overlap = 'push'\n", "rest_overlap = 'push'; use 'resolve'"),
        ("[collisions]\nenable = false\n", "unknown key 'enable' in \\[collisions\\].*enabled"),
    ]:
        toml.write_text(_scene_text(data_dir, extra))
        with pytest.raises(SceneError, match=match):
            load_scene(toml)
    text = _scene_text(data_dir).replace(
        'reference = "femur"', 'reference = "femur"\nbones = ["femr"]'
    )
    toml.write_text(text)
    with pytest.raises(SceneError, match="bones: 'femr' is not a bone of the scene.*femur"):
        load_scene(toml)
    toml.write_text(_scene_text(data_dir, "[collisions]\nenabled = false\nmargin = 0.5\n"))
    sc = load_scene(toml)
    assert not sc.collisions and sc.margin == 0.5 and sc.rest_overlap == "resolve"


@pytest.mark.realdata
def test_a_muscle_inside_a_bone_at_rest_is_refused(data_dir, tmp_path):
    # a bone that encloses the whole psoas (a box around it): wrong frame or wrong mesh
    from musclewrap.mesh import read_mesh, write_mesh
    from musclewrap.scene import SceneError, load_scene, run_scene

    lhdl = data_dir / "lhdl"
    V, _ = read_mesh(lhdl / "muscles" / "LHDL_R_Psoas.vtk")
    write_mesh(tmp_path / "box.vtp", *_box(V.min(0) - 10, V.max(0) + 10))
    text = _scene_text(data_dir).replace(
        str(lhdl / "bones" / "LHDL_R_Iliac.vtk"), str(tmp_path / "box.vtp")
    )
    toml = tmp_path / "s.toml"
    toml.write_text(text)
    with pytest.raises(SceneError, match="of 'psoas' lie inside the bone 'iliac'.*same frame"):
        run_scene(load_scene(toml), tmp_path / "o", frames="0:2", cache_dir=False, progress=None)
    assert not (tmp_path / "o" / "report.csv").exists()


@pytest.mark.realdata
@pytest.mark.slow
def test_lhdl_walk_subset_stays_out_of_the_bones(data_dir, tmp_path):
    """The walk with contact on, checked independently against the full-resolution bones."""
    from pathlib import Path

    from musclewrap.mesh import read_mesh
    from musclewrap.run._verify import verify_run
    from musclewrap.scene import load_scene, run_scene

    examples = Path(__file__).resolve().parents[1] / "examples"
    scene = load_scene(examples / "lhdl_walk.toml")
    frames = "0:211:105"
    s = run_scene(
        scene, tmp_path / "o", frames=frames, workers=2, cache_dir=tmp_path / "c", progress=None,
        render=False,
    )  # fmt: skip
    # the segmentations overlap the iliac bone at rest: resolved once, reported
    resolved = {n.split(":")[0] for n in s.notes if "rest overlap with bones resolved" in n}
    assert resolved == {m.name for m in scene.muscles}
    assert len(s.rows) == 4 * 3
    for r in s.rows:
        assert r["converged"], r
        assert abs(r["relative_volume_error"]) <= 1e-9, r
        assert r["skeleton_fit_mean"] <= 1.5, r
        # the run's own measure, after contact
        assert r["penetration_depth_max"] <= 0.5, r
        assert r["shape_change_max"] <= 0.5, r
    # without contact the solve puts vertices a few mm into the bones on these frames
    assert max(r["penetration_depth_before"] for r in s.rows) > 1.0
    assert (tmp_path / "o" / "penetration.png").is_file()
    # the independent check: exact winding numbers and distances, full-resolution bones
    rows = verify_run(scene, tmp_path / "o", frames)
    assert len(rows) == 12
    assert max(r["muscle_in_bone"] for r in rows) <= 0.5
    assert max(r["bone_in_muscle"] for r in rows) <= 1.0
    # every written mesh has the volume of the prepared (repaired, pushed-out) muscle
    for r in s.rows:
        m = r["muscle"]
        V, F = read_mesh(tmp_path / "o" / m / f"{m}_{r['frame']:04d}.vtp")
        assert V.shape[0] > 1000


@pytest.mark.realdata
def test_rest_overlap_read_back_from_the_cache_gives_the_same_run(data_dir, tmp_path):
    """The rest overlap's outcome is kept per muscle: a second run says and writes the same.

    The frames carry each vertex's index in the input file (the psoas is merged and
    repaired: not the identity).
    """
    import pyvista as pv

    from musclewrap.mesh import clean_mesh, read_mesh
    from musclewrap.scene import load_scene, run_scene

    toml = tmp_path / "s.toml"
    toml.write_text(_scene_text(data_dir))
    runs = [
        run_scene(
            load_scene(toml),
            tmp_path / o,
            frames="0:211:210",
            cache_dir=tmp_path / "c",
            progress=None,
            render=False,
        )  # fmt: skip
        for o in ("a", "b")
    ]
    assert len(list((tmp_path / "c").glob("rest-outcome-*.npz"))) == 1
    assert runs[0].notes == runs[1].notes
    assert any("rest overlap with bones resolved" in n for n in runs[1].notes)
    for r in runs[0].rows:
        m, f = r["muscle"], r["frame"]
        Va, _ = read_mesh(tmp_path / "a" / m / f"{m}_{f:04d}.vtp")
        Vb, _ = read_mesh(tmp_path / "b" / m / f"{m}_{f:04d}.vtp")
        assert np.array_equal(Va, Vb)
        ids = np.asarray(pv.read(tmp_path / "a" / m / f"{m}_{f:04d}.vtp").point_data["input_id"])
        V0, F0 = read_mesh(data_dir / "lhdl" / "muscles" / "LHDL_R_Psoas.vtk")
        V1, _, _ = clean_mesh(V0, F0, repair=True)
        assert ids.shape == (len(Va),) and not np.array_equal(ids, np.arange(len(Va)))
        kept = ids >= 0
        assert kept.mean() > 0.99 and len(np.unique(ids[kept])) == kept.sum()
        assert np.array_equal(V0[ids[kept]], V1[kept])


@pytest.mark.realdata
def test_rest_overlap_kept_prevents_only_new_penetration(data_dir, tmp_path):
    from musclewrap.scene import load_scene, run_scene

    toml = tmp_path / "s.toml"
    toml.write_text(_scene_text(data_dir, "[collisions]\nrest_overlap = 'keep'\n"))
    s = run_scene(
        load_scene(toml), tmp_path / "o", frames="0:211:100", cache_dir=tmp_path / "c",
        progress=None, render=False,
    )  # fmt: skip
    assert not any("rest overlap" in n for n in s.notes)
    for r in s.rows:
        assert r["converged"], r
        assert abs(r["relative_volume_error"]) <= 1e-9
        # the psoas lies 3.5 mm into the iliac bone at rest: kept, never deeper
        assert 0.5 < r["penetration_depth_max"] <= 3.53, r


@pytest.mark.realdata
def test_an_open_bone_is_closed_for_contact_or_refused(data_dir, tmp_path):
    from musclewrap.mesh import read_mesh, write_mesh
    from musclewrap.scene import SceneError, load_scene, run_scene

    lhdl = data_dir / "lhdl"
    V, F = read_mesh(lhdl / "bones" / "LHDL_R_Femur.vtk")
    # a hole: the faces around one vertex of the shaft removed
    write_mesh(tmp_path / "open.vtp", V, F[~(F == F[len(F) // 2, 0]).any(axis=1)])
    text = _scene_text(data_dir).replace(
        str(lhdl / "bones" / "LHDL_R_Femur.vtk"), str(tmp_path / "open.vtp")
    )
    toml = tmp_path / "s.toml"
    toml.write_text(text)
    s = run_scene(load_scene(toml), tmp_path / "o", frames="0:2", cache_dir=False, progress=None)
    assert any(n.startswith("femur: open (") and "closed for contact" in n for n in s.notes)
    assert all(r["converged"] for r in s.rows)
    # a bone that is only a few loose triangles cannot be closed: refused, naming the file
    write_mesh(tmp_path / "open.vtp", V, F[:3])
    with pytest.raises(SceneError, match="open.vtp: the bone 'femur' is open.*could not be closed"):
        run_scene(load_scene(toml), tmp_path / "o2", frames="0:2", cache_dir=False, progress=None)


def test_without_the_fine_finish_the_cage_is_the_same(bent):
    """``finish=False`` (the side poses of moment arms): the same cage at about half the cost."""
    d, cur = bent
    box = Obstacle(*_box([12.0, -300, -300], [400, 300, 500]))
    full = d.deform(cur, obstacles=[box])
    cage_only = d.deform(cur, obstacles=[box], finish=False)
    assert full.converged and cage_only.converged
    assert full.contact_vertices > 50  # the finish did move vertices
    np.testing.assert_array_equal(cage_only.cage, full.cage)
    # its fine positions are the cage's: W @ x, on the exact volume the cage steps end on
    np.testing.assert_allclose(cage_only.V, d.muscle.W @ cage_only.cage, atol=1e-9)
    assert abs(cage_only.relative_volume_error) <= 1e-12
    assert np.abs(full.V - cage_only.V).max() > 0.3


def test_the_finish_takes_the_poses_finds_again_to_the_same_bytes(bent):
    """A pose solved without its finish keeps what its contact found (`PoseContact`: the
    bounds, the line targets, the bone finds); `settle` taking them gives the same bytes as
    one that finds them anew, and as the pose finished at once."""
    import dataclasses

    d, cur = bent
    box = Obstacle(*_box([12.0, -300, -300], [400, 300, 500]))
    full = d.deform(cur, obstacles=[box])
    half = d.deform(cur, obstacles=[box], finish=False)
    assert half.pose is not None and full.pose is None
    kept = d.settle(half, half.cage, half.V, cur, obstacles=[box])
    anew = d.settle(dataclasses.replace(half, pose=None), half.cage, half.V, cur, obstacles=[box])
    assert kept.pose is None
    for r in (kept, anew):
        np.testing.assert_array_equal(r.V, full.V)
        np.testing.assert_array_equal(r.cage, full.cage)
        assert (r.contact_vertices, r.penetration_depth, r.bone_inside_depth) == (
            full.contact_vertices, full.penetration_depth, full.bone_inside_depth,
        )  # fmt: skip
    assert "pose" not in full.summary()


@pytest.mark.parametrize("into", [0.1, 1.0])
def test_the_finish_lands_shallow_pushes_in_two_rounds(into):
    """A pose's fine finish relaxes shallow pushes (under `defaults.contact_relax_depth` mean
    edges) in its first round only and lands them exactly in the next: two rounds, where
    relaxed three times they landed short and took four. Deeper pushes relax in the first
    rounds as before. Either way every vertex ends out, at the margin, the volume exact."""
    from musclewrap.constants import defaults
    from musclewrap.contact import Placed, push_out
    from musclewrap.mesh import volume

    V, F = capsule(radius=10.0, length=60.0, n_around=32, cap_rings=8, segments=40)
    edge = mean_edge_length(V, F)
    depth = into * edge  # how far the sphere reaches into the capsule's side
    S, SF = capsule(radius=15.0, length=0.0, n_around=64, cap_rings=32, segments=1)
    S = S - S.mean(axis=0) + [0.0, 25.0 - depth, 40.0]
    target = volume(V, F)
    P, rep = push_out(V, F, [Placed(Obstacle(S, SF))], volume_target=target, margin=0.0)
    assert rep.ok, rep.reason
    assert rep.depth_before > 0.5 * depth
    if into < defaults.contact_relax_depth:
        assert rep.rounds == 2
    else:
        assert rep.rounds >= 3
    assert rep.depth_after == 0.0 and rep.inside == 0
    assert abs(volume(P, F) / target - 1) <= 1e-12
    assert np.linalg.norm(P - [0.0, 25.0 - depth, 40.0], axis=1).min() >= 15.0 - 0.02


def _shape(V, V0, F):
    """The shape change of ``V`` against ``V0`` (`PreparedMuscle.shape_change`'s measure)."""
    from musclewrap.mesh import umbrella_laplacian

    U = umbrella_laplacian(F, len(V0))
    d0 = np.linalg.norm(U @ V0, axis=1)
    return np.abs(np.linalg.norm(U @ V, axis=1) - d0) / mean_edge_length(V0, F)


def _shelf():
    """A capsule, its uniform Laplacian and volume, and a move with a fold: the vertices
    past z = 50 pushed 6 mm sideways, those before it not (a shelf along a ring)."""
    from musclewrap.mesh import umbrella_laplacian, volume

    V0, F = capsule(radius=20.0, length=40.0, n_around=48, cap_rings=12, segments=12)
    D = np.zeros_like(V0)
    D[V0[:, 2] > 50.0, 0] = 6.0
    return V0, F, umbrella_laplacian(F, len(V0)), volume(V0, F), V0 + D


def test_unfold_irons_a_steps_fold_and_keeps_the_held_vertices_and_the_volume():
    """A move with a fold in it (a shelf along a ring) is ironed out away from the held cap
    (held vertices that are not folds stay where the move put them)."""
    from musclewrap.contact import unfold
    from musclewrap.mesh import volume

    V0, F, U, target, V = _shelf()
    held = V0[:, 2] > 60.0  # the cap the move had to put there
    s0, s = _shape(V0, V0, F), _shape(V, V0, F)
    assert s.max() > 0.5  # the shelf is a fold
    P = unfold(V0, V, F, U, s0, s, held, volume_target=target)
    sp_ = _shape(P, V0, F)
    assert sp_.max() < 0.5 * s.max()
    np.testing.assert_array_equal(P[held], V[held])
    assert abs(volume(P, F) - target) <= 1e-9 * target
    # only within fold_rings of the fold does anything move
    from musclewrap.constants import defaults
    from musclewrap.contact import rings

    fold = np.flatnonzero((s > defaults.fold_shape) & (s - s0 > defaults.fold_rise))
    far = rings(U, fold, defaults.fold_rings) > defaults.fold_rings
    np.testing.assert_array_equal(P[far], V[far])


def test_unfold_irons_a_fold_among_the_held_vertices():
    """The same shelf, held from before it: the fold lies among the held vertices (a crease
    on the bone, the 120-deg gluteus maximus's). The folds are ironed all the same; the
    other held vertices stay; the finish is what puts those moved back on the bone."""
    from musclewrap.constants import defaults
    from musclewrap.contact import unfold
    from musclewrap.mesh import volume

    V0, F, U, target, V = _shelf()
    held = V0[:, 2] > 40.0
    s0, s = _shape(V0, V0, F), _shape(V, V0, F)
    fold = (s > defaults.fold_shape) & (s - s0 > defaults.fold_rise)
    assert (fold & held).any() and not (fold & ~held).any()  # every fold is held
    P = unfold(V0, V, F, U, s0, s, held, volume_target=target)
    assert _shape(P, V0, F).max() < 0.75 * s.max()
    np.testing.assert_array_equal(P[held & ~fold], V[held & ~fold])
    assert abs(volume(P, F) - target) <= 1e-9 * target


def test_unfold_leaves_a_smooth_move_alone():
    """A rigid turn and a gentle bend raise no shape change: ``V`` comes back itself."""
    from musclewrap.contact import unfold
    from musclewrap.mesh import umbrella_laplacian, volume

    V0, F = capsule(radius=20.0, length=40.0, n_around=48, cap_rings=12, segments=12)
    U = umbrella_laplacian(F, len(V0))
    c, s_ = np.cos(0.3), np.sin(0.3)
    V = V0 @ np.array([[c, -s_, 0.0], [s_, c, 0.0], [0.0, 0.0, 1.0]]).T
    V[:, 0] += 1e-4 * (V0[:, 2] - 40.0) ** 2  # a gentle bend
    s0, s = _shape(V0, V0, F), _shape(V, V0, F)
    held = np.zeros(len(V0), dtype=bool)
    assert unfold(V0, V, F, U, s0, s, held, volume_target=volume(V0, F)) is V


def test_unfold_with_nothing_round_the_folds_to_meet_leaves_the_move():
    """Folds all over a mesh, none held: no thin plate can meet anything, so none is made."""
    from musclewrap.contact import unfold
    from musclewrap.mesh import umbrella_laplacian, volume

    V0, F = capsule(radius=5.0, length=0.0, n_around=12, cap_rings=4, segments=1)
    U = umbrella_laplacian(F, len(V0))
    V = V0 + np.random.default_rng(3).normal(scale=2.0, size=V0.shape)
    s0, s = _shape(V0, V0, F), _shape(V, V0, F)
    held = np.zeros(len(V0), dtype=bool)
    assert unfold(V0, V, F, U, s0, s, held, volume_target=volume(V0, F)) is V


@pytest.mark.realdata
def test_a_frame_is_the_same_bytes_alone_or_in_a_chunk_of_fifty(data_dir, tmp_path):
    """A frame's result with contact does not depend on the frames run with it.

    Its sides come from its waypoint (`FollowPath`), computed from the rest pose along
    the lattice whatever frames a run holds: the frame alone, in a chunk of fifty, and in
    a run split over two workers give the same bytes (issue 44's test of a warm start).
    """
    from musclewrap.run._plan import chunks
    from musclewrap.scene import load_scene, run_scene

    toml = tmp_path / "s.toml"
    toml.write_text(_scene_text(data_dir))
    frame = 148  # the walk's swing: the psoas in contact with the iliac bone

    def run(out, frames, workers):
        run_scene(
            load_scene(toml), tmp_path / out, frames=frames, cache_dir=tmp_path / "c",
            progress=None, render=False, workers=workers,
        )  # fmt: skip
        return (tmp_path / out / "psoas" / f"psoas_{frame:04d}.vtp").read_bytes()

    alone = run("alone", f"{frame}:{frame + 1}", 1)
    # one chunk of fifty frames, the frame in its middle
    assert run("fifty", f"{frame - 30}:{frame + 20}", 1) == alone
    # two workers: two chunks of 25 (`chunks`), the frame the first of the second
    assert chunks(50, 1, 2) == [range(0, 25), range(25, 50)]
    assert run("two", f"{frame - 25}:{frame + 25}", 2) == alone


def test_a_rounds_cage_step_holds_what_it_would_push_into_a_bone(capsule_muscle, monkeypatch):
    """A round's cage step (another muscle pushing) swings the surface into a bone further on,
    where no vertex was near enough to hold a condition: tried, those vertices held, and the
    step taken again keeps them nearly out, the push met as before, the volume exact."""
    import dataclasses

    import musclewrap.solver._contact as steps
    from musclewrap.constants import defaults
    from musclewrap.contact import Placed
    from musclewrap.mesh import volume

    rest = {"a": [[0.0, 0.0, 0.0], [0.0, 0.0, 200.0]]}
    d = capsule_muscle.bind(rest)
    r = d.deform(rest)
    # a bone 5 clear of the capsule's +x side, from z = 135 on (the band holds 2 edges, 6.4)
    slab = Obstacle(*_box([25.0, -300.0, 135.0], [400.0, 300.0, 500.0]))
    placed = [Placed(slab, name="slab")]
    # the -x side pushed 40 along +x over z = 70..130 (by another muscle)
    rows = np.flatnonzero((r.V[:, 0] < -15.0) & (np.abs(r.V[:, 2] - 100.0) < 30.0))
    need, out = np.full(len(rows), 40.0), np.tile([1.0, 0.0, 0.0], (len(rows), 1))

    def step(tries):
        monkeypatch.setattr(
            steps, "defaults", dataclasses.replace(defaults, contact_round_held=tries)
        )
        _, P = d.contact_round(r.cage, r.V, rows, need, out, obstacles=placed, margin=0.0)
        assert abs(volume(P, d.muscle.F) / volume(r.V, d.muscle.F) - 1.0) <= 1e-9
        return P, slab.measure(P)[1], float((P[rows, 0] - r.V[rows, 0]).min())

    P0, deep0, met0 = step(0)
    P, deep, met = step(defaults.contact_round_held)
    assert deep0 > 2.0  # as first tried: its swing 2.1 into the slab
    assert deep <= 0.45 * deep0  # held: 0.8 (soft conditions, one a cage vertex)
    assert met >= 0.95 * met0 > 10.0  # the push met as far (14.3 against 14.5)
    # nothing held where the try put nothing in: a bone beyond its reach changes no byte
    far = [Placed(Obstacle(*_box([60.0, -300.0, 135.0], [400.0, 300.0, 500.0])), name="far")]
    monkeypatch.setattr(steps, "defaults", defaults)
    got = d.contact_round(r.cage, r.V, rows, need, out, obstacles=far, margin=0.0)
    monkeypatch.setattr(steps, "defaults", dataclasses.replace(defaults, contact_round_held=0))
    assert np.array_equal(got[1], d.contact_round(r.cage, r.V, rows, need, out, obstacles=far)[1])


@pytest.mark.parametrize("start", ["zero", "near"])
def test_the_plates_compiled_iterations_are_scipys_conjugate_gradients(start):
    # `_plate_cg_kernel` against scipy's `cg` on the same matrix-free plate system: the
    # Laplacian rows of a capsule's region, one-sided pushes on some of its vertices
    import scipy.sparse as sp
    import scipy.sparse.linalg as spla

    from musclewrap.contact._finish import _plate_cg_kernel
    from musclewrap.mesh import umbrella_laplacian

    V, F = capsule(radius=8.0, length=40.0)
    rng = np.random.default_rng(3)
    U = umbrella_laplacian(F, len(V))
    m = len(V) // 2
    Us = U[np.arange(min(len(V), m + 100))][:, np.arange(m)].tocsr()
    n, k, w = 3 * m, 30, 100.0
    C = sp.csr_matrix(
        (rng.normal(size=3 * k), (np.repeat(np.arange(k), 3), rng.integers(0, n, 3 * k))),
        shape=(k, n),
    )
    a, on = rng.uniform(0.1, 1.0, k), (rng.uniform(size=k) > 0.3).astype(float)
    UsT, CT = Us.T.tocsr(), C.T.tocsr()

    def apply(x):
        return (UsT @ (Us @ x.reshape(m, 3))).ravel() + 1e-9 * x + w * (CT @ (on * (C @ x)))

    base = np.repeat(np.asarray(Us.multiply(Us).sum(axis=0)).ravel(), 3) + 1e-9
    jac = 1.0 / (base + w * (C.multiply(C).T @ on))
    b = w * (CT @ (on * a))
    x0 = np.zeros(n) if start == "zero" else 0.01 * rng.normal(size=n)
    ref, _ = spla.cg(
        spla.LinearOperator((n, n), matvec=apply, dtype=float), b, x0=x0.copy(), rtol=1e-12,
        maxiter=15, M=spla.LinearOperator((n, n), matvec=lambda x: jac * x, dtype=float),
    )  # fmt: skip
    csr = [
        np.ascontiguousarray(arr, dtype=dt)
        for M in (Us, UsT, C, CT)
        for arr, dt in ((M.indptr, np.int64), (M.indices, np.int64), (M.data, np.float64))
    ]
    got = _plate_cg_kernel(*csr, on, w, b, x0, jac, 15, 1e-12)
    assert np.abs(got - ref).max() <= 1e-10 * np.abs(ref).max()
    assert np.abs(got - x0).max() > 1e-3 * np.abs(ref).max()  # it moved
    # nothing pushed: the right side zero, the answer zero as scipy's
    assert not _plate_cg_kernel(*csr, on, w, np.zeros(n), x0, jac, 15, 1e-12).any()


def test_held_conditions_that_choose_as_before_do_not_count_as_changed():
    from musclewrap.solver._step import held_changed

    group = np.array([0, 0, 1, 1, 2])
    N = np.tile([1.0, 0.0, 0.0], (2, 1))
    before = (np.array([0, 2]), np.array([-0.5, -0.2]), N, np.array([-0.5, -0.2]))
    assert held_changed(None, before, group)

    def grown(row, rank):
        return tuple(np.concatenate([x, y]) for x, y in zip(before, (
            np.array([row]), np.array([rank]), np.array([[1.0, 0.0, 0.0]]), np.array([rank])
        ), strict=True))  # fmt: skip

    # beneath a deeper held condition of its cage vertex: the same choice
    assert not held_changed(before, grown(1, -0.3), group)
    # deeper than it, or on a cage vertex with none held yet: another step
    assert held_changed(before, grown(1, -0.7), group)
    assert held_changed(before, grown(4, -0.1), group)
