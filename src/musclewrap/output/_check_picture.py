"""The picture of ``musclewrap check``: the rest pose from the front and the side.

Muscles translucent, bones opaque, each action line coloured by its distance outside
its muscle. Drawn by PyVista in a child process (``python -m
musclewrap.output._check_picture DATA PNG``): VTK can crash a process at its first
render where no OpenGL backend exists, and that becomes a clear error here.
"""

from __future__ import annotations

import os
import subprocess
import sys
import tempfile
from pathlib import Path
from typing import Any

import numpy as np

from ..mesh import atomic_path
from ._render import _INSTALL, _PALETTE, RenderingError

__all__ = ["draw_check"]


def draw_check(out: Path, data: dict[str, Any]) -> Path:
    """Draw ``data`` (from `musclewrap.scene.check_scene`) into the PNG ``out``."""
    arrays: dict[str, np.ndarray] = {}
    for kind in ("muscles", "bones"):
        for i, (n, (V, F)) in enumerate(data[kind].items()):
            arrays[f"{kind}|{i}|{n}|V"] = V
            arrays[f"{kind}|{i}|{n}|F"] = F
    for i, (P, d) in enumerate(data["lines"]):
        arrays[f"line|{i}|P"] = P
        arrays[f"line|{i}|d"] = d
    for i, (n, (start, end)) in enumerate(data.get("areas", {}).items()):
        arrays[f"areas|{i}|{n}|O"] = start
        arrays[f"areas|{i}|{n}|I"] = end
    env = dict(os.environ)
    if not env.get("DISPLAY"):
        env.setdefault("VTK_DEFAULT_OPENGL_WINDOW", "vtkEGLRenderWindow")
    with tempfile.TemporaryDirectory(prefix="musclewrap-check-") as tmp:
        src = Path(tmp) / "data.npz"
        np.savez(src, **arrays, view=data["view"], meta=np.array([data["title"], data["unit"]]))
        with atomic_path(out) as part:
            png = Path(tmp) / "check.png"
            r = subprocess.run(
                [sys.executable, "-m", "musclewrap.output._check_picture", str(src), str(png)],
                env=env, capture_output=True, text=True, timeout=300, check=False,
            )  # fmt: skip
            if r.returncode != 0 or not png.is_file():
                tail = (r.stderr or "").strip().splitlines()[-3:]
                raise RenderingError(
                    f"{out}: the picture could not be drawn ({' / '.join(tail) or r.returncode})"
                    + _INSTALL
                )
            part.write_bytes(png.read_bytes())
    return out


def _main(src: str, png: str) -> None:
    import pyvista as pv

    d = np.load(src)
    title, unit = (str(x) for x in d["meta"])
    front, up = d["view"]
    right = np.cross(front, up)
    groups: dict[tuple[str, int, str], dict[str, np.ndarray]] = {}
    for k in d.files:
        if k.startswith(("muscles|", "bones|", "line|", "areas|")):
            parts = k.split("|")
            if parts[0] == "line":
                groups.setdefault(("line", int(parts[1]), ""), {})[parts[2]] = d[k]
            else:
                groups.setdefault((parts[0], int(parts[1]), parts[2]), {})[parts[3]] = d[k]
    pl = pv.Plotter(off_screen=True, shape=(1, 2), window_size=(1600, 900), border=False)
    # the colours span the 95th percentile: a tendon running on far past its muscle
    # would otherwise leave every other line one colour
    ds = [g["d"] for (k, _, _), g in groups.items() if k == "line"]
    allV = np.vstack([g["V"] for (k, _, _), g in groups.items() if k == "muscles"])
    size = float(np.linalg.norm(np.ptp(allV, axis=0)))
    # at least 1 % of the muscles' size: lines all inside read as inside, not as a range
    # of rounding errors
    dmax = max(float(np.quantile(np.concatenate(ds), 0.95)) if ds else 0.0, 0.01 * size)
    centre = allV.mean(axis=0)
    for col, view in enumerate((front, right)):
        pl.subplot(0, col)
        pl.set_background("white")
        for (kind, i, name), g in sorted(groups.items()):
            if kind == "areas":
                # the fibres' attachment areas: origin dark red, insertion dark blue
                for key, colour in (("O", "#b2182b"), ("I", "#2166ac")):
                    if len(g[key]):
                        pl.add_points(
                            g[key], color=colour, point_size=5, render_points_as_spheres=True
                        )
                continue
            if kind == "line":
                continue
            F = np.hstack([np.full((len(g["F"]), 1), 3), g["F"]]).ravel()
            mesh = pv.PolyData(g["V"], F)
            if kind == "bones":
                pl.add_mesh(mesh, color=(0.93, 0.90, 0.80), smooth_shading=True)
            else:
                pl.add_mesh(
                    mesh, color=_PALETTE[i % len(_PALETTE)], opacity=0.35, smooth_shading=True
                )
        for (kind, _, _), g in sorted(groups.items()):
            if kind != "line":
                continue
            P = g["P"]
            line = pv.lines_from_points(P)
            line["distance"] = g["d"]
            pl.add_mesh(
                line.tube(radius=0.004 * size),
                scalars="distance", cmap="viridis", clim=(0, dmax), above_color="red",
                scalar_bar_args={"title": f"line outside its muscle ({unit})", "color": "black"},
                show_scalar_bar=col == 1,
            )  # fmt: skip
        # framed on the muscles (the bones may run on far beyond them)
        pl.camera_position = [tuple(centre + 3 * size * view), tuple(centre), tuple(up)]
        pl.reset_camera(bounds=np.ravel([allV.min(axis=0), allV.max(axis=0)], order="F"))
        pl.add_text(
            ("front" if col == 0 else "side") + (f" - {title}" if col == 0 else ""),
            font_size=11,
            color="black",
        )
        if col == 0 and any(k == "areas" for k, _, _ in groups):
            pl.add_text(
                "fibres' attachment areas: origin red, insertion blue",
                position="lower_left", font_size=9, color="black",
            )  # fmt: skip
    pl.screenshot(png)
    pl.close()


if __name__ == "__main__":  # pragma: no cover - run by draw_check in a child process
    _main(sys.argv[1], sys.argv[2])
