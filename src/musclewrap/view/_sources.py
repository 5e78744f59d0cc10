"""What the viewer shows: a scene solved live, or a finished run played back, as one protocol.

The page (`._app.Viewer`) asks a `Source` for the pose of a `._state.Request` and sends
the state it gives back; it does not know which source it has. `LiveSource` solves
each pose as a run would (`musclewrap.run.LiveScene`); `Playback` reads a run's
``scene.pvd`` frame by frame (`._playback.Series`).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from pathlib import Path
from typing import Any, Protocol

import numpy as np

from .._typing import FloatArray
from ..mesh import apply_transform
from ..output import View, stretch_colours
from ..run import Coordinate, LiveScene, PoseResult
from ._playback import Series, segments, triangles
from ._state import Drawn, Request, cells, contact_colours, points, polylines, time_text

__all__ = ["LiveSource", "Playback", "Source"]


class Source(Protocol):
    """What the viewer's page needs of what it shows.

    ``names[kind]``: the parts' names per kind (``muscle``, ``bone``, ``lines``,
    ``fibres``), in the order of their state's names (``muscle0_p``, ...).
    ``colourings``: the colour menu's keys it offers; ``kept_out_of``: what its contact
    colouring measures to; ``can_write``: whether "Write this pose" is offered.
    """

    title: str
    n_frames: int
    times: FloatArray
    coordinates: list[Coordinate]
    names: dict[str, list[str]]
    colourings: tuple[str, ...]
    kept_out_of: str
    can_write: bool
    first_status: str

    def faces(self) -> dict[str, Any]:
        """The triangles' state sent before the first pose (empty: they come with it)."""
        ...

    def view(self, size: tuple[int, int]) -> View:
        """The camera of the run's pictures, for a view of ``size``."""
        ...

    def pose(
        self, r: Request, values: dict[str, float], colour: str
    ) -> tuple[dict[str, Any], float]:
        """The state of the pose ``r`` asks for, and the seconds its solve (or read) took.

        ``values``: the sliders' values, which a frame's pose moves to its own.
        """
        ...

    def colours(self, colour: str) -> dict[str, Any]:
        """The muscles' colours of the pose shown last, in the colouring ``colour``."""
        ...

    def after_first(self) -> None:
        """Work worth doing once the first picture is out (compiling kernels, say)."""
        ...

    def lighter(self) -> dict[str, Any]:
        """The lighter surfaces (`Lighter`) of the pose shown last, as state to send.

        What a `Request` with ``moving`` draws; made once (empty after that, or where the
        scene is within the budget), when the page has been idle after its first picture.
        """
        ...

    def still(self) -> dict[str, Any]:
        """The pose shown last in full, where it was sent lighter (empty: nothing to send)."""
        ...

    def write(self, folder: Path) -> list[Path] | None:
        """The pose shown last written into ``folder`` (None: nothing shown yet)."""
        ...


