"""Fibres at rest (a harmonic field between the attachments) and carried by the cage."""

import numpy as np
import pytest

from musclewrap import Muscle
from musclewrap.fibres import areas_on_bones, attachment_areas, fibres_at_rest
from musclewrap.synthetic import CAPSULE_SCENARIOS, capsule, capsule_scenario


@pytest.fixture(scope="module")
def capsule_fibres():
    m = Muscle.from_mesh(*capsule(n_around=32, cap_rings=8, segments=40), cage_size=200)
    rest, _ = capsule_scenario("bend")
    return m, rest, fibres_at_rest(m, rest, count=60, points=15, voxels=30_000)


def test_fibres_run_inside_from_origin_to_insertion(capsule_fibres):
    import igl

    m, rest, fb = capsule_fibres
    assert fb.points.shape == (60, 15, 3)
    assert (igl.fast_winding_number(m.V, m.F, fb.points.reshape(-1, 3)) > 0.5).all()
    # the capsule runs along z from 0 to 200, its line from pole to pole: every fibre starts
    # in the origin's area (the first tenth along the line, z <= 20, within two grid cells)
    # and ends in the insertion's (z >= 180), so it is at least 3/4 of the capsule long
    tol = 2 * fb.spacing
    assert fb.points[:, 0, 2].max() < 20 + tol and fb.points[:, -1, 2].min() > 180 - tol
    assert fb.lengths().min() > 150
    # distinct fibres (seeds spread over the half-way level, none traced twice)
    assert len(np.unique(fb.points[:, 7].round(6), axis=0)) == 60


def test_each_fibre_has_its_share_of_the_cross_section(capsule_fibres):
    """Shares of the widest level's cells, nearest seed (they sum to 1); on a capsule's
    round section spread evenly, so no fibre takes much more than its 1/60; the areas
    are the shares of the volume over the mean fibre length (the section, PCSA-like)."""
    m, _, fb = capsule_fibres
    assert fb.share.shape == fb.area.shape == (60,)
    assert (fb.share > 0).all() and abs(fb.share.sum() - 1.0) < 1e-12
    assert fb.share.max() < 3.0 / 60 and fb.share.min() > 0.1 / 60  # 0.19-2.05 of 1/60
    pcsa = m.volume_rest / fb.lengths().mean()
    np.testing.assert_allclose(fb.area, fb.share * pcsa, rtol=1e-12)
    # the capsule's section: radius 20 (the PCSA of a cylinder-like body near it)
    assert 0.7 * np.pi * 20**2 < fb.area.sum() < 1.3 * np.pi * 20**2


@pytest.mark.parametrize("scenario", CAPSULE_SCENARIOS)
def test_fibres_stay_inside_the_deformed_muscle(capsule_fibres, scenario):
    import igl

    m, _, fb = capsule_fibres
    rest, cur = capsule_scenario(scenario)
    r = m.bind(rest).deform(cur)
    P = fb.at(r.cage)
    assert (igl.fast_winding_number(r.V, m.F, P.reshape(-1, 3)) > 0.5).all(), scenario


def test_a_rigid_motion_keeps_the_fibres_lengths(capsule_fibres):
    from scipy.spatial.transform import Rotation

    m, _, fb = capsule_fibres
    R = Rotation.from_rotvec([0.3, -0.5, 0.9]).as_matrix()
    moved = fb.at(m.cage.C @ R.T + [10.0, -4.0, 7.0])
    assert np.abs(fb.lengths(moved) / fb.lengths() - 1).max() <= 1e-9
    # and the rotated-line scenario, through the solver
    rest, cur = capsule_scenario("rot")
    r = m.bind(rest).deform(cur)
    assert np.abs(fb.lengths(fb.at(r.cage)) / fb.lengths() - 1).max() <= 1e-9
    with pytest.raises(ValueError, match="cage has shape"):
        fb.at(m.cage.C[:-1])


def test_attachment_areas_from_the_lines_and_their_errors():
    V, _ = capsule(n_around=16, cap_rings=4, segments=10)
    rest, _ = capsule_scenario("bend")
    o, i = attachment_areas(V, rest, reach=0.05)
    assert len(o) and len(i) and V[o, 2].max() <= 10 and V[i, 2].min() >= 190
    with pytest.raises(ValueError, match="reach must lie"):
        attachment_areas(V, rest, reach=0.6)
    with pytest.raises(ValueError, match="no action lines"):
        attachment_areas(V, {})


