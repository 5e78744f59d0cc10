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

import re
from dataclasses import dataclass

__all__ = [
    "BONES",
    "GROUPS",
    "LANDMARKS",
    "MUSCLES",
    "Anatomy",
    "MuscleGroup",
    "NameMatch",
    "match_bone",
    "match_group",
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
    _m("gluteus_maximus", "hip", "glutmax gmax glmax glutealmaximus", "glut_max glmax"),
    _m("gluteus_medius", "hip", "glutmed gmed glmed glutealmedius", "glut_med glmed"),
    _m("gluteus_minimus", "hip", "glutmin gmin glmin glutealminimus", "glut_min glmin"),
    _m("iliacus", "hip", "iliacusmuscle il ili", "iliacus"),
    _m("psoas", "hip", "psoasmajor psoasmaj ps", "psoas"),
    _m("piriformis", "hip", "piri pir", "peri piri"),
    _m("gemelli", "hip", "gemellus gemellisuperior gemelliinferior", "gem"),
    _m("quadratus_femoris", "hip", "quadfem qf", "quad_fem"),
    _m("tensor_fasciae_latae", "thigh", "tensorfascialatae tensorfascialata tfl", "tfl"),
    _m("rectus_femoris", "thigh", "rectfem recfem rf", "rect_fem recfem"),
    _m("vastus_lateralis", "thigh", "vaslat vastuslateral vl", "vas_lat vaslat"),
    _m("vastus_medialis", "thigh", "vasmed vastusmedial vm", "vas_med vasmed"),
    _m("vastus_intermedius", "thigh", "vasint vastusintermedialis vi", "vas_int vasint"),
    _m("sartorius", "thigh", "sart sar sr", "sar sart"),
    _m("gracilis", "thigh", "grac gr", "grac"),
    _m("semitendinosus", "thigh", "semiten semitend st", "semiten"),
    _m("semimembranosus", "thigh", "semimem semimemb sm", "semimem"),
    _m(
        "biceps_femoris_long",
        "thigh",
        "bicepsfemorislonghead bicepsfemorislh bicepsfemoris bflh bfl",
        "bifemlh bflh",
    ),
    _m(
        "biceps_femoris_short",
        "thigh",
        "bicepsfemorisshorthead bicepsfemorissh bfsh bfs",
        "bifemsh bfsh",
    ),
    _m("adductor_longus", "thigh", "addlong al", "add_long addlong"),
    _m("adductor_brevis", "thigh", "addbrev ab", "add_brev addbrev"),
    _m("adductor_magnus", "thigh", "addmag am", "add_mag addmag"),
    _m("pectineus", "thigh", "pect pec", "pect"),
    _m(
        "gastrocnemius_medial",
        "shank",
        "gastrocnemiusmedialis gastrocnemiusmedialhead medialgastrocnemius gasmed medgas mg",
        "med_gas gasmed",
    ),
    _m(
        "gastrocnemius_lateral",
        "shank",
        "gastrocnemiuslateralis gastrocnemiuslateralhead lateralgastrocnemius gaslat latgas lg",
        "lat_gas gaslat",
    ),
    _m("soleus", "shank", "sol", "soleus"),
    _m("tibialis_anterior", "shank", "tibant ta", "tib_ant tibant"),
    _m("tibialis_posterior", "shank", "tibpost tp", "tib_post tibpost"),
    _m("flexor_digitorum_longus", "shank", "fdl", "flex_dig fdl"),
    _m("flexor_hallucis_longus", "shank", "fhl", "flex_hal fhl"),
    _m("extensor_digitorum_longus", "shank", "edl", "ext_dig edl"),
    _m("extensor_hallucis_longus", "shank", "ehl", "ext_hal ehl"),
    _m("peroneus_brevis", "shank", "fibularisbrevis perbrev pb", "per_brev perbrev"),
    _m("peroneus_longus", "shank", "fibularislongus perlong pl", "per_long perlong"),
    _m("peroneus_tertius", "shank", "fibularistertius pertert", "per_tert"),
    _m("erector_spinae", "trunk", "erectorspinae ercspn es", "ercspn"),
    _m("internal_oblique", "trunk", "internalobliques intobl io", "intobl"),
    _m("external_oblique", "trunk", "externalobliques extobl eo", "extobl"),
)


@dataclass(frozen=True)
class MuscleGroup:
    """Several muscles segmented as one mesh: its name, spellings and the muscles it holds."""

    name: str
    aliases: tuple[str, ...]
    #: the muscles of `MUSCLES` it holds, by name (the first one's region carries it)
    parts: tuple[str, ...]


def _g(name: str, aliases: str, parts: str) -> MuscleGroup:
    return MuscleGroup(name, (name.replace("_", ""), *aliases.split()), tuple(parts.split()))


