"""A user's own subject: the name table, ``musclewrap init`` and ``musclewrap check``."""

from __future__ import annotations

import re
import shutil
from pathlib import Path

import numpy as np
import pytest

from musclewrap.cli import main
from musclewrap.errors import SceneError
from musclewrap.model._names import (
    match_bone,
    match_muscle,
    mesh_name_tokens,
    path_anatomy,
    split_path_name,
)
from musclewrap.scene import check_scene, load_scene, run_scene
from musclewrap.subject import init_scene

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"

# OpenCap's LaiUhlrich2022 and LaiArnoldModified2017 keep Rajagopal 2016's names (their
# model files are not in ../shared/data; this is their right leg's list)
LAI_RIGHT = (
    "addbrev_r addlong_r addmagDist_r addmagIsch_r addmagMid_r addmagProx_r bflh_r bfsh_r "
    "edl_r ehl_r fdl_r fhl_r gaslat_r gasmed_r glmax1_r glmax2_r glmax3_r glmed1_r glmed2_r "
    "glmed3_r glmin1_r glmin2_r glmin3_r grac_r iliacus_r perbrev_r perlong_r piri_r psoas_r "
    "recfem_r sart_r semimem_r semiten_r soleus_r tfl_r tibant_r tibpost_r vasint_r vaslat_r "
    "vasmed_r"
).split()


# ---------------------------------------------------------------------------- the table
def test_path_names_split_into_stem_part_side():
    assert split_path_name("glut_max2_r") == ("glut_max", "2", "r")
    assert split_path_name("addmagIsch_l") == ("addmag", "Isch", "l")
    assert split_path_name("psoas_r") == ("psoas", "", "r")
    assert split_path_name("ercspn_r") == ("ercspn", "", "r")
    assert split_path_name("iliacus") == ("iliacus", "", None)


def test_mesh_file_names_give_words_and_side():
    assert mesh_name_tokens("VHF_Left_Muscle_BicepsFemorisLong_smooth")[1] == "l"
    assert mesh_name_tokens("LHDL_R_GluteusMaximus")[1] == "r"
    assert mesh_name_tokens("r_femur") == (["r", "femur"], "r")
    assert mesh_name_tokens("sacrum")[1] is None


def _expected(stem: str) -> str:
    return {
        "glut_max": "gluteus_maximus", "glmax": "gluteus_maximus", "glut_med": "gluteus_medius",
        "glmed": "gluteus_medius", "bifemlh": "biceps_femoris_long", "bflh": "biceps_femoris_long",
        "bifemsh": "biceps_femoris_short", "bfsh": "biceps_femoris_short",
        "rect_fem": "rectus_femoris", "recfem": "rectus_femoris", "sar": "sartorius",
        "sart": "sartorius", "add_mag": "adductor_magnus", "addmag": "adductor_magnus",
        "iliacus": "iliacus", "psoas": "psoas", "med_gas": "gastrocnemius_medial",
        "gasmed": "gastrocnemius_medial", "peri": "piriformis", "piri": "piriformis",
    }.get(stem, "")  # fmt: skip


def _model_muscles(path: Path) -> list[str]:
    from musclewrap.scene import OpenSimModel

    return list(OpenSimModel(path).path_names)


@pytest.mark.parametrize(
    "model",
    [
        "opensim/models/gait2392_thelen2003muscle.osim",
        "opensim/models/subject01_simbody.osim",
        "opensim/models/Rajagopal2016.osim",
        "lhdl/model/LHDL_hip_r.osim",
        "LaiUhlrich2022 (Rajagopal's names)",
    ],
)
def test_name_table_knows_every_muscle_of_the_model(data_dir, model):
    names = LAI_RIGHT if model.startswith("Lai") else _model_muscles(data_dir / model)
    assert len(names) >= 8
    for n in names:
        found = path_anatomy(n)
        assert found is not None, f"{model}: {n} is not in the name table"
        anatomy, side = found
        assert side == n[-1], n  # every path of these models ends in _r or _l
        stem = split_path_name(n)[0]
        if _expected(stem):
            assert anatomy.name == _expected(stem), n
    # one muscle to several paths where the model splits it
    by = {}
    for n in names:
        a, side = path_anatomy(n)  # type: ignore[misc]
        by.setdefault((a.name, side), []).append(n)
    if "glut_max1_r" in names:
        assert by[("gluteus_maximus", "r")] == ["glut_max1_r", "glut_max2_r", "glut_max3_r"]
    if "addmagDist_r" in names:
        assert len(by[("adductor_magnus", "r")]) == 4


