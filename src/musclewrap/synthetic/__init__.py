"""Synthetic muscles and motions shipped with the package (no external data needed)."""

from ._capsule import CAPSULE_SCENARIOS, capsule, capsule_scenario, rings_mesh

__all__ = ["CAPSULE_SCENARIOS", "capsule", "capsule_scenario", "rings_mesh"]