#: muscles a segmentation often leaves in one mesh
GROUPS: tuple[MuscleGroup, ...] = (
    _g("iliopsoas", "iliopsoasmuscle", "iliacus psoas"),
    _g("gastrocnemius", "gastroc gastrocs", "gastrocnemius_medial gastrocnemius_lateral"),
    _g("triceps_surae", "calfmuscles", "gastrocnemius_medial gastrocnemius_lateral soleus"),
    _g(
        "hamstrings",
        "hamstring hamstringmuscles",
        "semitendinosus semimembranosus biceps_femoris_long biceps_femoris_short",
    ),
    _g(
        "quadriceps",
        "quadricepsfemoris quads quad",
        "rectus_femoris vastus_lateralis vastus_medialis vastus_intermedius",
    ),
    _g("vasti", "vastii", "vastus_lateralis vastus_medialis vastus_intermedius"),
    _g("adductors", "adductor adductorgroup", "adductor_longus adductor_brevis adductor_magnus"),
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
    _b("pelvis", "hipbone innominate coxal oscoxae", "pelvis"),
    _b("iliac", "iliacbone ilium", "pelvis"),
    _b("sacrum", "sacral", "pelvis sacrum"),
    _b("femur", "femoral thighbone", "femur_{s}"),
    _b("patella", "kneecap", "patella_{s} tibia_{s}"),
    _b("tibia", "tibial", "tibia_{s}"),
    _b("fibula", "fibular", "fibula_{s} tibia_{s}"),
    _b("talus", "astragalus", "talus_{s}"),
    _b("calcaneus", "calcn calcaneum heelbone", "calcn_{s}"),
    # the midfoot and forefoot ride on the calcaneus's body in gait2392 and Rajagopal 2016,
    # the toes on their own
    _b("navicular", "naviculare scaphoid", "calcn_{s}"),
    _b("cuboid", "cuboideum", "calcn_{s}"),
    _b(
        "cuneiforms",
        "cuneiform medialcuneiform intermediatecuneiform lateralcuneiform",
        "calcn_{s}",
    ),
    _b("metatarsals", "metatarsal metatarsus metatarsi", "calcn_{s}"),
    _b("phalanges", "phalanx phalange toe toes hallux", "toes_{s} calcn_{s}"),
    _b("coccyx", "coccygeal tailbone", "pelvis sacrum"),
)

#: cartilages and other landmark surfaces (kept as bones of the scene, and used to register)
LANDMARKS: tuple[BoneName, ...] = (
    _b("femoral_head", "femurhead femoralhead headoffemur caputfemoris", "femur_{s}"),
    _b(
        "femur_distal",
        "distalfemur femurdistal femoralcondyles femurcondyles condyles",
        "femur_{s}",
    ),
    _b("acetabulum", "pelvisacetabulum acetabular", "pelvis"),
    _b("tibial_plateau", "tibiaproximal proximaltibia tibialplateau", "tibia_{s}"),
    _b("patellar_cartilage", "patellacartilage", "patella_{s} tibia_{s}"),
)

# words in mesh file names that say nothing of which muscle or bone it is: a run of words
# that names one neither starts nor ends with them
_NOISE = {
    "vhf", "lhdl", "smooth", "smoothed", "mesh", "surface", "seg", "segmentation", "final",
    "muscle", "muscles", "bone", "bones", "cartilage", "cartilages", "cart", "m", "mm",
    "stl", "obj", "ply", "vtk", "vtp", "the", "of", "label", "labels", "mask", "roi", "sub",
    "subject", "hemi", "side", "model", "decimated", "remeshed", "closed", "fixed",
    "right", "left", "r", "l", "rt", "lt", "dx", "sx",
}  # fmt: skip
_RIGHT, _LEFT = {"right", "r", "rt", "dx"}, {"left", "l", "lt", "sx"}
_CARTILAGE = {"cartilage", "cartilages", "cart"}

#: the longest run of a name's words that is tried (words are concatenated: "biceps femoris
#: long head" is four)
_MAX_RUN = 5
#: spellings this short (abbreviations: VL, RF, ST) count only as a whole word of the name
_SHORT = 3


@dataclass(frozen=True)
class NameMatch:
    """What a name was matched to and how sure the match is.

    ``run`` is the part of the name that was matched (its words, concatenated);
    ``others`` the entries that fit it equally well (a tie: the name is ambiguous, and
    `musclewrap.subject.init_scene` places it nowhere).
    """

    name: str
    #: 1.0 for a spelling in the table, else 1 - (letters off) / (letters)
    score: float
    #: "exact", "abbreviation 'vl'", or "'illiacus' read as 'iliacus' (1 letter off)"
    how: str
    run: str = ""
    others: tuple[str, ...] = ()


