"""Published fibre moment arms to check ours against."""

from __future__ import annotations

__all__ = ["LHDL_FIBRE_RANGES", "published_cover"]

#: The LHDL specimen's fibres, Modenese & Kohout (2020), Table 2, as issue 48 quotes them:
#: (swept coordinate, muscle) -> the smallest and largest moment arm across the muscle's
#: fibres over the sweep of that coordinate, mm (8 of the table's 12 muscle-tasks). What
#: ``examples/lhdl_hip_sweeps.toml`` is checked against (BENCHMARKS.md, the gallery).
LHDL_FIBRE_RANGES: dict[tuple[str, str], tuple[float, float]] = {
    ("hip_flexion_r", "psoas"): (9.0, 26.0),
    ("hip_flexion_r", "iliacus"): (13.0, 46.0),
    ("hip_flexion_r", "gluteus_maximus"): (-92.0, -19.0),
    ("hip_flexion_r", "gluteus_medius"): (-35.0, 15.0),
    ("hip_adduction_r", "psoas"): (5.0, 21.0),
    ("hip_adduction_r", "gluteus_medius"): (-75.0, -4.0),
    ("hip_rotation_r", "psoas"): (-5.0, 4.0),
    ("hip_rotation_r", "iliacus"): (-2.0, 9.0),
}


def published_cover(lo: float, hi: float, published: tuple[float, float]) -> float:
    """The part (0 to 1) of the ``published`` range that ours, ``lo .. hi``, overlaps.

    What issue 48's 85 % is measured by (BENCHMARKS.md, the gallery).

    >>> published_cover(15.0, 35.0, (10.0, 30.0))
    0.75
    >>> published_cover(-5.0, 0.0, (1.0, 2.0))
    0.0
    """
    return max(min(hi, published[1]) - max(lo, published[0]), 0.0) / (published[1] - published[0])
