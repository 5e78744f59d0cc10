"""The OpenSim side of a scene: poses, muscle paths and body frames (optional extra)."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from .._typing import FloatArray, PathLike
from ..errors import SceneError, suggest

__all__ = ["OpenSimModel", "import_opensim"]


def import_opensim() -> Any:
    """Import the ``opensim`` package quietly, or explain how to install it.

    Raises
    ------
    ImportError
        Naming the extra: ``pip install 'musclewrap[opensim]'``.
    """
    try:
        import opensim
    except ImportError as exc:
        raise ImportError(
            "OpenSim scenes need the 'opensim' package: pip install 'musclewrap[opensim]' "
            f"(or give per-frame action lines in a CSV instead; import failed: {exc})"
        ) from None
    # OpenSim logs to stdout and, by default, to ./opensim.log: keep both quiet.
    opensim.Logger.setLevelString("error")
    try:
        opensim.Logger.removeFileSink()
    except Exception:  # pragma: no cover - older bindings without file sinks  # noqa: BLE001
        pass
    return opensim


def _couplers(osim: Any, model: Any, state: Any) -> tuple[list[tuple[Any, ...]], bool]:
    """A model's enforced coordinate couplers, and whether it has other constraints.

    The couplers come each after those that set its independent coordinates; constraints
    of other kinds (or couplers in a cycle) need OpenSim's assembly. Each coupler is
    (dependent name, independent names, function, scale factor, a vector for the
    function's arguments).
    """
    found, other = [], False
    cs = model.getConstraintSet()
    for i in range(cs.getSize()):
        c = cs.get(i)
        if not c.isEnforced(state):
            continue
        cc = osim.CoordinateCouplerConstraint.safeDownCast(c)
        if cc is None:
            other = True
            continue
        names = cc.getIndependentCoordinateNames()
        independent = tuple(names.get(k) for k in range(names.getSize()))
        scale = osim.PropertyHelper.getValueDouble(cc.getPropertyByName("scale_factor"))
        found.append(
            (cc.getDependentCoordinateName(), independent, cc.getFunction(), scale,
             osim.Vector(len(independent), 0.0))
        )  # fmt: skip
    ordered: list[tuple[Any, ...]] = []
    while found:  # each after the couplers that set its independent coordinates
        later = {f[0] for f in found}
        ready = [f for f in found if not later.intersection(f[1])]
        if not ready:  # a cycle: OpenSim's assembly resolves it
            return ordered, True
        ordered += ready
        found = [f for f in found if f not in ready]
    return ordered, other


class OpenSimModel:
    """An OpenSim model with one working state.

    Parameters
    ----------
    path : str or os.PathLike
        The ``.osim`` file.

    Raises
    ------
    SceneError
        If the file is missing or OpenSim cannot load it (its message is quoted).
    ImportError
        If the ``opensim`` extra is not installed.
    """

    def __init__(self, path: PathLike) -> None:
        self.path = Path(path)
        if not self.path.is_file():
            raise SceneError(f"{self.path}: no such OpenSim model file")
        osim = import_opensim()
        self._osim = osim
        try:
            self.model = osim.Model(str(self.path))
            self.state = self.model.initSystem()
        except Exception as exc:  # OpenSim raises its own exception types  # noqa: BLE001
            msg = " ".join(str(exc).split())
            raise SceneError(f"{self.path}: OpenSim could not load the model: {msg}") from None
        cs = self.model.getCoordinateSet()
        self._coords = {cs.get(i).getName(): cs.get(i) for i in range(cs.getSize())}
        bs = self.model.getBodySet()
        self.body_names = tuple(bs.get(i).getName() for i in range(bs.getSize()))
        self._paths: dict[str, Any] = {}
        ms = self.model.getMuscles()
        for i in range(ms.getSize()):
            self._paths[ms.get(i).getName()] = ms.get(i).getGeometryPath()
        self._couplers, self._constrained = _couplers(osim, self.model, self.state)

    # ------------------------------------------------------------ names
    @property
    def coordinate_names(self) -> tuple[str, ...]:
        """Names of the model's coordinates."""
        return tuple(self._coords)

    @property
    def path_names(self) -> tuple[str, ...]:
        """Names of the model's muscles (each has a geometry path)."""
        return tuple(self._paths)

    def parent_joints(self) -> dict[str, tuple[str, tuple[str, ...]]]:
        """Per body: its parent body (or 'ground') and the coordinates of the joint between."""
        js = self.model.getJointSet()
        out = {}
        for i in range(js.getSize()):
            j = js.get(i)
            child = j.getChildFrame().findBaseFrame().getName()
            parent = j.getParentFrame().findBaseFrame().getName()
            out[child] = (
                parent,
                tuple(j.get_coordinates(k).getName() for k in range(j.numCoordinates())),
            )
        return out

    def path_bodies(self, paths: Sequence[str]) -> set[str]:
        """The bodies the points of ``paths`` are fixed in (at the current pose)."""
        return {b for p in paths for b in self.path_point_bodies(p)}

    def coordinates_between(self, bodies: Sequence[str], frame: str) -> tuple[list[str], list[str]]:
        """The coordinates that move ``bodies`` relative to ``frame``, in the model's order.

        Walks each body's joints up to ``frame`` (or to the root); a coordinate coupled
        to others (Rajagopal's ``knee_angle_r_beta``) brings the ones it follows
        instead, and a locked one is left out. Returns (free coordinates, locked ones).
        """
        up = self.parent_joints()
        coupled = {}
        cs = self.model.getConstraintSet()
        for i in range(cs.getSize()):
            c = self._osim.CoordinateCouplerConstraint.safeDownCast(cs.get(i))
            if c is not None:
                names = c.getIndependentCoordinateNames()
                coupled[c.getDependentCoordinateName()] = [
                    names.get(k) for k in range(names.getSize())
                ]
        wanted: set[str] = set()
        locked: set[str] = set()
        for b in bodies:
            while b != frame and b in up:
                parent, coords = up[b]
                if parent == "ground" and frame != "ground":
                    break  # the root's joint moves the whole scene: held still
                for name in coords:
                    for c in coupled.get(name, [name]):
                        (locked if self._coords[c].getDefaultLocked() else wanted).add(c)
                b = parent
        order = list(self._coords)
        return [c for c in order if c in wanted], [c for c in order if c in locked]

    def is_rotational(self, name: str) -> bool:
        """Whether coordinate ``name`` is an angle (radians in the model)."""
        return int(self._coords[name].getMotionType()) == 1

    def coordinate_range(self, name: str) -> tuple[float, float]:
        """A coordinate's range in the model (model units: radians or metres)."""
        c = self._coords[name]
        return float(c.getRangeMin()), float(c.getRangeMax())

    def default_pose(self) -> dict[str, float]:
        """Each coordinate's default value (model units: radians or metres)."""
        return {n: float(c.getDefaultValue()) for n, c in self._coords.items()}

    def _frame(self, name: str) -> Any:
        if name == "ground":
            return self.model.getGround()
        if name not in self.body_names:
            raise SceneError(
                f"{self.path}: the model has no body '{name}'; "
                + suggest(name, ("ground", *self.body_names))
            )
        return self.model.getBodySet().get(name)

    def check_path(self, name: str) -> None:
        """Raise `SceneError` (with the nearest names) if no force has path ``name``."""
        if name not in self._paths:
            raise SceneError(
                f"{self.path}: the model has no muscle '{name}'; " + suggest(name, self.path_names)
            )

    def check_body(self, name: str) -> None:
        """Raise `SceneError` (with the nearest names) if ``name`` is not a body or 'ground'."""
        self._frame(name)

    # ------------------------------------------------------------ poses
    def set_pose(self, values: Mapping[str, float]) -> None:
        """Set coordinate values (radians or metres) and realize positions.

        Coordinates not named keep their current values. A coordinate that a
        `CoordinateCouplerConstraint` couples to others takes the constraint's value of
        them, exactly. A model with constraints of any other kind is assembled by
        OpenSim, from a fresh assembly solver every time: OpenSim's own solver tracks
        from the pose it last assembled, so a pose would depend on the poses before it
        (by up to 1e-9 rad) and a frame on the frames run with it.
        """
        for name, v in values.items():
            self._coords[name].setValue(self.state, float(v), False)
        for dependent, independent, function, scale, args in self._couplers:
            for k, name in enumerate(independent):
                args.set(k, self._coords[name].getValue(self.state))
            self._coords[dependent].setValue(self.state, scale * function.calcValue(args), False)
        if self._constrained:
            self.model.updateAssemblyConditions(self.state)
            self.model.assemble(self.state)
        self.model.realizePosition(self.state)

    def path_points(self, name: str, frame: str) -> FloatArray:
        """Active points of a muscle's path (via, moving, wrap) in ``frame`` (model units).

        Returns
        -------
        (k, 3) float64 array
        """
        gp = self._paths[name]
        target = self._frame(frame)
        arr = gp.getCurrentPath(self.state)
        out = np.empty((arr.getSize(), 3))
        for k in range(arr.getSize()):
            pp = arr.get(k)
            loc = pp.getLocation(self.state)
            g = pp.getParentFrame().findStationLocationInAnotherFrame(self.state, loc, target)
            out[k] = (g.get(0), g.get(1), g.get(2))
        return out

    def path_point_bodies(self, name: str) -> list[str]:
        """The body each active point of a muscle's path is fixed in (as `path_points`)."""
        arr = self._paths[name].getCurrentPath(self.state)
        return [arr.get(k).getParentFrame().findBaseFrame().getName() for k in range(arr.getSize())]

    def path_set_conditional(self, name: str) -> tuple[int, bool]:
        """The number of points in a muscle's path set, and whether any is conditional."""
        ps = self._paths[name].getPathPointSet()
        kinds = [ps.get(k).getConcreteClassName() for k in range(ps.getSize())]
        return len(kinds), "ConditionalPathPoint" in kinds

    def path_set_points(self, name: str, frame: str) -> tuple[FloatArray, list[str]]:
        """Every point a muscle's path is defined by, active or not, in ``frame``, and bodies.

        The path's point set in its order (`path_points` gives the active ones and the
        wraps' points): a conditional via point outside its coordinate's range is
        still where its body holds it. Model units.
        """
        target = self._frame(frame)
        ps = self._paths[name].getPathPointSet()
        out = np.empty((ps.getSize(), 3))
        bodies = []
        for k in range(ps.getSize()):
            pp = ps.get(k)
            loc = pp.getLocation(self.state)
            g = pp.getParentFrame().findStationLocationInAnotherFrame(self.state, loc, target)
            out[k] = (g.get(0), g.get(1), g.get(2))
            bodies.append(pp.getParentFrame().findBaseFrame().getName())
        return out, bodies

    def moment_arm(self, path: str, coordinate: str) -> float:
        """OpenSim's moment arm of a muscle path about a coordinate in the current pose.

        ``GeometryPath.computeMomentArm`` (model length units for a rotational
        coordinate, none for a translational one).
        """
        return float(self._paths[path].computeMomentArm(self.state, self._coords[coordinate]))

    def transform(self, body: str, frame: str) -> FloatArray:
        """4x4 rigid transform taking ``body``-frame coordinates to ``frame`` (model units)."""
        src, dst = self._frame(body), self._frame(frame)
        Vec3 = self._osim.Vec3
        pts = []
        for p in ((0.0, 0.0, 0.0), (1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0)):
            g = src.findStationLocationInAnotherFrame(self.state, Vec3(*p), dst)
            pts.append((g.get(0), g.get(1), g.get(2)))
        P = np.array(pts)
        T = np.eye(4)
        T[:3, :3] = (P[1:] - P[0]).T
        T[:3, 3] = P[0]
        return T

    def mass_center(self, body: str) -> FloatArray:
        """A body's centre of mass in its own frame (model units)."""
        if body == "ground":
            raise SceneError("'ground' has no centre of mass: name a body or a bone mesh")
        c = self._frame(body).getMassCenter()
        return np.array([c.get(0), c.get(1), c.get(2)])