def test_attachment_areas_on_the_bones_of_each_end():
    """A vertex on a bone of the origin's body counts in the part of the muscle on the
    origin's side (0.3 of its extent), in a patch that reaches near a path's first point;
    a side with no such bone, or too few vertices on it, takes its end cap."""
    V, F = capsule(n_around=16, cap_rings=4, segments=20)  # along z, 0..200; line pole to pole
    rest, _ = capsule_scenario("bend")
    caps = attachment_areas(V, rest)
    # a bone along one side from z = 10 to 150: the origin's area is its part below 60
    side = (V[:, 0] < -15) & (V[:, 2] > 10) & (V[:, 2] < 150)
    o, i, rules = areas_on_bones(V, F, rest, side, None)
    assert rules == ("bones", "ends")
    np.testing.assert_array_equal(o, np.flatnonzero(side & (V[:, 2] < 60)))
    np.testing.assert_array_equal(i, caps[1])
    # the muscle's half, where asked
    o, _, _ = areas_on_bones(V, F, rest, side, None, end_part=0.5)
    np.testing.assert_array_equal(o, np.flatnonzero(side & (V[:, 2] < 100)))
    # a bone from z = 60 to 185 as the insertion's: its part above 140
    top = (V[:, 0] < -15) & (V[:, 2] > 60) & (V[:, 2] < 185)
    o, i, rules = areas_on_bones(V, F, rest, None, top)
    assert rules == ("ends", "bones")
    np.testing.assert_array_equal(i, np.flatnonzero(top & (V[:, 2] > 140)))
    np.testing.assert_array_equal(o, caps[0])
    # a bone of the origin's body that the muscle lies on only further on (the psoas over
    # the pelvic brim) is no origin: the cap
    brim = (V[:, 0] < -15) & (V[:, 2] > 100) & (V[:, 2] < 160)
    o, _, rules = areas_on_bones(V, F, rest, brim, None)
    assert rules[0] == "ends"
    np.testing.assert_array_equal(o, caps[0])
    # nor one near its end but far from where the path starts (a joint it passes over:
    # 44 mm and more from the first point, past 0.15 of the line's 200); beside a patch
    # that reaches the start, only that one counts
    over = (V[:, 0] < -15) & (V[:, 2] > 40) & (V[:, 2] < 58)
    assert over.sum() >= 3 and areas_on_bones(V, F, rest, over, None, least=3)[2][0] == "ends"
    start = (V[:, 0] > 15) & (V[:, 2] > 10) & (V[:, 2] < 40)
    o, _, rules = areas_on_bones(V, F, rest, over | start, None)
    assert rules[0] == "bones"
    np.testing.assert_array_equal(o, np.flatnonzero(start))
    assert areas_on_bones(V, F, rest, over, None, end_reach=0.4, least=3)[2][0] == "bones"
    # too few vertices: the cap; fewer than `least` is the rule
    few = np.zeros(len(V), dtype=bool)
    few[np.flatnonzero(side & (V[:, 2] < 30))[:3]] = True
    assert few.sum() == 3
    assert areas_on_bones(V, F, rest, few, None)[2][0] == "ends"
    assert areas_on_bones(V, F, rest, few, None, least=3)[2][0] == "bones"
    with pytest.raises(ValueError, match="a mask per vertex"):
        areas_on_bones(V, F, rest, side[:-1], None)


def test_fibres_start_along_a_side_attachment_not_at_the_cap():
    """A muscle attached along one side (a fan, as the gluteus maximus along the iliac
    crest): its fibres start spread over that side, where the end caps gather them."""
    m = Muscle.from_mesh(*capsule(n_around=32, cap_rings=8, segments=40), cage_size=200)
    rest, _ = capsule_scenario("bend")
    V = m.V
    side = (V[:, 0] < -12) & (V[:, 2] > 10) & (V[:, 2] < 100)
    o, i, _ = areas_on_bones(V, m.F, rest, side, None, end_part=0.5)
    fb = fibres_at_rest(m, rest, count=40, voxels=30_000, origin=o, insertion=i)
    capped = fibres_at_rest(m, rest, count=40, voxels=30_000)
    h = 2 * fb.spacing
    start = fb.points[:, 0]
    assert (start[:, 0] < -12 + h).all()  # on the attachment
    # spread along it: over most of its 90 mm (86 here), against the cap's 20 mm (17)
    assert np.ptp(start[:, 2]) > 70 and np.ptp(capped.points[:, 0, 2]) < 20 + h


