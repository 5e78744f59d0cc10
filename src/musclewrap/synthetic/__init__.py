"""Synthetic muscles and motions shipped with the package (no external data needed)."""

from ._capsule import (
    CAPSULE_SCENARIOS,
    capsule,
    capsule_scenario,
    principal_axis_scenario,
    rings_mesh,
)
from ._demo import DemoScene, demo_scene

__all__ = [
    "CAPSULE_SCENARIOS",
    "DemoScene",
    "capsule",
    "capsule_scenario",
    "demo_scene",
    "principal_axis_scenario",
    "rings_mesh",
]
