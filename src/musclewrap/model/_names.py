"""Anatomical names: what the common OpenSim models and mesh files call each muscle and bone.

One table, `MUSCLES`, holds for each muscle of the lower limb and trunk its name in a
scene (snake case, English), the segment its belly lies along (which body carries the
mesh), the spellings mesh files use and the stems of the path names of the common
OpenSim models: gait2392 and gait2354 with their scalings (Delp 1990; also Arnold 2010,
Hamner 2010 and the LHDL hip model of Modenese & Kohout 2020, which keep its names),
and Rajagopal 2016 with its descendants (LaiArnold 2017, OpenCap's LaiUhlrich 2022).
A model's path name is its stem, then an optional part (``1``..``3``, or Rajagopal's
``Dist``/``Isch``/``Mid``/``Prox``), then the side (``_r``/``_l``).
"""

from __future__ import annotations

import difflib
import re
from dataclasses import dataclass

from ..constants import defaults

__all__ = [
    "BONES",
    "LANDMARKS",
    "MUSCLES",
    "Anatomy",
    "NameMatch",
    "match_bone",
    "match_muscle",
    "mesh_name_tokens",
    "path_anatomy",
    "split_path_name",
]


@dataclass(frozen=True)
class Anatomy:
    """One muscle: its scene name, the segment holding its belly, and its spellings."""

    name: str
    #: "trunk", "hip" (carried by the pelvis), "thigh" (femur), "shank" (tibia)
    region: str
    #: spellings in mesh file names, lower case letters only (the name itself is one)
    aliases: tuple[str, ...]
    #: stems of OpenSim path names, lower case (gait2392's, then Rajagopal's)
    stems: tuple[str, ...]


def _m(name: str, region: str, aliases: str, stems: str) -> Anatomy:
    return Anatomy(name, region, (name.replace("_", ""), *aliases.split()), tuple(stems.split()))


#: the muscles, hip to foot
MUSCLES: tuple[Anatomy, ...] = (
    _m("gluteus_maximus", "hip", "glutmax gmax glutealmaximus", "glut_max glmax"),
    _m("gluteus_medius", "hip", "glutmed gmed glutealmedius", "glut_med glmed"),
    _m("gluteus_minimus", "hip", "glutmin gmin glutealminimus", "glut_min glmin"),
    _m("iliacus", "hip", "iliacusmuscle", "iliacus"),
    _m("psoas", "hip", "psoasmajor psoasmaj", "psoas"),
    _m("piriformis", "hip", "piri", "peri piri"),
    _m("gemelli", "hip", "gemellus gemellisuperior gemelliinferior", "gem"),
    _m("quadratus_femoris", "hip", "quadfem", "quad_fem"),
    _m("tensor_fasciae_latae", "thigh", "tensorfascialatae tensorfascialata tfl", "tfl"),
    _m("rectus_femoris", "thigh", "rectfem recfem", "rect_fem recfem"),
    _m("vastus_lateralis", "thigh", "vaslat vastuslateral", "vas_lat vaslat"),
    _m("vastus_medialis", "thigh", "vasmed vastusmedial", "vas_med vasmed"),
    _m("vastus_intermedius", "thigh", "vasint vastusintermedialis", "vas_int vasint"),
    _m("sartorius", "thigh", "sart", "sar sart"),
    _m("gracilis", "thigh", "grac", "grac"),
    _m("semitendinosus", "thigh", "semiten semitend", "semiten"),
    _m("semimembranosus", "thigh", "semimem semimemb", "semimem"),
    _m(
        "biceps_femoris_long",
        "thigh",
        "bicepsfemorislonghead bicepsfemorislh bicepsfemoris bflh",
        "bifemlh bflh",
    ),
    _m(
        "biceps_femoris_short",
        "thigh",
        "bicepsfemorisshorthead bicepsfemorissh bfsh",
        "bifemsh bfsh",
    ),
    _m("adductor_longus", "thigh", "addlong", "add_long addlong"),
    _m("adductor_brevis", "thigh", "addbrev", "add_brev addbrev"),
    _m("adductor_magnus", "thigh", "addmag", "add_mag addmag"),
    _m("pectineus", "thigh", "pect", "pect"),
    _m(
        "gastrocnemius_medial",
        "shank",
        "gastrocnemiusmedialis gastrocnemiusmedialhead medialgastrocnemius gasmed",
        "med_gas gasmed",
    ),
    _m(
        "gastrocnemius_lateral",
        "shank",
        "gastrocnemiuslateralis gastrocnemiuslateralhead lateralgastrocnemius gaslat",
        "lat_gas gaslat",
    ),
    _m("soleus", "shank", "sol", "soleus"),
    _m("tibialis_anterior", "shank", "tibant", "tib_ant tibant"),
    _m("tibialis_posterior", "shank", "tibpost", "tib_post tibpost"),
    _m("flexor_digitorum_longus", "shank", "fdl", "flex_dig fdl"),
    _m("flexor_hallucis_longus", "shank", "fhl", "flex_hal fhl"),
    _m("extensor_digitorum_longus", "shank", "edl", "ext_dig edl"),
    _m("extensor_hallucis_longus", "shank", "ehl", "ext_hal ehl"),
    _m("peroneus_brevis", "shank", "fibularisbrevis perbrev", "per_brev perbrev"),
    _m("peroneus_longus", "shank", "fibularislongus perlong", "per_long perlong"),
    _m("peroneus_tertius", "shank", "fibularistertius pertert", "per_tert"),
    _m("erector_spinae", "trunk", "erectorspinae ercspn", "ercspn"),
    _m("internal_oblique", "trunk", "internalobliques intobl", "intobl"),
    _m("external_oblique", "trunk", "externalobliques extobl", "extobl"),
)