def test_mesh_names_of_the_data_are_classified(data_dir):
    """Every file of ../shared/data's mesh folders: muscles by muscle, bones and cartilages."""
    want = {
        "VHF_Right_Muscle_Illiacus_smooth": "iliacus",  # misspelt in the data
        "VHF_Right_Muscle_Semitendonosus_smooth": "semitendinosus",  # likewise
        "VHF_Right_Muscle_PsoasMajor_smooth": "psoas",
        "VHF_Left_Muscle_BicepsFemorisLong_smooth": "biceps_femoris_long",
        "VHF_Right_Muscle_BicepsFemorisShortHead_smooth": "biceps_femoris_short",
        "VHF_Right_Muscle_TensorFasciaeLatae_smooth": "tensor_fasciae_latae",
        "LHDL_R_GluteusMaximus": "gluteus_maximus",
    }
    files = sorted((data_dir / "vhf").glob("*.stl")) + sorted((data_dir / "lhdl").glob("*/*.vtk"))
    files += sorted((data_dir / "opensim" / "Geometry").glob("*.vtp"))
    for f in files:
        stem = f.name.rsplit(".", 1)[0]
        m, b = match_muscle(stem), match_bone(stem)
        if "Muscle" in stem or "LHDL_R_G" in stem or stem in ("LHDL_R_Iliacus", "LHDL_R_Psoas"):
            assert m is not None and b is None, stem
            if stem in want:
                assert m.name == want[stem], stem
        else:
            assert m is None and b is not None, stem
    assert match_bone("VHF_Right_Cartilage_FemurHead_smooth") == (
        match_bone("VHF_Right_Cartilage_FemurHead_smooth")[0],  # type: ignore[index]
        True,
    )
    assert match_bone("VHF_Right_Cartilage_FemurHead_smooth")[0].name == "femoral_head"  # type: ignore[index]
    assert match_bone("LHDL_R_Iliac")[0].name == "iliac"  # type: ignore[index]
    # muscles that differ in one word are not taken for each other
    assert match_muscle("GluteusMinimus").name == "gluteus_minimus"  # type: ignore[union-attr]
    assert match_muscle("VastusMedialis").name == "vastus_medialis"  # type: ignore[union-attr]
    assert match_muscle("scan_0042") is None


#: abbreviations a scan's labels use for the VHF folder's muscles
_ABBREVIATED = {
    "AdductorBrevis": "AB", "AdductorLongus": "AL", "AdductorMagnus": "AM",
    "BicepsFemorisShortHead": "BFsh", "BicepsFemorisLong": "BFlh", "GluteusMaximus": "GMax",
    "GluteusMedius": "GMed", "GluteusMinimus": "GMin", "Gracilis": "GR", "Illiacus": "IL",
    "Pectineus": "PEC", "PsoasMajor": "PS", "RectusFemoris": "RF", "Sartorius": "SR",
    "Semimembranosus": "SM", "Semitendonosus": "ST", "TensorFasciaeLatae": "TFL",
    "VastusIntermedius": "VI", "VastusLateralis": "VL", "VastusMedialis": "VM",
}  # fmt: skip


def _snake(camel: str) -> str:
    return re.sub(r"(?<!^)(?=[A-Z])", "_", camel).lower()


#: the VHF folder's names (``VHF_<Side>_<Kind>_<Name>_smooth``) as other folders write them:
#: (side "Right"/"Left", kind "Muscle"/"Bone"/"Cartilage", CamelName) -> stem
RENAMED = {
    "another subject's prefix": lambda s, k, n: f"Subj07_{s}_{k}_{n}_smooth",
    "subject and side letter first": lambda s, k, n: f"S07_{s[0]}_{_snake(n)}",
    "side spelt out last": lambda s, k, n: f"{n}_{s.lower()}",
    "snake case, side letter last": lambda s, k, n: f"{_snake(n)}_{s[0].lower()}",
    "BIDS-like labels": lambda s, k, n: f"sub-03_hemi-{s[0]}_label-{n.lower()}",
    "upper case": lambda s, k, n: f"{s.upper()}_{_snake(n).upper()}",
    "spaces and a number": lambda s, k, n: f"{k} {len(n)} - {_snake(n).replace('_', ' ').title()} ({s[0]})",
    "side letter glued on": lambda s, k, n: f"{s[0]}{n}",
    "hyphens": lambda s, k, n: f"{_snake(n).replace('_', '-')}-{s[0]}",
    "abbreviations": lambda s, k, n: f"Subject12_{s}_{_ABBREVIATED.get(n, n)}",
    "a typo": lambda s, k, n: f"{s}_{_typo(n)}",
}  # fmt: skip


def _typo(camel: str) -> str:
    """The name with its fourth letter doubled (``GluteusMaximus`` -> ``GlutteusMaximus``)."""
    return camel[:4] + camel[3] + camel[4:]


def _vhf_names(data_dir: Path) -> list[tuple[Path, tuple[str, str, str]]]:
    out = []
    for f in sorted((data_dir / "vhf").glob("*.stl")):
        _, side, kind, name, _ = f.stem.split("_")
        out.append((f, (side, kind, name)))
    return out


def _classified(stem: str) -> tuple[str, str, str | None]:
    m, b = match_muscle(stem), match_bone(stem)
    side = mesh_name_tokens(stem)[1]
    if m is not None and (b is None or len(m.run) > len(b[0].run)):
        return "muscle", m.name, side
    assert b is not None, stem
    return ("landmark" if b[1] else "bone"), b[0].name, side


@pytest.mark.parametrize("style", sorted(RENAMED))
def test_a_renamed_folder_names_the_same_muscles_bones_and_sides(data_dir, style):
    """Issue 47: the VHF folder's files renamed as other folders name them are taken for
    the same muscle, bone or cartilage, on the same side, with nothing ambiguous."""
    for f, parts in _vhf_names(data_dir):
        renamed = RENAMED[style](*parts)
        assert _classified(renamed) == _classified(f.stem), (style, renamed)
        m = match_muscle(renamed)
        assert m is None or not m.others, (renamed, m)


