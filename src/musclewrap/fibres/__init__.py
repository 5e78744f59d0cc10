"""Fibres inside a muscle: streamlines of a harmonic field between its attachments."""

from ._field import (
    Fibres,
    HarmonicField,
    attachment_areas,
    fibres_at_rest,
    harmonic_field,
    keep_inside,
    trace_fibres,
)

__all__ = [
    "Fibres",
    "HarmonicField",
    "attachment_areas",
    "fibres_at_rest",
    "harmonic_field",
    "keep_inside",
    "trace_fibres",
]
