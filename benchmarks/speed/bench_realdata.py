"""Real muscles: preparation time, skeleton fit, shape change and time per pose.

Run: ``python benchmarks/speed/bench_realdata.py [DATA_DIR]`` (default ``../shared/data``).

For every VHF muscle in ``DATA/vhf`` (and the LHDL gluteus maximus): preparation (clean, cage, coordinates,
proxy) and bind (skeleton coordinates, factorisation) times, then the five capsule scenarios
on the muscle's principal axis with the default solver: iterations, volume error, skeleton
fit, largest shape change (spike measure, mean rest edge lengths) and the median time per
pose over the median float64 ``W @ X`` (numpy, 3 columns) timed in phases alternating with it
(`musclewrap._bench.interleaved_ms`).
"""

import sys
import time
from pathlib import Path

import numpy as np

from musclewrap import Muscle
from musclewrap._bench import interleaved_ms
from musclewrap.synthetic import CAPSULE_SCENARIOS, principal_axis_scenario


def main(data: Path, repeats: int = 21) -> None:
    files = sorted((data / "vhf").glob("VHF_*_Muscle_*.stl"))
    files.append(data / "lhdl" / "muscles" / "LHDL_R_GluteusMaximus.vtk")
    Muscle.from_file(files[0])  # compile/load the kernels once, outside the timings
    print(
        "muscle                      verts  prep s  bind s  scenario    it  vol err   "
        "fit mm  shape  ms/pose  W@X ms  x W@X"
    )
    for path in files:
        t = time.perf_counter()
        m = Muscle.from_file(path)
        prep = time.perf_counter() - t
        X = np.random.default_rng(0).random((m.W.shape[1], 3))
        name = path.name.replace("_smooth.stl", "").replace("VHF_", "").replace(".vtk", "")
        for k, sc in enumerate(CAPSULE_SCENARIOS):
            rest, cur = principal_axis_scenario(m.V, sc)
            t = time.perf_counter()
            d = m.bind(rest)
            bind = time.perf_counter() - t
            r = d.deform(cur)
            ms, wx = interleaved_ms(
                lambda d=d, cur=cur: d.deform(cur), lambda W=m.W, X=X: W @ X, repeats
            )
            head = f"{name[:27]:27s} {len(m.V):6d}  {prep:6.2f}" if k == 0 else " " * 41
            print(
                f"{head}  {bind:6.3f}  {sc:10s} {r.iterations:2d}  {r.relative_volume_error:8.1e}"
                f"  {r.skeleton_fit_mean:6.3f}  {m.shape_change(r.V).max():5.3f}"
                f"  {ms:7.2f}  {wx:6.2f}  {ms / wx:5.2f}",
                flush=True,
            )


if __name__ == "__main__":
    default = Path(__file__).resolve().parents[2].parent / "shared" / "data"
    main(Path(sys.argv[1]) if len(sys.argv) > 1 else default)