def test_names_ties_are_said_and_words_must_be_whole():
    # one letter from two muscles: both said
    m = match_muscle("GluteusMiximus")  # maximus or minimus?
    assert m is not None and m.others, m
    # an abbreviation counts only as a whole word; a full name beats one
    assert match_muscle("Revolved") is None
    assert match_muscle("AB12_Gracilis").name == "gracilis"  # type: ignore[union-attr]
    # typos only on long runs, by a letter or two
    assert match_muscle("Solus").name == "soleus"  # type: ignore[union-attr]
    assert match_muscle("Grcls") is None


# ---------------------------------------------------------------------------- init
def _folder_of(scene, where: Path) -> Path:
    """A folder holding (links to) just the meshes a scene names."""
    where.mkdir(parents=True, exist_ok=True)
    files = [m.mesh for m in scene.muscles] + [b.mesh for b in scene.bones]
    if scene.registration is not None:
        files += [lm.mesh for lm in scene.registration.landmarks]
    for f in set(files):
        (where / f.name).symlink_to(f)
    return where


def _mapping(scene) -> dict:
    return {
        "muscles": {m.name: (m.paths, m.body, m.mesh.resolve()) for m in scene.muscles},
        "bones": {b.name: (b.body, b.mesh.resolve()) for b in scene.bones},
        "units": (scene.mesh_unit, scene.model_unit),
        "coordinates": scene.coordinates,
        "rest": {k: round(v, 3) for k, v in scene.rest_pose.items()},
        "output": scene.output_frame,
        "frames": sorted({m.frame for m in scene.muscles}),
        "registration": None
        if scene.registration is None
        else (
            scene.registration.axes,
            [(lm.name, lm.fit, lm.body, lm.mesh.resolve()) for lm in scene.registration.landmarks],
        ),
    }


@pytest.mark.parametrize("example", sorted(p.name for p in EXAMPLES.glob("*.toml")))
def test_init_writes_the_hand_written_scene(data_dir, tmp_path, example):
    hand = load_scene(EXAMPLES / example)
    folder = _folder_of(hand, tmp_path / "meshes")
    r = init_scene(hand.osim, folder, tmp_path / "scene.toml", motion=hand.motions[0])
    assert not r.unplaced
    made = load_scene(r.scene)
    want = _mapping(hand)
    if example == "gait2392_leg.toml":
        # its hip's rest angles are the VHF scan's, which `check` fits to the model's pelvis
        # and sacrum (test_scene.py): init writes the model's zero, as the scene had it
        want["rest"].update(hip_flexion_r=0.0, hip_adduction_r=0.0)
    assert _mapping(made) == want
    text = r.scene.read_text()
    assert "by name (exact)" in text and "inside it" in text  # each guess says how sure
    rep = check_scene(made)
    assert rep.ok, [str(f) for f in rep.errors]


@pytest.mark.parametrize("example", ["lhdl_walk.toml", "gait2392_walk.toml"])
def test_init_scene_runs_as_the_hand_written_one(data_dir, tmp_path, example):
    """The same files, frame for frame (the hand-tuned cage of the LHDL iliacus carried over)."""
    hand = load_scene(EXAMPLES / example)
    folder = _folder_of(hand, tmp_path / "meshes")
    r = init_scene(hand.osim, folder, tmp_path / "scene.toml", motion=hand.motion)
    text = r.scene.read_text()
    for m in hand.muscles:  # the example's own tuning, which no guess can know
        if m.cage_size != 300:
            text = text.replace(
                f"[muscles.{m.name}]\n", f"[muscles.{m.name}]\ncage_size = {m.cage_size}\n"
            )
    r.scene.write_text(text)
    made = load_scene(r.scene)
    a, b = tmp_path / "hand", tmp_path / "made"
    for sc, out in ((hand, a), (made, b)):
        run_scene(sc, out, frames="0:211:105", render=False, progress=None)
    for m in hand.muscles:
        fa = sorted((a / m.name).glob(f"{m.name}_[0-9]*.vtp"))
        fb = sorted((b / m.name).glob(f"{m.name}_[0-9]*.vtp"))
        assert [f.name for f in fa] == [f.name for f in fb] and fa
        from musclewrap.mesh import read_mesh

        for x, y in zip(fa, fb, strict=True):
            Va, Fa = read_mesh(x)
            Vb, Fb = read_mesh(y)
            assert np.array_equal(Fa, Fb)
            assert np.abs(Va - Vb).max() <= 1e-9 * np.ptp(Va, axis=0).max()


