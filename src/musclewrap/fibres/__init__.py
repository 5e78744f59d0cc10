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

__all__ = [
    "Fibres",
    "HarmonicField",
    "areas_on_bones",
    "attachment_areas",
    "fibres_at_rest",
    "harmonic_field",
    "keep_inside",
    "trace_fibres",
]
