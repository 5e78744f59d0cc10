"""Accuracy figures quoted in README.md, BENCHMARKS.md and the code, on the real meshes.

Run: ``python benchmarks/accuracy/bench_accuracy.py [DATA_DIR]`` (default ``../shared/data``).

1. Mean value coordinates: how well they reproduce each VHF mesh (muscles, bones,
   cartilage) from its cage, ``max |W C - V|`` over the mesh's bounding-box diagonal, for
   several values of the in-plane tolerance (``tol.mvc_in_plane``: a face whose plane holds
   the point to that sine is left out).
2. The default solve's single-precision proxy products: the largest vertex distance, over
   the muscle's size, between the default solve and the same iteration in double precision
   (`Deformer._proxy_matrices`), and whether the iteration counts agree, on the 15K
   capsule and every VHF muscle in the five scenarios on its principal axis.
"""

import sys
from pathlib import Path

import numpy as np

from musclewrap import Muscle
from musclewrap.constants import tol
from musclewrap.coordinates._mvc import _mvc_block
from musclewrap.synthetic import (
    CAPSULE_SCENARIOS,
    capsule,
    capsule_scenario,
    principal_axis_scenario,
)

IN_PLANE = (1e-10, 1e-8, 1e-7, 1e-6, 1e-5)


def main(data: Path) -> None:
    files = sorted((data / "vhf").glob("VHF_*.stl"))
    print(
        f"1. reproduction max |W C - V| / diagonal, by in-plane tolerance (default {tol.mvc_in_plane:g})"
    )
    print(f"   {'mesh':44s}" + "".join(f"{t:>9.0e}" for t in IN_PLANE))
    muscles = []
    for f in files:
        m = Muscle.from_file(f)
        if "_Muscle_" in f.name:
            muscles.append((f.stem, m))
        diag = np.linalg.norm(np.ptp(m.V, axis=0))
        C, CF = m.cage.C, m.cage.CF
        errs = [np.abs(_mvc_block(m.V, C, CF, t) @ C - m.V).max() / diag for t in IN_PLANE]
        print(f"   {f.stem[:44]:44s}" + "".join(f"{e:9.1e}" for e in errs))
    print("2. float32 proxy products against the same iteration in float64")
    cases = [("capsule", Muscle.from_mesh(*capsule()), capsule_scenario)]
    cases += [(n, m, lambda s, m=m: principal_axis_scenario(m.V, s)) for n, m in muscles]
    worst = 0.0
    for name, m, scenario in cases:
        size = np.linalg.norm(np.ptp(m.V, axis=0))
        devs, same = [], True
        for s in CAPSULE_SCENARIOS:
            rest, cur = scenario(s)
            d = m.bind(rest)
            r32 = d.deform(cur)
            r64 = d._proxy_matrices(np.float64).deform(cur)
            devs.append(np.abs(r32.V - r64.V).max() / size)
            same &= r32.iterations == r64.iterations
        worst = max(worst, max(devs))
        print(f"   {name[:44]:44s} largest {max(devs):.1e} of the size, iterations equal: {same}")
    print(f"   worst {worst:.1e}")


if __name__ == "__main__":
    main(Path(sys.argv[1]) if len(sys.argv) > 1 else Path("../shared/data"))