def test_init_on_the_vhf_folder_finds_every_gait2392_muscle(data_dir, tmp_path):
    r = init_scene(
        data_dir / "opensim/models/subject01_simbody.osim",
        data_dir / "vhf",
        tmp_path / "vhf.toml",
        motion=data_dir / "opensim/motions/subject01_walk1_ik.mot",
    )
    sc = load_scene(r.scene)
    # all 20 muscle files of the folder: the 19 right ones and the left long head of the
    # biceps femoris, on its left path
    assert len(sc.muscles) == 20 and not r.unplaced
    paths = {m.name: m.paths for m in sc.muscles}
    assert paths["biceps_femoris_long_left"] == ("bifemlh_l",)
    assert paths["adductor_magnus"] == ("add_mag1_r", "add_mag2_r", "add_mag3_r")
    assert paths["iliacus"] == ("iliacus_r",) and paths["semitendinosus"] == ("semiten_r",)
    assert paths["tensor_fasciae_latae"] == ("tfl_r",)
    assert sc.registration is not None and sc.registration.axes == ("y", "z", "x")
    assert [lm.name for lm in sc.registration.landmarks] == ["hip", "knee"]
    assert {b.name: b.body for b in sc.bones} == {
        "patella": "tibia_r", "tibia": "tibia_r", "femur_distal": "femur_r",
        "femoral_head": "femur_r", "acetabulum": "pelvis",
    }  # fmt: skip
    assert "knee_angle_l" in sc.coordinates  # the left muscle's joints are driven too
    rep = check_scene(sc)
    assert rep.ok, [str(f) for f in rep.errors]


def test_init_takes_the_models_bones_the_folder_lacks(data_dir, tmp_path):
    """``--model-bones``: the VHF folder has no femur or pelvis, so the model's own meshes
    of femur_r and pelvis join the scene (its other side's pelvis not), said in its comment,
    the femur fitted along its shaft (issue 46), and the scene checks with the muscles
    lying on them."""
    r = init_scene(
        data_dir / _GAIT, data_dir / "vhf", tmp_path / "vhf.toml", motion=data_dir / _WALK,
        model_bones=True,
    )  # fmt: skip
    sc = load_scene(r.scene)
    got = {b.name: (b.mesh.name, b.body) for b in sc.bones if b.source}
    assert got == {
        "femur": ("femur_r.vtp", "femur_r"), "pelvis": ("pelvis.vtp", "pelvis"),
        "sacrum": ("sacrum.vtp", "pelvis"),
    }  # fmt: skip
    assert len(sc.bones) == 5 + 3  # the folder's own five kept
    assert "# bones from the model (init --model-bones)" in r.text
    assert 'model = "femur_r.vtp"' in r.text and "l_pelvis" not in r.text
    rep = check_scene(sc)
    assert rep.ok, [str(f) for f in rep.errors]
    assert [b.name for b in sc.bones if b.fit] == ["femur"]  # a long bone: fitted
    assert 'fit = "shaft"' in r.text
    (fitted,) = [f.message for f in rep.findings if f.subject == "femur" and "fitted" in f.message]
    assert "vastus_intermedius 2319 vertices 11.12 mm deep -> " in fitted
    for f in rep.findings:  # what is left in the fitted femur, the run pushes out at rest
        if "inside the bone 'femur' at rest" in f.message:
            assert float(f.message.split("up to ")[1].split()[0]) < 1.0, f.message


_GAIT = "opensim/models/subject01_simbody.osim"
_WALK = "opensim/motions/subject01_walk1_ik.mot"


@pytest.fixture(scope="module")
def vhf_mapping(data_dir, tmp_path_factory):
    """What init writes for the VHF folder as it is named (once for the renamed ones)."""
    out = tmp_path_factory.mktemp("vhf") / "a.toml"
    a = init_scene(data_dir / _GAIT, data_dir / "vhf", out, motion=data_dir / _WALK)
    return _mapping(load_scene(a.scene))


@pytest.mark.parametrize("style", sorted(RENAMED))
def test_init_on_a_renamed_folder_writes_the_same_scene(data_dir, tmp_path, style, vhf_mapping):
    """Issue 47: the VHF folder renamed maps every muscle to the same paths, every bone to
    the same body, and finds the same registration."""
    folder = tmp_path / "renamed"
    folder.mkdir()
    for f, parts in _vhf_names(data_dir):
        (folder / f"{RENAMED[style](*parts)}.stl").symlink_to(f)
    b = init_scene(data_dir / _GAIT, folder, tmp_path / "b.toml", motion=data_dir / _WALK)
    assert not b.unplaced, b.unplaced
    assert _mapping(load_scene(b.scene)) == vhf_mapping


def _no_knee(data_dir: Path, folder: Path) -> None:
    """The VHF folder without its distal femur's cartilage, the hip's named nothing."""
    folder.mkdir()
    for i, f in enumerate(sorted((data_dir / "vhf").glob("*.stl"))):
        if "FemurDistal" not in f.name:
            (folder / (f"scan_{i:02d}.stl" if "Cartilage" in f.name else f.name)).symlink_to(f)


def test_init_stops_where_no_placement_puts_the_muscles_on_their_paths(data_dir, tmp_path):
    """Issue 47: another subject's meshes with a hip's cartilage but nothing for the knee
    cannot be registered; init says what it found and needs, and writes no scene a metre
    off."""
    folder = tmp_path / "meshes"
    _no_knee(data_dir, folder)
    out = tmp_path / "s.toml"
    with pytest.raises(SceneError, match="no placement puts the muscles on their paths") as e:
        init_scene(
            data_dir / "opensim/models/subject01_simbody.osim", folder, out,
            motion=data_dir / "opensim/motions/subject01_walk1_ik.mot",
        )  # fmt: skip
    said = str(e.value)
    # the roundest unnamed cap is taken for the hip's cartilage by its shape; no knee
    assert "Landmark surfaces found: scan_" in said and "(femoral head)" in said
    assert "femoral head's cartilage" in said and "distal femur's cartilage" in said
    assert "not recognised by name: scan_" in said  # the files it could not name
    assert not out.exists() and not list(tmp_path.glob("*.mot"))