class LiveSource:
    """A scene solved pose by pose (`musclewrap.run.LiveScene`)."""

    colourings = ("stretch", "contact")
    can_write = True
    first_status = "solving the first pose ..."

    def __init__(self, scene: LiveScene) -> None:
        self.scene = scene
        self.title = f"musclewrap view: {scene.scene.name or scene.scene.path.name}"
        self.n_frames = scene.n_frames
        self.times = scene.times
        self.coordinates = scene.coordinates
        names = [j.name for j in scene.jobs]
        self.names = {
            "muscle": names,
            "bone": list(scene.bone_body),
            "lines": names,
            "fibres": names if scene.scene.fibres is not None else [],
        }
        self.kept_out_of = "a bone or another muscle" if scene.grouped else "a bone"
        # the triangles, once, with the first pose: the muscles' solvers are built in the
        # solver thread while the page loads
        self._faces_due = True
        self._bone_meshes: dict[str, Any] = {}
        self.last: PoseResult | None = None
        self.drawn = Drawn()  # the surfaces' positions the page has, full and lighter

    def faces(self) -> dict[str, Any]:
        return {}

    def view(self, size: tuple[int, int]) -> View:
        return self.scene.view(size=size)  # type: ignore[no-any-return]

    def _faces(self) -> dict[str, Any]:
        self._bone_meshes = self.scene.bone_meshes()
        out = {}
        for i, n in enumerate(self.names["muscle"]):
            out[f"muscle{i}_f"] = cells(self.scene.muscle_faces(n))
        for i, b in enumerate(self.names["bone"]):
            out[f"bone{i}_f"] = cells(self._bone_meshes[b][1])
        return out

    def pose(
        self, r: Request, values: dict[str, float], colour: str
    ) -> tuple[dict[str, Any], float]:
        t0 = time.perf_counter()
        res = self.scene.solve(
            r.values if r.kind == "values" else None,
            frame=r.frame if r.kind == "frame" else None,
        )
        self.last = res
        seconds = time.perf_counter() - t0
        up: dict[str, Any] = {}
        if self._faces_due:  # the triangles, with the first pose
            up.update(self._faces())
            self._faces_due = False
        up["light"] = self.drawn.begin(r.moving)
        for i, b in enumerate(self.names["bone"]):  # sent where it moved in the output frame
            T = res.bones[b]
            self.drawn.put(up, f"bone{i}", self._bone_at(b, T), T.tobytes())
        for i, n in enumerate(self.names["muscle"]):
            self.drawn.put(up, f"muscle{i}", res.muscles[n])
            up[f"lines{i}_p"], up[f"lines{i}_f"] = polylines(res.lines[n])
        for i, n in enumerate(self.names["fibres"]):
            P = res.fibres.get(n)
            up[f"fibres{i}_p"], up[f"fibres{i}_f"] = polylines([] if P is None else list(P))
        up.update(self.colours(colour))
        if r.frame is not None:
            up["time_text"] = time_text(self.times, self.n_frames, r.frame)
        else:
            up["time_text"] = "a pose of the sliders (not a frame)"
        for i, c in enumerate(self.coordinates):
            v = float(res.values[c.name])
            up[f"q{i}_label"] = f"{v:.2f} {c.unit}"  # the pose shown
            if r.kind == "frame":  # the sliders go to the frame's pose
                values[c.name] = v
        unit = self.scene.scene.mesh_unit
        overlap = res.overlap
        up["status"] = (
            f"volume error {res.volume_error:.1e} (largest of {len(res.rows)} muscles) · deepest "
            f"in a bone {res.penetration:.3g} {unit}"
            + ("" if np.isnan(overlap) else f" · deepest in another muscle {overlap:.3g} {unit}")
            + f" · iterations {max(row['iterations'] for row in res.rows.values())}"
        )
        bad = res.unconverged
        up["warning"] = (
            "NOT CONVERGED at this pose: "
            + "; ".join(f"{n}: {why}" for n, why in bad.items())
            + " (the muscles shown are the solver's last iterate)"
            if bad
            else ""
        )
        return up, seconds

    def colours(self, colour: str) -> dict[str, Any]:
        res = self.last
        if res is None:
            return {}
        up: dict[str, Any] = {}
        for i, n in enumerate(self.names["muscle"]):
            if colour == "contact":
                rgb = contact_colours(self.scene.contact(res)[n])
            else:
                rgb = stretch_colours(res.stretch[n])
            self.drawn.colours(up, f"muscle{i}", rgb)
        return up

    def after_first(self) -> None:
        # the contact colours' distances once, after the first picture: their kernels
        # compiled (or read from Numba's cache) before the colour menu asks for them
        if self.last is not None:
            self.scene.contact(self.last)

    def lighter(self) -> dict[str, Any]:
        res = self.last
        if res is None or self.drawn.light:
            return {}
        meshes, now = {}, {}
        for i, n in enumerate(self.names["muscle"]):
            meshes[f"muscle{i}"] = (res.muscles[n], self.scene.muscle_faces(n))
            now[f"muscle{i}"] = (res.muscles[n], None)
        for i, b in enumerate(self.names["bone"]):
            T = res.bones[b]
            meshes[f"bone{i}"] = self._bone_meshes[b]
            now[f"bone{i}"] = (self._bone_at(b, T), T.tobytes())
        return self.drawn.make_light(meshes, now)

    def still(self) -> dict[str, Any]:
        return self.drawn.still()

    def _bone_at(self, b: str, T: FloatArray) -> Callable[[], FloatArray]:
        """Bone ``b``'s display positions placed by ``T`` (computed where they are sent)."""
        return lambda: apply_transform(T, self._bone_meshes[b][0])

    def write(self, folder: Path) -> list[Path] | None:
        if self.last is None:
            return None
        return self.scene.write(self.last, folder)  # type: ignore[no-any-return]


