"""Contact along a path from the rest pose (issue 23): the waypoints' lattice, and real
activities past the model's ranges, checked independently against the full-resolution bones.
"""

import dataclasses
from pathlib import Path

import numpy as np
import pytest

from musclewrap.scene import load_scene, random_motion, read_motion, run_scene, write_motion
from musclewrap.scene._drive import lattice_parent, lattice_paths

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"
HIP = ("hip_flexion_r", "hip_adduction_r", "hip_rotation_r")


# ------------------------------------------------------------------ the lattice
def test_lattice_parent_walks_the_straight_line_to_the_rest_pose():
    rng = np.random.default_rng(3)
    for u in rng.uniform(-14, 14, size=(300, 3)):
        chain = [u]
        while np.any(chain[-1] != 0):
            chain.append(lattice_parent(chain[-1]))
            assert len(chain) < 30
        # a pose's first waypoint is a lattice point within one and a half steps of it
        assert np.abs(u - chain[1]).max() <= 1.5
        for a, b in zip(chain[1:-1], chain[2:], strict=False):
            # each a lattice point, one step nearer the rest pose in the largest coordinate,
            # never more than one step from its child in any coordinate
            assert np.array_equal(a, np.round(a))
            assert np.abs(b).max() == np.abs(a).max() - 1
            assert np.abs(a - b).max() <= 1
        # the rounding drifts, but the way stays near the straight line to the rest pose
        # (2.6 steps at most over 3000 poses up to 14 steps out)
        d = u / np.linalg.norm(u)
        for p in chain[1:]:
            assert np.linalg.norm(p - (p @ d) * d) <= 3.0


def test_a_poses_waypoint_depends_on_the_pose_alone():
    rng = np.random.default_rng(5)
    U = np.cumsum(rng.normal(0, 0.3, size=(120, 3)), axis=0)
    nodes, parent, at = lattice_paths(U)
    # parents first, every node's parent is its lattice parent
    for k, (n, p) in enumerate(zip(nodes, parent, strict=True)):
        assert p < k
        want = lattice_parent(n)
        assert np.array_equal(want, np.zeros(3)) if p < 0 else np.array_equal(nodes[p], want)
    # the same poses among other frames, or alone, in another order: the same waypoints
    sub = U[::7][::-1]
    n2, p2, at2 = lattice_paths(sub)
    for u, a, a2 in zip(sub, at[::7][::-1], at2, strict=True):
        assert np.array_equal(nodes[a] if a >= 0 else 0 * u, n2[a2] if a2 >= 0 else 0 * u)
    # rest pose and its neighbourhood: no waypoint
    n0, _, a0 = lattice_paths(np.array([[0.0, 0.0, 0.0], [0.4, -0.9, 0.2]]))
    assert len(n0) == 0 and list(a0) == [-1, -1]


def test_random_motion_is_smooth_seeded_and_in_range(tmp_path):
    ranges = {"a": (-10.0, 90.0), "b": (-30.0, 30.0)}
    t, cols = random_motion(ranges, seconds=3.0, rate=100.0, seed=7)
    t2, cols2 = random_motion(ranges, seconds=3.0, rate=100.0, seed=7)
    _, cols3 = random_motion(ranges, seconds=3.0, rate=100.0, seed=8)
    assert len(t) == 301 and np.array_equal(cols["a"], cols2["a"])
    assert not np.allclose(cols["a"], cols3["a"])
    for k, (lo, hi) in ranges.items():
        v = cols[k]
        assert v.min() >= lo and v.max() <= hi
        assert np.ptp(v) > 0.3 * (hi - lo)  # it does move through its range
        # smooth: no jump between frames beyond what the knots' spacing allows
        assert np.abs(np.diff(v)).max() <= 3 * (hi - lo) * 1.5 / 100
    path = write_motion(tmp_path / "m.mot", t, cols)
    m = read_motion(path)
    # to the bit: a pose written and run is the pose asked for (ten decimals moved the
    # viewer's written pose of the LHDL walk by 5e-11 deg, and its iliacus by 0.04 mm)
    assert m.in_degrees and np.array_equal(m.time, t)
    assert all(np.array_equal(m.columns[k], cols[k]) for k in cols)
    tiny = write_motion(tmp_path / "t.mot", np.array([0.0, 1e-7]), {"a": np.array([1e-300, -2.5])})
    assert np.array_equal(read_motion(tiny).columns["a"], [1e-300, -2.5])
    with pytest.raises(ValueError, match="increasing"):
        write_motion(tmp_path / "bad.mot", t[::-1], cols)
    assert not (tmp_path / "bad.mot").exists()