def test_init_says_a_muscle_in_two_meshes_and_two_muscles_in_one(data_dir, tmp_path):
    """Issue 47: a muscle segmented in two meshes is two scene muscles on its paths, several
    muscles in one mesh (the iliopsoas) follow all of their paths, and the scene says so."""
    folder = tmp_path / "meshes"
    folder.mkdir()
    lhdl = data_dir / "lhdl/muscles"
    for name, f in [
        ("LHDL_R_Psoas.vtk", "LHDL_R_Psoas.vtk"),
        ("LHDL_R_GluteusMaximus.vtk", "LHDL_R_GluteusMaximus.vtk"),
        ("LHDL_R_GluteusMaximus_deep.vtk", "LHDL_R_GluteusMaximus.vtk"),
        ("R_Iliopsoas.vtk", "LHDL_R_Iliacus.vtk"),
    ]:
        (folder / name).symlink_to(lhdl / f)
    r = init_scene(data_dir / "lhdl/model/LHDL_hip_r.osim", folder, tmp_path / "s.toml")
    assert r.muscles == {
        "gluteus_maximus": ("glut_max1_r", "glut_max2_r", "glut_max3_r"),
        "gluteus_maximus_2": ("glut_max1_r", "glut_max2_r", "glut_max3_r"),
        "iliopsoas": ("iliacus_r", "psoas_r"),
        "psoas": ("psoas_r",),
    }
    said = " ".join(r.notes)
    assert "several muscles in one mesh, the iliopsoas (iliacus, psoas)" in said
    assert "the gluteus maximus is in 2 meshes" in said
    assert "several muscles in one mesh" in r.text
    sc = load_scene(r.scene)
    assert sorted(m.name for m in sc.muscles) == sorted(r.muscles)


def test_init_registers_by_a_whole_femur_where_no_cartilage_is(data_dir, tmp_path):
    """Issue 47: the LHDL muscles and femur (another subject's CT frame, no cartilage) on
    gait2392: the hip from the femur's head, the knee from its condyles; the paths then
    run through their muscles and check finds nothing wrong."""
    folder = tmp_path / "meshes"
    folder.mkdir()
    for f in ("GluteusMaximus", "GluteusMedius", "Iliacus", "Psoas"):
        (folder / f"LHDL_R_{f}.vtk").symlink_to(data_dir / f"lhdl/muscles/LHDL_R_{f}.vtk")
    (folder / "LHDL_R_Femur.vtk").symlink_to(data_dir / "lhdl/bones/LHDL_R_Femur.vtk")
    r = init_scene(
        data_dir / "opensim/models/subject01_simbody.osim", folder, tmp_path / "s.toml",
        motion=data_dir / "opensim/motions/subject01_walk1_ik.mot",
    )  # fmt: skip
    sc = load_scene(r.scene)
    assert sc.registration is not None
    assert [(lm.name, lm.fit, lm.body) for lm in sc.registration.landmarks] == [
        ("hip", "femoral_head", "femur_r"),
        ("knee", "femur_distal", "tibia_r"),
    ]
    assert all(lm.mesh.name == "LHDL_R_Femur.vtk" for lm in sc.registration.landmarks)
    assert set(r.muscles) == {"gluteus_maximus", "gluteus_medius", "iliacus", "psoas"}
    rep = check_scene(sc)
    assert rep.ok, [str(f) for f in rep.errors]
    # the median muscle's paths come within a few mm of it for a quarter of their length
    assert np.median([f.near for f in rep.fits.values()]) < 5.0


@pytest.mark.parametrize("case", ["nothing recognisable", "no registration", "two subjects"])
def test_init_refuses_with_what_to_do_and_writes_nothing(data_dir, tmp_path, capsys, case):
    """Issue 47's three refusals, through the command line: exit status 2, a message that
    says what to do, no scene and no sweep written."""
    folder = tmp_path / "meshes"
    folder.mkdir()
    vhf = sorted((data_dir / "vhf").glob("*.stl"))
    if case == "nothing recognisable":
        for i, f in enumerate(vhf[:4]):
            (folder / f"scan_{i:04d}.stl").symlink_to(f)
        says = ["no mesh of the folder could be matched", "Name each mesh by its muscle"]
    elif case == "no registration":
        folder.rmdir()
        _no_knee(data_dir, folder)
        says = ["no placement puts the muscles on their paths", "femoral head's cartilage"]
    else:  # the VHF folder with two LHDL muscles (another subject's CT frame) among them
        for f in vhf:
            (folder / f.name).symlink_to(f)
        for m in ("Psoas", "Sartorius"):
            src = data_dir / "lhdl/muscles" / f"LHDL_R_{m}.vtk"
            if src.exists():
                (folder / src.name).symlink_to(src)
        (folder / "LHDL_R_Iliacus.vtk").symlink_to(data_dir / "lhdl/muscles/LHDL_R_Iliacus.vtk")
        says = ["not in one frame", "LHDL_R_Iliacus.vtk", "one subject's meshes"]
    out = tmp_path / "s.toml"
    code = main(["init", str(data_dir / _GAIT), str(folder), "-o", str(out)])
    err = capsys.readouterr().err
    assert code == 2, err
    for s in says:
        assert s in err, (s, err)
    assert not out.exists() and not list(tmp_path.glob("*.mot"))


