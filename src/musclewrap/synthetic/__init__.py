"""Synthetic muscles and motions shipped with the package (no external data needed).

`write_knee_scene` writes the embedded demo (``musclewrap demo``): two muscles side by
side wrapping over a knee's condyles in flexion, as an ordinary scene. `capsule` and its
scenarios are the 2012 implementation's benchmark; `demo_scene` a single muscle beside
two rods, driven from Python (tests and fuzzing).
"""

from ._capsule import (
    CAPSULE_SCENARIOS,
    capsule,
    capsule_scenario,
    principal_axis_scenario,
    rings_mesh,
    sleeve,
)
from ._demo import DemoScene, demo_scene
from ._knee import KneeDemo, knee_demo, write_knee_scene

__all__ = [
    "CAPSULE_SCENARIOS",
    "DemoScene",
    "KneeDemo",
    "capsule",
    "capsule_scenario",
    "demo_scene",
    "knee_demo",
    "principal_axis_scenario",
    "rings_mesh",
    "sleeve",
    "write_knee_scene",
]