# ------------------------------------------------------------------ real activities
def _check(scene, out, frames, rows, *, shape=0.5):
    """The issue's targets on every frame, by the run's report and the independent check.

    ``shape``: the bound on the shape change, or per muscle (a dict, 0.5 for the others).
    With two or more muscles, none more than 0.5 inside another (issue 24).
    """
    from musclewrap.run._verify import verify_run

    bound = shape if isinstance(shape, dict) else {}
    for r in rows:
        assert r["converged"], r
        assert abs(r["relative_volume_error"]) <= 1e-9, r
        assert r["penetration_depth_max"] <= 0.5, r
        assert r["bone_inside_depth_max"] <= 1.0, r
        assert r["shape_change_max"] <= bound.get(r["muscle"], 0.5 if bound else shape), r
        if len(scene.muscles) > 1:
            assert r["muscle_overlap_max"] <= 0.5, r
        # where the model's line itself runs through a bone it cannot be followed there
        if r["line_inside_depth_max"] <= 0.5:
            assert r["skeleton_fit_mean"] <= 1.5, r
    checked = verify_run(scene, out, frames)
    assert len(checked) == len(rows)
    for r in checked:
        assert r["muscle_in_bone"] <= 0.5, r
        assert r["bone_in_muscle"] <= 1.0, r
        assert abs(r["relative_volume_error"]) <= 1e-9, r
        assert r["muscle_in_muscle"] <= 0.5, r
    return checked


def _meshes(out: Path, muscles, frames) -> dict[str, bytes]:
    return {
        f"{m}_{k:04d}": (out / m / f"{m}_{k:04d}.vtp").read_bytes() for m in muscles for k in frames
    }


@pytest.mark.realdata
@pytest.mark.slow
def test_deep_squat_through_its_deepest_frames(data_dir, tmp_path):
    """The OpenCap deep squat past the model's hip flexion range (106 deg), frame by frame
    independent of which other frames were run, on how many workers."""
    scene = load_scene(EXAMPLES / "lhdl_squat.toml")
    frames = "700:740:4"  # hip flexion 99-106 deg, the ischium under the gluteus maximus
    common = dict(cache_dir=tmp_path / "c", progress=None, render=False)
    s = run_scene(scene, tmp_path / "a", frames=frames, workers=2, **common)
    assert len(s.rows) == 4 * 10
    assert any("hip_flexion_r leaves the model's range [-10, 90] deg" in n for n in s.notes)
    # the 0.5 on every muscle: the gluteus medius creased to 0.60 on frame 724 with
    # stiffer contact conditions (contact_softness 0.1; 0.32 at 0.5: BENCHMARKS.md,
    # "Thresholds, either side"). The gluteus maximus was 0.5008 on frame 708 (e9449e0 to
    # 21dfc5e's parent): the bones' cage steps folded it away from the bones, and the
    # rounds took it over 0.5; with those folds ironed out (`contact.unfold`) it is 0.38
    # on the squat every 4th frame (BENCHMARKS.md, "Where the gluteus maximus creases")
    _check(scene, tmp_path / "a", frames, s.rows)
    # the gluteus maximus's line runs through the femur on these frames: said how deep
    gm = [r for r in s.rows if r["muscle"] == "gluteus_maximus"]
    assert max(r["line_inside_depth_max"] for r in gm) > 3.0
    # contact wins there: how far the surface left its line, and the fit where it is free
    assert max(r["lines_conflict_max"] for r in gm) > 3.0
    assert all(np.isfinite(r["skeleton_fit_free"]) for r in s.rows)
    assert any(n.startswith("gluteus_maximus: on ") and "contact wins" in n for n in s.notes)
    # other frames around them, one worker, another chunking: the same files, byte for byte
    s1 = run_scene(scene, tmp_path / "b", frames="716:741:8", workers=1, **common)
    assert len(s1.rows) == 4 * 4
    names = [m.name for m in scene.muscles]
    a = _meshes(tmp_path / "a", names, (716, 724, 732))
    assert a == _meshes(tmp_path / "b", names, (716, 724, 732))