def test_init_takes_an_unnamed_spherical_cap_for_the_hip(data_dir, tmp_path):
    """Issue 47: the hip's cartilages named nothing (scan_*.stl): the roundest cap among the
    unnamed meshes is the hip's cartilage by its shape, the scene says so, and the muscles
    get the same paths as with the names."""
    folder = tmp_path / "meshes"
    folder.mkdir()
    for f in sorted((data_dir / "vhf").glob("*.stl")):
        hip = "FemurHead" in f.name or "Acetabulum" in f.name
        (folder / (f"scan_{f.name[18:22]}.stl" if hip else f.name)).symlink_to(f)
    r = init_scene(data_dir / _GAIT, folder, tmp_path / "s.toml", motion=data_dir / _WALK)
    sc = load_scene(r.scene)
    assert sc.registration is not None
    hip = next(lm for lm in sc.registration.landmarks if lm.name == "hip")
    assert hip.mesh.name.startswith("scan_") and hip.fit == "sphere"
    assert "by its shape: a spherical cap" in r.text
    a = init_scene(data_dir / _GAIT, data_dir / "vhf", tmp_path / "a.toml", motion=data_dir / _WALK)
    assert r.muscles == a.muscles
    rep = check_scene(sc)
    assert rep.ok, [str(f) for f in rep.errors]


def _segments(data_dir: Path, folder: Path, named: tuple[str, ...]) -> dict[str, Path]:
    """The VHF folder as a segmentation tool writes it: Segment_N.stl, but for ``named``."""
    folder.mkdir()
    out = {}
    for i, f in enumerate(sorted((data_dir / "vhf").glob("*.stl"))):
        name = f.name if any(n in f.name for n in named) else f"Segment_{i + 1}.stl"
        (folder / name).symlink_to(f)
        out[name] = f
    return out


def test_init_places_meshes_no_name_places_by_their_shape_and_place(
    data_dir, tmp_path, vhf_mapping
):
    """Issue 47: the VHF folder with only three muscles named (the others, the bones and
    the cartilages Segment_N.stl): the hip's cartilage by its shape, the knee's by its
    shape and place, the tibia where the model's tibia lies, and each muscle by the paths
    that run along it, one muscle per mesh; every guess said in the scene, and the scene
    the named folder's."""
    folder = tmp_path / "segments"
    files = _segments(data_dir, folder, ("GluteusMaximus", "RectusFemoris", "AdductorMagnus"))
    r = init_scene(data_dir / _GAIT, folder, tmp_path / "s.toml", motion=data_dir / _WALK)
    got = _mapping(load_scene(r.scene))
    want = vhf_mapping
    right = {k: v for k, v in want["muscles"].items() if not k.endswith("_left")}
    assert got["muscles"] == right
    assert got["registration"][0] == want["registration"][0]
    # the landmarks: the roundest cap (the acetabulum's) for the hip, the distal shell for the knee
    marks = {name: mesh.name for name, _, _, mesh in got["registration"][1]}  # resolved
    assert "FemurDistal" in marks["knee"] and "Cartilage" in marks["hip"]
    assert got["bones"]["tibia"] == want["bones"]["tibia"]
    text = r.text
    assert text.count("by its place, not its name: its paths' nearest quarter") == len(right) - 3
    assert "the femur distal by its shape and place: a thin shell" in text
    assert "the tibia by its shape and place: a closed solid" in text
    said = {u.split(":")[0]: u for u in r.unplaced}
    patella = next(n for n, f in files.items() if "Patella" in f.name)
    assert "by its shape a closed solid" in said[patella] and "name it" in said[patella]
    left = next(n for n, f in files.items() if "Left" in f.name)
    assert "along it runs no path of the model" in said[left]
    head = next(n for n, f in files.items() if "FemurHead" in f.name)
    assert "by its shape a thin shell" in said[head]
    rep = check_scene(load_scene(r.scene))
    assert rep.ok, [str(f) for f in rep.errors]


def test_init_lets_shape_and_place_overrule_a_name(data_dir, tmp_path, vhf_mapping):
    """Issue 47: where the name and the shape disagree the shape decides: a cartilage named
    like a muscle is no muscle; two muscles whose names were swapped get the paths that run
    along them, and the scene says the name was overruled."""
    folder = tmp_path / "swapped"
    folder.mkdir()
    swap = {"Gracilis": "Sartorius", "Sartorius": "Gracilis"}
    for f in sorted((data_dir / "vhf").glob("*.stl")):
        name = f.name
        for a, b in swap.items():
            if f"_{a}_" in f.name:
                name = f.name.replace(a, b)
        if "FemurHead" in f.name:
            name = "R_Gluteus_Medius_2.stl"  # a cartilage named like a muscle
        (folder / name).symlink_to(f)
    r = init_scene(data_dir / _GAIT, folder, tmp_path / "s.toml", motion=data_dir / _WALK)
    got = _mapping(load_scene(r.scene))
    for n in ("gracilis", "sartorius"):
        assert got["muscles"][n][:2] == vhf_mapping["muscles"][n][:2]
        assert got["muscles"][n][2] == vhf_mapping["muscles"][n][2]
    assert r.text.count("but by its place") == 2
    assert any(
        u.startswith("R_Gluteus_Medius_2.stl") and "by its shape a thin shell" in u
        for u in r.unplaced
    )
    assert "gluteus_medius_2" not in got["muscles"]


