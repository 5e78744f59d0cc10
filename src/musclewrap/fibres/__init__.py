"""Fibres inside a muscle: streamlines of a harmonic field between its attachments."""

from ._field import (
    Fibres,
    HarmonicField,
    areas_on_bones,
    attachment_areas,
    fibres_at_rest,
    harmonic_field,
    keep_inside,
    trace_fibres,
)
from ._published import LHDL_FIBRE_RANGES, published_cover

__all__ = [
    "LHDL_FIBRE_RANGES",
    "Fibres",
    "HarmonicField",
    "areas_on_bones",
    "attachment_areas",
    "fibres_at_rest",
    "harmonic_field",
    "keep_inside",
    "published_cover",
    "trace_fibres",
]