def _hip_motion(tmp_path: Path, name: str, time, cols) -> Path:
    return write_motion(tmp_path / f"{name}.mot", time, cols)


def _scene_with(tmp_path: Path, motion: Path, muscles=("gluteus_maximus", "iliacus")):
    scene = load_scene(EXAMPLES / "lhdl_walk.toml")
    return dataclasses.replace(
        scene,
        motions=(motion,),
        muscles=tuple(m for m in scene.muscles if m.name in muscles),
        paper_frames=0,
    )


@pytest.mark.realdata
@pytest.mark.slow
def test_hip_flexed_to_120_deg_with_adduction_and_rotation(data_dir, tmp_path):
    """An extreme motion of our own: flexion to 120 deg (30 past the model's range) while
    the hip adducts and rotates both ways by 20 deg."""
    t = np.linspace(0.0, 3.0, 61)
    s = np.sin(np.pi * t / 3.0) ** 2  # 0 -> 1 -> 0
    cols = {
        "hip_flexion_r": 1.576 + (120.0 - 1.576) * s,
        "hip_adduction_r": -4.727 + 24.727 * s * np.sin(2 * np.pi * t / 1.5),
        "hip_rotation_r": -5.29 + 25.29 * s * np.cos(2 * np.pi * t / 2.0),
    }
    scene = _scene_with(tmp_path, _hip_motion(tmp_path, "extreme", t, cols))
    frames = "0:61:3"
    r = run_scene(
        scene, tmp_path / "o", frames=frames, workers=2, cache_dir=tmp_path / "c",
        progress=None, render=False,
    )  # fmt: skip
    assert any("hip_flexion_r leaves the model's range" in n for n in r.notes)
    assert any("up to 120 deg" in n or "up to 119." in n for n in r.notes)
    # Contact holds (no vertex of either inside the other), but not the shape: where the
    # bones push the gluteus maximus 20 mm (15 mm into the iliacus), the cage's step creases
    # it (1.04 at 120 deg with the muscles turned by their paths' bodies, 0.75 with the
    # reference point's twist, both with contact_softness 0.1; without contact 0.44 and 20 mm
    # inside the bones). Since the steps' folds are ironed out (`contact.unfold`): the
    # gluteus maximus up to 0.65, over 0.5 on 2 of these 21 frames (5 before), the iliacus
    # up to 0.74 on 6 (7; with all four hip muscles its solve alone gave it 0.51-0.55
    # there). With the iliacus's cage of 150 (2026-11-29): the gluteus maximus <= 0.44, the
    # iliacus up to 0.65 on 5 (the whole scene's four muscles: <= 0.49, the iliacus 0.37,
    # `bench_motions.py`). Measured, not the issue's 0.5: see BENCHMARKS.md ("Where the
    # gluteus maximus creases past 100 deg").
    _check(scene, tmp_path / "o", frames, r.rows, shape=0.8)


@pytest.mark.realdata
@pytest.mark.slow
def test_random_smooth_motions_inside_the_models_ranges(data_dir, tmp_path):
    """Seeded random motions of all three hip coordinates over the model's whole ranges."""
    from musclewrap.scene import OpenSimModel

    scene = load_scene(EXAMPLES / "lhdl_walk.toml")
    model = OpenSimModel(scene.osim)
    ranges = {c: tuple(np.degrees(model.coordinate_range(c))) for c in HIP}
    for seed in (1, 2):
        t, cols = random_motion(ranges, seconds=3.0, rate=20.0, knots_per_second=1.5, seed=seed)
        sc = _scene_with(tmp_path, _hip_motion(tmp_path, f"random{seed}", t, cols))
        out = tmp_path / f"o{seed}"
        r = run_scene(
            sc, out, frames="0:61:2", workers=2, cache_dir=tmp_path / "c", progress=None,
            render=False,
        )  # fmt: skip
        assert not any("leaves the model's range" in n for n in r.notes)
        _check(sc, out, "0:61:2", r.rows)