def test_init_lists_what_it_cannot_place(data_dir, tmp_path):
    folder = tmp_path / "meshes"
    folder.mkdir()
    for f in ("muscles/LHDL_R_Psoas.vtk", "bones/LHDL_R_Femur.vtk"):
        (folder / Path(f).name).symlink_to(data_dir / "lhdl" / f)
    # a muscle the LHDL model has no path for, and a file whose name says nothing
    (folder / "VHF_Right_Muscle_Sartorius_smooth.stl").symlink_to(
        data_dir / "vhf/VHF_Right_Muscle_Sartorius_smooth.stl"
    )
    (folder / "scan_0042.stl").symlink_to(data_dir / "vhf/VHF_Right_Bone_Patella_smooth.stl")
    r = init_scene(data_dir / "lhdl/model/LHDL_hip_r.osim", folder, tmp_path / "s.toml")
    assert set(r.muscles) == {"psoas"} and r.bones == {"femur": "femur_r"}
    assert len(r.unplaced) == 2
    assert any("Sartorius" in u and "no path for it" in u for u in r.unplaced)
    assert any("scan_0042" in u and "names no muscle" in u for u in r.unplaced)
    text = r.scene.read_text()
    assert "NOT PLACED (2)" in text and "scan_0042.stl" in text
    # no motion given: a sweep of the hip's coordinates over their ranges
    assert r.motion_written is not None and r.motion_written.is_file()
    assert load_scene(r.scene).motion == r.motion_written


def test_init_refuses_a_folder_without_meshes(tmp_path, data_dir):
    with pytest.raises(ValueError, match="no mesh files"):
        init_scene(data_dir / "lhdl/model/LHDL_hip_r.osim", tmp_path, tmp_path / "s.toml")
    code = main(
        [
            "init",
            str(data_dir / "lhdl/model/LHDL_hip_r.osim"),
            str(tmp_path / "nowhere"),
            "-o",
            str(tmp_path / "s.toml"),
        ]
    )
    assert code == 2 and not (tmp_path / "s.toml").exists()


# ---------------------------------------------------------------------------- check
def _broken(data_dir: Path, tmp_path: Path, case: str) -> Path:
    src = (EXAMPLES / "gait2392_walk.toml").read_text()
    src = src.replace("../../shared/data", data_dir.as_posix())
    if case == "units":
        src = src.replace('mesh = "mm"\nmodel = "m"', 'mesh = "m"\nmodel = "mm"')
    elif case == "body":
        src = src.replace(
            'Tibia_smooth.stl"\nbody = "tibia_r"', 'Tibia_smooth.stl"\nbody = "femur_r"'
        )
    elif case == "path":
        src = src.replace('paths = ["semiten_r"]', 'paths = ["vas_lat_r"]')
    elif case == "registration":
        a, b = src.index("\n[registration]"), src.index("\n[muscles.")
        src = src[:a] + src[b:]
        src = "\n".join(x for x in src.splitlines() if not x.startswith("mesh_frame"))
    elif case == "motion":
        mot = (data_dir / "opensim/motions/subject01_walk1_ik.mot").read_text().splitlines()
        k = next(i for i, x in enumerate(mot) if x.strip().startswith("time"))
        j = mot[k].split("\t").index("knee_angle_r")
        rows = [mot[i].split("\t") for i in range(k, len(mot))]
        mot = mot[:k] + ["\t".join(r[:j] + r[j + 1 :]) for r in rows]
        (tmp_path / "no_knee.mot").write_text("\n".join(mot) + "\n")
        src = re.sub(r'motion = ".*?"', f'motion = "{(tmp_path / "no_knee.mot").as_posix()}"', src)
    p = tmp_path / f"{case}.toml"
    p.write_text(src)
    return p


@pytest.mark.parametrize(
    ("case", "subject", "says", "fix"),
    [
        (
            "units",
            "scene",
            "registration scales the meshes by 1.18e-06",
            "mesh = 'mm', model = 'm'",
        ),
        (
            "body",
            "tibia",
            "carried by 'femur_r', but 24 path points of 'tibia_r'",
            "body = 'tibia_r'",
        ),
        ("path", "semitendinosus", "do not run along it at rest", "semiten_r"),
        ("registration", "scene", "no muscle lies along its lines", "[registration]"),
        (
            "motion",
            "knee_angle_r",
            "no column 'knee_angle_r'",
            "take it out of [model] coordinates",
        ),
    ],
)
def test_check_catches_a_broken_scene(data_dir, tmp_path, case, subject, says, fix):
    rep = check_scene(_broken(data_dir, tmp_path, case))
    assert not rep.ok
    hit = [f for f in rep.errors if f.subject == subject and says in f.message]
    assert hit, [str(f) for f in rep.findings]
    assert fix in hit[0].fix