def mesh_name_tokens(stem: str) -> tuple[list[str], str | None]:
    """A file name's words (lower case; camel case, separators and digits split) and its side.

    >>> mesh_name_tokens("VHF_Right_Muscle_GluteusMaximus_smooth")
    (['vhf', 'right', 'muscle', 'gluteus', 'maximus', 'smooth'], 'r')
    >>> mesh_name_tokens("sub-03_hemi-R_label-BFlh")
    (['sub', '03', 'hemi', 'r', 'label', 'b', 'flh'], 'r')
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


def _edits(a: str, b: str, most: int) -> int:
    """Levenshtein distance of ``a`` and ``b``, or ``most + 1`` once it exceeds ``most``."""
    if abs(len(a) - len(b)) > most:
        return most + 1
    prev = list(range(len(b) + 1))
    for i, ca in enumerate(a, 1):
        cur = [i]
        for j, cb in enumerate(b, 1):
            cur.append(min(prev[j] + 1, cur[j - 1] + 1, prev[j - 1] + (ca != cb)))
        if min(cur) > most:
            return most + 1
        prev = cur
    return prev[-1]


def _letters_off(n: int) -> int:
    """How many letters a run of ``n`` may be off its spelling: 1 from 5, 2 from 9."""
    return 0 if n < 5 else 1 if n < 9 else 2


def _runs(words: list[str]) -> list[tuple[str, bool]]:
    """The runs of words that may name something: (concatenated, whether one whole word)."""
    out = []
    for i, w in enumerate(words):
        if w in _NOISE or w.isdigit():
            continue
        for j in range(i + 1, min(i + _MAX_RUN, len(words)) + 1):
            last = words[j - 1]
            if last.isdigit():
                break
            if last in _NOISE:
                if j > i + 1:
                    break
                continue
            out.append(("".join(words[i:j]), j == i + 1))
    return out


def _best(
    words: list[str], table: tuple[Anatomy, ...] | tuple[BoneName, ...] | tuple[MuscleGroup, ...]
) -> NameMatch | None:
    """The entry of ``table`` that the longest run of ``words`` spells.

    A run spells an entry exactly (a whole word, for a spelling of at most `_SHORT`
    letters: an abbreviation), or off by a few letters (`_letters_off`, for runs of 5 and
    more letters against the table's full spellings). The longest run wins, an exact
    spelling before a misspelt one of the same length; entries that fit as well are
    the match's ``others``.
    """
    # (full spelling, letters, letters off, entry, spelling, run): full spellings before
    # abbreviations, then the longest run, then the fewest letters off
    found: list[tuple[bool, int, int, str, str, str]] = []
    for run, whole in _runs(words):
        off = _letters_off(len(run))
        for entry in table:
            for alias in entry.aliases:
                if run == alias:
                    if len(alias) > _SHORT or whole:
                        found.append((len(alias) > _SHORT, len(run), 0, entry.name, alias, run))
                elif off and len(alias) >= 5:
                    d = _edits(run, alias, off)
                    if d <= off:
                        found.append((True, len(run), d, entry.name, alias, run))
    if not found:
        return None
    found.sort(key=lambda f: (not f[0], -f[1], f[2], f[3]))
    full, letters, d, name, alias, run = found[0]
    # ties: another entry as good; near-ties: another misspelt by one letter more
    others = tuple(
        sorted(
            {
                f[3]
                for f in found
                if f[:2] == (full, letters) and f[2] <= d + (1 if d else 0) and f[3] != name
            }
        )
    )
    if d == 0:
        how = "exact" if full else f"abbreviation '{alias}'"
        return NameMatch(name, 1.0, how, run, others)
    return NameMatch(
        name,
        round(1.0 - d / letters, 3),
        f"'{run}' read as '{alias}' ({d} letter{'s' if d > 1 else ''} off)",
        run,
        others,
    )


def match_muscle(stem: str) -> NameMatch | None:
    """The muscle a mesh file's name (without suffix) names, or None.

    By the longest run of its words that spells a muscle of `MUSCLES` (any prefix or
    suffix around it, any case, separators or none; an abbreviation as a whole word; a
    misspelling of a letter or two in a long name):

    >>> match_muscle("VHF_Right_Muscle_Illiacus_smooth").name
    'iliacus'
    >>> match_muscle("S07_R_gracilis").name, match_muscle("r_vas_lat").name
    ('gracilis', 'vastus_lateralis')
    >>> match_muscle("Subject12_Right_VL").how
    "abbreviation 'vl'"
    """
    return _best(mesh_name_tokens(stem)[0], MUSCLES)


def match_group(stem: str) -> NameMatch | None:
    """The group of muscles (`GROUPS`) a mesh file's name names, or None.

    >>> match_group("R_Iliopsoas").name, match_group("Gastrocnemius_L").name
    ('iliopsoas', 'gastrocnemius')
    """
    return _best(mesh_name_tokens(stem)[0], GROUPS)


def match_bone(stem: str) -> tuple[NameMatch, bool] | None:
    """The bone or landmark a mesh file's name names, and whether it is a landmark.

    A landmark (a cartilage) where its spelling is the longer run ("FemoralHead" is the
    femoral head, not the femur), or where the name says cartilage and a landmark fits.

    >>> match_bone("L_Femoral_Head_Cart")[0].name, match_bone("femur-R")[0].name
    ('femoral_head', 'femur')
    """
    words, _ = mesh_name_tokens(stem)
    lm, bone = _best(words, LANDMARKS), _best(words, BONES)
    if lm is not None and (
        bone is None or len(lm.run) >= len(bone.run) or _CARTILAGE.intersection(words)
    ):
        return lm, True
    if bone is not None:
        return bone, False
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