@pytest.mark.realdata
def test_a_waypoint_that_does_not_converge_is_named_in_the_notes(data_dir, tmp_path):
    """The path's own solves are reported, with the waypoint's pose in the model's words."""
    scene = load_scene(EXAMPLES / "lhdl_walk.toml")
    psoas = next(m for m in scene.muscles if m.name == "psoas")
    scene = dataclasses.replace(
        scene, muscles=(dataclasses.replace(psoas, max_iterations=1),), paper_frames=0
    )
    r = run_scene(
        scene, tmp_path / "o", frames="0:211:30", workers=1, cache_dir=tmp_path / "c",
        progress=None, render=False,
    )  # fmt: skip
    notes = [n for n in r.notes if n.startswith("psoas: ") and "waypoints on the path" in n]
    assert len(notes) == 1, r.notes
    assert "hip_flexion_r " in notes[0] and " deg" in notes[0]
    assert "did not converge" in notes[0] and "iteration" in notes[0]


@pytest.mark.realdata
def test_a_motion_that_turns_a_joint_the_other_way_from_the_model_is_named(data_dir):
    """gait2392's walk flexes the knee negative, Rajagopal 2016 positive (0..120 deg): the
    knees are named, with the fix, against Rajagopal and not against gait2392; OpenCap's
    squat, written for Rajagopal's sign, is named against gait2392. Negated in the file,
    the knee is no longer named, nor where it leaves the range on less than half the frames
    (issue 46's hard case: `init` and `check` said nothing)."""
    from musclewrap.model import OpenSimModel
    from musclewrap.run._check import CheckReport, _check_model
    from musclewrap.scene import reversed_coordinates

    scene = load_scene(EXAMPLES / "gait2392_leg.toml")
    motions = data_dir / "opensim" / "motions"
    walk = read_motion(motions / "subject01_walk1_ik.mot")
    squat = read_motion(motions / "opencap_squat_videoAndMocap.mot")
    raj = OpenSimModel(data_dir / "opensim" / "models" / "Rajagopal2016.osim")
    g = OpenSimModel(scene.osim)
    coords = ["hip_flexion_r", "hip_adduction_r", "knee_angle_r", "knee_angle_l", "ankle_angle_r"]
    assert reversed_coordinates(scene, walk, raj, coords) == ["knee_angle_r", "knee_angle_l"]
    assert reversed_coordinates(scene, walk, g, coords) == []
    assert reversed_coordinates(scene, squat, g, coords) == ["knee_angle_r", "knee_angle_l"]
    knee = -walk.columns["knee_angle_r"]
    negated = dataclasses.replace(walk, columns=dict(walk.columns, knee_angle_r=knee))
    assert reversed_coordinates(scene, negated, raj, coords) == ["knee_angle_l"]
    # outside the range on 30 % of the frames (less than half): not a sign
    some = np.where(np.arange(len(knee)) < 0.3 * len(knee), -knee, knee)
    partly = dataclasses.replace(walk, columns=dict(walk.columns, knee_angle_r=some))
    assert reversed_coordinates(scene, partly, raj, coords) == ["knee_angle_l"]
    # the check says it, with the fix (a scene of no meshes: the model's side alone)
    bare = dataclasses.replace(
        scene, muscles=(), bones=(), motions=(motions / "subject01_walk1_ik.mot",)
    )
    rep = CheckReport(Path("scene.toml"))
    assert _check_model(bare, raj, rep)
    said = [f for f in rep.findings if f.level == "warning" and f.subject == "knee_angle_r"]
    assert len(said) == 1 and "Rajagopal2016.osim's range [0, 120] deg" in said[0].message
    assert said[0].fix.startswith("negate the column 'knee_angle_r' in subject01_walk1_ik.mot")