@pytest.mark.realdata
def test_fibres_of_a_real_muscle_stay_inside_it_bent_and_shortened(data_dir):
    import igl

    from musclewrap.synthetic import principal_axis_scenario

    m = Muscle.from_file(data_dir / "vhf" / "VHF_Right_Muscle_RectusFemoris_smooth.stl")
    rest, cur = principal_axis_scenario(m.V, "bend_short")
    fb = fibres_at_rest(m, rest)  # the defaults: 100 fibres of 15 points
    assert fb.points.shape == (100, 15, 3)
    assert (igl.fast_winding_number(m.V, m.F, fb.points.reshape(-1, 3)) > 0.5).all()
    r = m.bind(rest).deform(cur)
    assert r.converged
    w = igl.fast_winding_number(r.V, m.F, fb.at(r.cage).reshape(-1, 3))
    assert (w > 0.5).all()
    # the line is 15 % shorter: the fibres shorten with it (0.82-0.89 of their length here)
    ratio = fb.lengths(fb.at(r.cage)) / fb.lengths()
    assert (ratio < 0.95).all() and (ratio > 0.75).all()
    assert abs(ratio.mean() - 0.85) < 0.03


def test_fibres_run_through_a_tendon_two_cells_thin():
    """A belly of radius 20 ending in a tendon of radius 1.6 (about two grid cells across).

    Streamlines of a voxel field leave so thin a passage or stall at its staircase walls
    (the LHDL psoas's tendon kept 4 of 100 fibres so); the tracer slides along the walls
    and, where that fails, climbs the field cell by cell, so every fibre reaches the end.
    """
    import igl

    from musclewrap.synthetic import rings_mesh

    z = np.concatenate([[0.0], np.linspace(2, 150, 40), np.linspace(158, 228, 15), [230.0]])
    r = np.concatenate([[0.0], 20 * np.sin(np.linspace(0.3, 1.75, 40)), np.full(15, 1.6), [0]])
    r[41:44] = [8.0, 4.0, 2.2]  # the belly narrows into the tendon
    m = Muscle.from_mesh(*rings_mesh(z, r, 24), cage_size=150)
    rest = {"line": np.array([[0.0, 0, 0], [0, 0, 115], [0, 0, 230]])}
    fb = fibres_at_rest(m, rest, count=40)
    assert (igl.fast_winding_number(m.V, m.F, fb.points.reshape(-1, 3)) > 0.5).all()
    assert fb.points[:, -1, 2].min() > 0.9 * 230 - 2 * fb.spacing
    assert fb.points[:, 0, 2].max() < 0.1 * 230 + 2 * fb.spacing


def test_points_outside_a_surface_are_moved_just_inside_it():
    import igl

    from musclewrap.fibres import keep_inside

    V, F = capsule(n_around=32, cap_rings=8, segments=20)  # radius 20 along z, 0..200
    rng = np.random.default_rng(3)
    inside = np.column_stack([rng.uniform(-10, 10, (50, 2)), rng.uniform(30, 170, 50)])
    outside = np.array([[25.0, 0, 100], [0, -23, 50], [0, 0, -4], [0, 0, 230]])
    P, moved, farthest, left = keep_inside(np.vstack([inside, outside]), V, F, depth=0.1)
    assert moved == 4 and left == 0
    np.testing.assert_array_equal(P[:50], inside)  # inside points are not touched
    w = igl.fast_winding_number(V, F, P[50:])
    assert (w > 0.5).all()
    # each lands about depth inside its closest surface point: |P| = 20 - 0.1 on the side
    assert abs(np.hypot(*P[50, :2]) - 19.9) < 0.05 and abs(np.hypot(*P[51, :2]) - 19.9) < 0.05
    assert farthest == pytest.approx(30.1, abs=0.2)  # the point 30 beyond the far pole
    same, n, _, _ = keep_inside(inside, V, F, depth=0.1)
    assert n == 0 and (same == inside).all()