@dataclass(frozen=True)
class BoneName:
    """A bone (or a cartilage, a landmark): its scene name, spellings and body."""

    name: str
    aliases: tuple[str, ...]
    #: body names to try, in order ("{s}": the side, r or l); the first the model has
    bodies: tuple[str, ...]


def _b(name: str, aliases: str, bodies: str) -> BoneName:
    return BoneName(name, (name.replace("_", ""), *aliases.split()), tuple(bodies.split()))


#: bones, carried rigidly by a body
BONES: tuple[BoneName, ...] = (
    _b("pelvis", "hipbone innominate coxal oscoxae ilium", "pelvis"),
    _b("iliac", "iliacbone ilium", "pelvis"),
    _b("sacrum", "sacral", "pelvis sacrum"),
    _b("femur", "femoral thighbone", "femur_{s}"),
    _b("patella", "kneecap", "patella_{s} tibia_{s}"),
    _b("tibia", "tibial", "tibia_{s}"),
    _b("fibula", "fibular", "fibula_{s} tibia_{s}"),
    _b("talus", "", "talus_{s}"),
    _b("calcaneus", "calcn calcaneum", "calcn_{s}"),
)

#: cartilages and other landmark surfaces (kept as bones of the scene, and used to register)
LANDMARKS: tuple[BoneName, ...] = (
    _b("femoral_head", "femurhead headoffemur caputfemoris", "femur_{s}"),
    _b("femur_distal", "distalfemur femoralcondyles femurcondyles condyles", "femur_{s}"),
    _b("acetabulum", "pelvisacetabulum acetabular", "pelvis"),
    _b("tibial_plateau", "tibiaproximal proximaltibia tibialplateau", "tibia_{s}"),
    _b("patellar_cartilage", "patellacartilage", "patella_{s} tibia_{s}"),
)

# words in mesh file names that say nothing of which muscle or bone it is
_NOISE = {
    "vhf", "lhdl", "smooth", "smoothed", "mesh", "surface", "seg", "segmentation", "final",
    "muscle", "muscles", "bone", "bones", "cartilage", "cartilages", "m", "mm", "stl", "the",
    "right", "left", "r", "l", "rt", "lt", "dx", "sx",
}  # fmt: skip
_RIGHT, _LEFT = {"right", "r", "rt", "dx"}, {"left", "l", "lt", "sx"}