class Playback:
    """A finished run's ``scene.pvd``, frame by frame (no solve)."""

    colourings = ("stretch",)
    kept_out_of = "a bone"
    can_write = False
    first_status = "reading the first frame ..."

    def __init__(self, series: Series) -> None:
        self.series = series
        self.title = f"musclewrap view: {series.folder}"
        self.n_frames = len(series)
        self.times = series.times
        self.coordinates: list[Coordinate] = []
        self.names: dict[str, list[str]] = {"muscle": [], "bone": [], "lines": [], "fibres": []}
        for name, kind in series.parts.items():
            self.names[kind].append(name)
        self.drawn = Drawn()  # the surfaces' positions the page has, full and lighter
        self._k = 0  # the frame shown last
        self._first: dict[str, tuple[FloatArray, Any]] = {}  # per part: its first surface

    def faces(self) -> dict[str, Any]:
        s = self.series
        out = {}
        for kind in ("muscle", "bone"):
            for i, n in enumerate(self.names[kind]):
                first = next((k for k in range(len(s)) if n in s.files[k]), None)
                if first is not None:
                    d = s.part(first, n)
                    assert d is not None
                    F = triangles(d)
                    self._first[f"{kind}{i}"] = (d["points"], F)
                    out[f"{kind}{i}_f"] = cells(F)
        return out

    def view(self, size: tuple[int, int]) -> View:
        return self.series.view(size=size)  # type: ignore[no-any-return]

    def pose(
        self, r: Request, values: dict[str, float], colour: str
    ) -> tuple[dict[str, Any], float]:
        t0 = time.perf_counter()
        s, k = self.series, int(r.frame or 0)
        self._k = k
        up: dict[str, Any] = {"time_text": time_text(self.times, self.n_frames, k)}
        up["light"] = self.drawn.begin(r.moving)
        for kind in ("muscle", "bone"):
            for i, n in enumerate(self.names[kind]):
                d = s.part(k, n)
                if d is None:
                    continue
                # a bone's file: the same as shown, a bone that does not move
                self.drawn.put(
                    up, f"{kind}{i}", d["points"], None if kind == "muscle" else s.files[k][n]
                )
                if kind == "muscle":
                    c = d.get("point:area_stretch", np.ones(len(d["points"])))
                    self.drawn.colours(up, f"muscle{i}", stretch_colours(c))
        for kind in ("lines", "fibres"):
            for i, n in enumerate(self.names[kind]):
                d = s.part(k, n)
                if d is None:
                    continue
                up[f"{kind}{i}_p"] = points(d["points"])
                up[f"{kind}{i}_f"] = cells(segments(d))
        up["status"] = f"playing back {s.folder / 'scene.pvd'} ({len(s)} frames; no solve)"
        return up, time.perf_counter() - t0

    def colours(self, colour: str) -> dict[str, Any]:
        return {}  # a run's colours are its files' (the stretch)

    def after_first(self) -> None:
        pass

    def lighter(self) -> dict[str, Any]:
        if self.drawn.light or not self._first:
            return {}
        s, k, now = self.series, self._k, {}
        for kind in ("muscle", "bone"):
            for i, n in enumerate(self.names[kind]):
                d = s.part(k, n)
                if d is not None:  # this frame's, for the first slider moved
                    now[f"{kind}{i}"] = (d["points"], None if kind == "muscle" else s.files[k][n])
        return self.drawn.make_light(self._first, now)

    def still(self) -> dict[str, Any]:
        return self.drawn.still()

    def write(self, folder: Path) -> list[Path] | None:
        return None
