"""The rest pose's fit to the model's bones (`musclewrap.model.fit_posture`), either side.

    python benchmarks/tuning/bench_posture.py [SCENE] [--from FLEXION ADDUCTION ...] [--settings]

For a registered scene with bones from the model (default `examples/gait2392_leg.toml`):
the fit ``musclewrap check`` makes, started from each rest pose of ``--from`` (hip flexion
and adduction in degrees, the scene's other coordinates as written; default its own and
the model's zero), and with ``--settings`` each of the fit's keywords on either side of its
default, started from zero (and the cap off from the fitted pose: whether a second fit
stays). Per line: the fitted hip angles, whether the fit settled inside its search, the
muscle vertices in the priced bones before and after, the psoas's and iliacus's, and the
share of the paths of the muscles that reach those bones inside them (before -> after).
"""

from __future__ import annotations

import argparse
import dataclasses
import time
from pathlib import Path

import numpy as np

from musclewrap.mesh import apply_transform
from musclewrap.model import OpenSimModel
from musclewrap.run._posture import rest_posture
from musclewrap.run._read import _read_bone, _read_muscle, default_cache_dir
from musclewrap.scene import drive_scene, load_scene

ROOT = Path(__file__).resolve().parents[2]

#: (keywords, start) either side of the defaults (alike 0.02, cap 4, margin 2, spacing 2)
SETTINGS = [
    ({}, None),
    ({"alike": 0.0}, None),
    ({"alike": 0.01}, None),
    ({"alike": 0.05}, None),
    ({"cap": 2.0}, None),
    ({"cap": 1e9}, None),
    ({"margin": 1.0}, None),
    ({"margin": 3.0}, None),
    ({"spacing": 1.0}, None),
    ({"cap": 1e9}, "fitted"),
]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("scene", nargs="?", default=str(ROOT / "examples" / "gait2392_leg.toml"))
    ap.add_argument("--from", dest="starts", nargs="+", type=float, default=None)
    ap.add_argument("--settings", action="store_true")
    a = ap.parse_args()
    scene = load_scene(Path(a.scene))
    own = (scene.rest_pose.get("hip_flexion_r", 0.0), scene.rest_pose.get("hip_adduction_r", 0.0))
    cache = default_cache_dir()
    model = OpenSimModel(scene.osim)
    muscles = {
        m.name: _read_muscle(m, cache)[:2] for m in scene.muscles if m.frame == "registration"
    }
    bones = {b.name: _read_bone(b, cache)[:2] for b in scene.bones}
    if a.settings:
        runs = [(kw, (0.0, 0.0) if start is None else own) for kw, start in SETTINGS]
    else:
        flat = a.starts if a.starts is not None else [*own, 0.0, 0.0]
        runs = [({}, (flat[i], flat[i + 1])) for i in range(0, len(flat) - 1, 2)]
    for kw, start in runs:
        rest = {**scene.rest_pose, "hip_flexion_r": start[0], "hip_adduction_r": start[1]}
        s = dataclasses.replace(scene, rest_pose=rest)
        drive = drive_scene(s, "0:1", {n: V.mean(axis=0) for n, (V, _) in bones.items()})
        body_b = {n: (apply_transform(drive.to_body[n], V), F) for n, (V, F) in bones.items()}
        t0 = time.perf_counter()
        found = rest_posture(s, model, muscles, body_b, None, kw)
        if found is None:
            print(
                f"{kw or 'defaults'} from {start}: nothing to fit (no registration, model bone or coordinate)"
            )
            continue
        f = found.fit
        got = {
            c: rest.get(c, 0.0) + float(np.degrees(d))
            for c, d in zip(f.coordinates, f.change, strict=True)
        }
        n0, n1 = (sum(v[0] for v in d.values()) for d in (f.before, f.after))
        each = ", ".join(
            f"{m} {f.before.get(m, (0, 0))[0]} ({f.before.get(m, (0, 0.0))[1]:.1f}) -> "
            f"{f.after.get(m, (0, 0))[0]} ({f.after.get(m, (0, 0.0))[1]:.1f})"
            for m in ("psoas", "iliacus")
        )
        print(
            f"{kw or 'defaults'} from {start}: "
            + ", ".join(f"{c} {v:.4g}" for c, v in got.items())
            + f"; settled {f.settled}; muscle vertices in the bones {n0} -> {n1} ({each}); "
            f"paths inside {100 * found.inside[0]:.0f} -> {100 * found.inside[1]:.0f} % "
            f"({time.perf_counter() - t0:.1f} s)",
            flush=True,
        )


if __name__ == "__main__":
    main()
