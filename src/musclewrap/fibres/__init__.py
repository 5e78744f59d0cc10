"""Fibres inside a muscle: streamlines of a harmonic field between its attachments."""

from ._field import Fibres, attachment_areas, fibres_at_rest

__all__ = ["Fibres", "attachment_areas", "fibres_at_rest"]