def test_check_and_run_refuse_a_broken_scene_alike(data_dir, tmp_path, capsys):
    p = _broken(data_dir, tmp_path, "path")
    assert main(["check", str(p)]) == 2
    said = capsys.readouterr().out
    assert "error: semitendinosus: its lines (vas_lat_r) do not run along it" in said
    assert main(["run", str(p), "-o", str(tmp_path / "out"), "--frames", "0:1"]) == 2
    err = capsys.readouterr().err
    assert "error: semitendinosus: its lines (vas_lat_r) do not run along it" in err
    assert not (tmp_path / "out").exists()


def test_check_passes_an_example_and_draws_it(data_dir, tmp_path, capsys):
    png = tmp_path / "check.png"
    assert main(["check", str(EXAMPLES / "lhdl_walk.toml"), "-o", str(png)]) == 0
    out = capsys.readouterr().out
    assert "0 errors" in out and "gluteus_maximus: lines 71 % inside" in out
    from PIL import Image

    im = np.asarray(Image.open(png).convert("RGB"))
    assert im.shape == (900, 1600, 3)
    # both views show something besides the white background
    for half in (im[:, :800], im[:, 800:]):
        assert (half.sum(axis=2) < 600).mean() > 0.02


def test_cli_init_then_check(data_dir, tmp_path, capsys):
    hand = load_scene(EXAMPLES / "lhdl_walk.toml")
    folder = _folder_of(hand, tmp_path / "meshes")
    out = tmp_path / "lhdl.toml"
    osim = str(hand.osim)
    assert main(["init", osim, str(folder), "--motion", str(hand.motion), "-o", str(out)]) == 0
    said = capsys.readouterr().out
    assert (
        "4 muscles, 3 bones" in said
        and "gluteus_maximus: glut_max1_r, glut_max2_r, glut_max3_r" in said
    )
    assert main(["init", osim, str(folder), "-o", str(out)]) == 2  # exists: --force
    assert main(["check", str(out)]) == 0
    shutil.rmtree(folder)


def test_init_on_another_model_rajagopal(data_dir, tmp_path):
    """The VHF folder on Rajagopal 2016 with the OpenCap squat: its names, its missing pectineus."""
    r = init_scene(
        data_dir / "opensim/models/Rajagopal2016.osim",
        data_dir / "vhf",
        tmp_path / "raj.toml",
        motion=data_dir / "opensim/motions/opencap_squat_videoAndMocap.mot",
    )
    assert len(r.muscles) == 19
    assert r.muscles["adductor_magnus"] == (
        "addmagDist_r", "addmagIsch_r", "addmagMid_r", "addmagProx_r",
    )  # fmt: skip
    assert r.muscles["biceps_femoris_long_left"] == ("bflh_l",)
    assert [u for u in r.unplaced if "Pectineus" in u and "no path for it" in u]
    sc = load_scene(r.scene)
    assert sc.registration is not None and sc.registration.axes == ("y", "z", "x")
    assert "knee_angle_r_beta" not in sc.coordinates and "knee_angle_r" in sc.coordinates
    assert check_scene(sc).ok


def test_checks_measures_are_read_back_and_taken_anew_for_a_changed_mesh(
    data_dir, tmp_path, monkeypatch
):
    """The check's libigl measures at rest (``run`` and ``view`` check at every start) are
    kept in the cache: a second check measures nothing and finds the same; a moved bone
    is measured anew."""
    import igl

    from musclewrap.mesh import read_mesh, write_mesh

    sc = load_scene(EXAMPLES / "lhdl_walk.toml")
    first = check_scene(sc, cache_dir=tmp_path)
    kept = {p.name for p in tmp_path.glob("measure-*.npz")}
    assert {k.split("-")[1] for k in kept} == {"inside", "outside"}
    calls = []
    for f in ("point_mesh_squared_distance", "fast_winding_number", "winding_number"):
        was = getattr(igl, f)
        monkeypatch.setattr(igl, f, lambda *a, was=was, f=f, **k: calls.append(f) or was(*a, **k))
    again = check_scene(sc, cache_dir=tmp_path)
    assert calls == []
    assert again.findings == first.findings and again.fits == first.fits
    # the femur 2 mm along x: its measures (the muscles inside it, the paths on it) anew
    femur = next(b for b in sc.bones if b.name == "femur")
    V, F = read_mesh(femur.mesh)[:2]
    moved = tmp_path / "femur_moved.vtp"
    write_mesh(moved, V + [2.0, 0.0, 0.0], F)
    text = sc.path.read_text().replace("../../shared/data/lhdl/bones/LHDL_R_Femur.vtk", str(moved))
    (tmp_path / "moved.toml").write_text(text.replace("../../shared/data", str(data_dir)))
    check_scene(load_scene(tmp_path / "moved.toml"), cache_dir=tmp_path)
    new = {p.name for p in tmp_path.glob("measure-*.npz")} - kept
    assert {k.split("-")[1] for k in new} == {"inside", "outside"} and calls