@dataclass(frozen=True)
class NameMatch:
    """What a name was matched to and how sure the match is."""

    name: str
    #: 1.0 for a spelling in the table, else the similarity of the nearest one
    score: float
    #: "exact", or "similar to 'xyz'"
    how: str


def mesh_name_tokens(stem: str) -> tuple[list[str], str | None]:
    """A file name's words (lower case; camel case and separators split) and its side.

    >>> mesh_name_tokens("VHF_Right_Muscle_GluteusMaximus_smooth")
    (['vhf', 'right', 'muscle', 'gluteus', 'maximus', 'smooth'], 'r')
    """
    words = re.findall(r"[A-Z]+(?![a-z])|[A-Z]?[a-z]+|\d+", stem)
    words = [w.lower() for w in words]
    side = None
    for w in words:
        if w in _RIGHT:
            side = "r"
        elif w in _LEFT:
            side = "l"
    return words, side


def _key(words: list[str]) -> str:
    return "".join(w for w in words if w not in _NOISE and not w.isdigit())


def _best(key: str, table: tuple[Anatomy, ...] | tuple[BoneName, ...]) -> NameMatch | None:
    if not key:
        return None
    best: tuple[float, str, str] = (0.0, "", "")
    for entry in table:
        for alias in entry.aliases:
            if key == alias:
                return NameMatch(entry.name, 1.0, "exact")
            r = difflib.SequenceMatcher(None, key, alias).ratio()
            if r > best[0]:
                best = (r, entry.name, alias)
    if best[0] >= defaults.name_similar:
        return NameMatch(best[1], round(best[0], 3), f"similar to '{best[2]}'")
    return None


def match_muscle(stem: str) -> NameMatch | None:
    """The muscle a mesh file's name (without suffix) names, or None.

    >>> match_muscle("VHF_Right_Muscle_Illiacus_smooth").name
    'iliacus'
    """
    return _best(_key(mesh_name_tokens(stem)[0]), MUSCLES)


def match_bone(stem: str) -> tuple[NameMatch, bool] | None:
    """The bone or landmark a mesh file's name names, and whether it is a landmark."""
    words, _ = mesh_name_tokens(stem)
    key = _key(words)
    lm = _best(key, LANDMARKS)
    if lm is not None and (lm.score == 1.0 or "cartilage" in words):
        return lm, True
    bone = _best(key, BONES)
    if bone is not None:
        return bone, False
    if lm is not None:
        return lm, True
    return None


_PART = re.compile(r"^(?P<stem>.*?)(?P<part>\d+|Dist|Isch|Mid|Prox|Sup|Inf)?$")


def split_path_name(path: str) -> tuple[str, str, str | None]:
    """A model's path name as (stem, part, side).

    >>> split_path_name("glut_max2_r")
    ('glut_max', '2', 'r')
    >>> split_path_name("addmagDist_r")
    ('addmag', 'Dist', 'r')
    """
    side = None
    base = path
    m = re.match(r"^(.*)_([rlRL])$", path)
    if m:
        base, side = m.group(1), m.group(2).lower()
    p = _PART.match(base)
    assert p is not None  # the pattern matches every string
    stem = p.group("stem").rstrip("_").lower()
    return stem, p.group("part") or "", side


_BY_STEM = {s: a for a in MUSCLES for s in a.stems}


def path_anatomy(path: str) -> tuple[Anatomy, str | None] | None:
    """The muscle an OpenSim path belongs to, and its side; None if the table lacks it.

    >>> a, side = path_anatomy("bifemlh_r")
    >>> a.name, side
    ('biceps_femoris_long', 'r')
    """
    stem, _, side = split_path_name(path)
    a = _BY_STEM.get(stem)
    return None if a is None else (a, side)
