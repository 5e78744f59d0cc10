"""Action lines: validation, arc-length sampling and matching."""

from __future__ import annotations

import csv
from collections.abc import Iterator, Mapping
from dataclasses import dataclass
from pathlib import Path

import numba
import numpy as np
import numpy.typing as npt

from .._typing import FloatArray, PathLike
from .._validation import as_points

__all__ = [
    "LineError",
    "LineSampling",
    "PathLines",
    "check_lines",
    "csv_rows",
    "distinct_mask",
    "placement_problem",
    "polyline_at",
    "read_lines_csv",
    "sample_lines",
    "set_point_params",
    "window_mean",
    "within_reach",
]


class LineError(ValueError):
    """Action lines that cannot drive a deformation."""


class PathLines(dict):
    """Action lines (name -> (k, 3) points) that know the bodies their points are fixed in.

    A model's muscle path: besides its points, per line the rotation from the rest pose
    to this one of the body each point is fixed in, expressed in the lines' frame
    (``rotations[name]``, (k, 3, 3)). Given as the current lines of a deformation, these
    rotations, interpolated along the path, turn the muscle's differential coordinates
    (`path_rotations`); plain lines use the lines' own frames and a reference point.

    Parameters
    ----------
    lines : mapping of str to (k, 3) array_like
        The points, as for `check_lines`.
    rotations : mapping of str to (k, 3, 3) array_like
        Per line and point, the rotation of the point's body (rest to this pose).
    keys : mapping of str to ((n,) array_like, (n, 3, 3) array_like), optional
        Per line, the rotations to interpolate instead of the points' own: every point
        the path is defined by, active or not, at its normalized arc length on the line
        (`set_point_params`) with its body's rotation. A conditional via point that
        switches then no longer changes which bodies the muscle turns with along its
        path: without them a via point fixed in the femur that appears near the knee
        takes the belly from a turn blended between femur and tibia to the femur's
        at once (the vastus lateralis's fibres 18 mm longer, gait2392 at -69.4 deg).
    """

    def __init__(
        self,
        lines: Mapping[str, npt.ArrayLike],
        rotations: Mapping[str, npt.ArrayLike],
        keys: Mapping[str, tuple[npt.ArrayLike, npt.ArrayLike]] | None = None,
    ) -> None:
        super().__init__(lines)
        self.rotations = {str(k): np.asarray(v, dtype=np.float64) for k, v in rotations.items()}
        self.keys = {
            str(k): (np.asarray(t, dtype=np.float64), np.asarray(R, dtype=np.float64))
            for k, (t, R) in (keys or {}).items()
        }


def set_point_params(P: FloatArray, X: FloatArray) -> FloatArray:
    """Normalized arc length on the poly-line ``P`` of the nearest point to each of ``X``.

    A point of the poly-line gets its own parameter; a point off it (a conditional
    via point outside its range) that of its projection, continuous in the pose
    wherever the nearest segment is unique. Made non-decreasing in the order of ``X``
    (the path's order), so that interpolating between them never runs backwards.
    """
    P = np.asarray(P, dtype=np.float64)
    P = P[distinct_mask(P)]
    X = np.asarray(X, dtype=np.float64).reshape(-1, 3)
    if len(P) < 2:
        return np.zeros(len(X))
    s = _arclength(P)
    a, d = P[:-1], np.diff(P, axis=0)  # (m, 3) segments
    dd = np.einsum("ij,ij->i", d, d)
    f = np.clip(np.einsum("kij,ij->ki", X[:, None, :] - a[None], d) / dd, 0.0, 1.0)
    dist = np.linalg.norm(X[:, None, :] - (a[None] + f[..., None] * d[None]), axis=2)
    j = np.argmin(dist, axis=1)
    k = np.arange(len(X))
    t = s[j] + f[k, j] * (s[j + 1] - s[j])
    return np.maximum.accumulate(t)


def check_lines(lines: Mapping[str, npt.ArrayLike], name: str = "lines") -> dict[str, FloatArray]:
    """Validate action lines and drop repeated consecutive points.

    Parameters
    ----------
    lines : mapping of str to (k, 3) array_like
        Poly-lines by name, points in order.
    name : str, optional
        Label quoted in error messages (e.g. a file name).

    Returns
    -------
    dict of str to (k, 3) float64 array

    Raises
    ------
    LineError
        If there are no lines, a line has fewer than two distinct points, or a
        coordinate is not finite.
    """
    if not lines:
        raise LineError(f"{name}: no action lines given")
    out = {}
    for key, pts in lines.items():
        try:
            P = as_points(pts, f"{name}: line '{key}'")
        except ValueError as exc:
            raise LineError(str(exc)) from None
        P = P[distinct_mask(P)]
        if len(P) < 2:
            raise LineError(
                f"{name}: line '{key}' needs at least two distinct points, got {len(P)}"
            )
        out[str(key)] = P
    return out


def distinct_mask(P: FloatArray) -> npt.NDArray[np.bool_]:
    """The rows of a poly-line that `check_lines` keeps: those unequal to the row before."""
    keep = np.ones(len(P), dtype=bool)
    keep[1:] = np.any(P[1:] != P[:-1], axis=1)
    return keep


@numba.njit(cache=True)
def _arclength_kernel(P):  # noqa: ANN001, ANN202 # pragma: no cover - compiled
    s = np.empty(P.shape[0])
    s[0] = 0.0
    for i in range(1, P.shape[0]):
        d0, d1, d2 = P[i, 0] - P[i - 1, 0], P[i, 1] - P[i - 1, 1], P[i, 2] - P[i - 1, 2]
        s[i] = s[i - 1] + np.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
    total = s[P.shape[0] - 1]
    for i in range(P.shape[0]):
        s[i] /= total
    return s


@numba.njit(cache=True)
def _segment_of(s, u):  # noqa: ANN001, ANN202 # pragma: no cover - compiled
    # the last j with s[j] <= u, for s[0] < u < s[-1] (a hand-written bisection:
    # np.searchsorted compiles shape checks and string formatting that cost seconds)
    lo, hi = 0, s.shape[0] - 1
    while hi - lo > 1:
        mid = (lo + hi) // 2
        if s[mid] <= u:
            lo = mid
        else:
            hi = mid
    return lo


@numba.njit(cache=True)
def _polyline_at_kernel(P, t, out):  # noqa: ANN001, ANN202 # pragma: no cover - compiled
    # linear interpolation in normalized arc length, clamped to the ends (as np.interp)
    # (element loops and a hand-written bisection: row assignments and np.searchsorted
    # compile shape checks and string formatting that cost seconds on a first run)
    s = _arclength_kernel(P)
    last = P.shape[0] - 1
    for i in range(t.shape[0]):
        ti = t[i]
        if ti <= s[0]:
            for k in range(3):
                out[i, k] = P[0, k]
        elif ti >= s[last]:
            for k in range(3):
                out[i, k] = P[last, k]
        else:
            j = _segment_of(s, ti)
            f = (ti - s[j]) / (s[j + 1] - s[j])
            for k in range(3):
                out[i, k] = P[j, k] + f * (P[j + 1, k] - P[j, k])


@numba.njit(cache=True)
def _window_mean_kernel(X, P, t, w, out):  # noqa: ANN001, ANN202 # pragma: no cover - compiled
    # the mean of the piecewise-linear function through the rows of P at the normalized
    # arc lengths of the points X, over [t - w, t + w], exactly: the difference of its
    # running integral over the window's width; where w is 0, its value at t. All in one
    # function: with a helper for the integral at a point, compiled apart, it took 0.83 s
    # to compile on a first run, alone 0.48 s
    s = _arclength_kernel(X)
    last = P.shape[0] - 1
    D = P.shape[1]
    cum = np.empty((P.shape[0], D))  # the integral from 0 to each point
    for k in range(D):
        cum[0, k] = 0.0
    for j in range(last):
        h = s[j + 1] - s[j]
        for k in range(D):
            cum[j + 1, k] = cum[j, k] + 0.5 * h * (P[j, k] + P[j + 1, k])
    for i in range(t.shape[0]):
        wi = w[i]
        value = not wi > 0.0  # the function's value at t, else its integral at t -/+ w
        for k in range(D):
            out[i, k] = 0.0
        for end in range(1 if value else 2):
            u = t[i] if value else (t[i] + wi if end else t[i] - wi)
            sign = 1.0 if value or end else -1.0
            if u <= s[0] or u >= s[last]:  # clamped to the ends
                e = 0 if u <= s[0] else last
                for k in range(D):
                    out[i, k] += sign * (P[e, k] if value else cum[e, k])
                continue
            j = _segment_of(s, u)
            h = s[j + 1] - s[j]
            d = u - s[j]
            for k in range(D):
                slope = (P[j + 1, k] - P[j, k]) / h
                if value:
                    out[i, k] += P[j, k] + d * slope
                else:
                    out[i, k] += sign * (cum[j, k] + d * P[j, k] + 0.5 * d * d * slope)
        if not value:
            for k in range(D):
                out[i, k] /= 2.0 * wi


def window_mean(
    X: FloatArray, t: FloatArray, w: FloatArray, P: FloatArray | None = None
) -> FloatArray:
    """Means of a poly-line (or rows per its point) over windows of normalized arc length.

    The rows of ``P`` (default ``X``, the points; or anything given per point:
    quaternions) joined linearly between the points' normalized arc lengths along
    ``X``, averaged over ``[t - w, t + w]`` exactly (``w`` 0: the value at ``t``, as
    `polyline_at`). Averaged so, a sample is continuously differentiable in the
    points: a point of the path sliding past a sample no longer turns the sample's
    velocity at once (a kink in its way through the poses, a step in the moment arms
    of a muscle driven by it).

    Parameters
    ----------
    X : (k, 3) float64 array
        Poly-line points (consecutive points distinct).
    t, w : (s,) float64 arrays
        Window centres in [0, 1] and half-widths (within [0, 1]: ``t - w >= 0``,
        ``t + w <= 1``).
    P : (k, d) float64 array, optional
        Rows per point to average (default ``X``).

    Returns
    -------
    (s, d) float64 array
    """
    X = np.ascontiguousarray(X, dtype=np.float64)
    P = X if P is None else np.ascontiguousarray(P, dtype=np.float64)
    t = np.ascontiguousarray(t, dtype=np.float64)
    out = np.empty((len(t), P.shape[1]))
    _window_mean_kernel(X, P, t, np.ascontiguousarray(w, dtype=np.float64), out)
    return out


def _arclength(P: FloatArray) -> FloatArray:
    return _arclength_kernel(np.ascontiguousarray(P, dtype=np.float64))


def polyline_at(P: FloatArray, t: FloatArray) -> FloatArray:
    """Points of a poly-line at normalized arc-length parameters.

    Parameters
    ----------
    P : (k, 3) float64 array
        Poly-line points (consecutive points distinct).
    t : (s,) float64 array
        Parameters in [0, 1].

    Returns
    -------
    (s, 3) float64 array
    """
    t = np.asarray(t, dtype=np.float64)
    out = np.empty((len(t), 3))
    _polyline_at_kernel(np.ascontiguousarray(P, dtype=np.float64), t, out)
    return out


@dataclass(frozen=True)
class LineSampling:
    """Fixed arc-length samples of a set of action lines.

    Attributes
    ----------
    names : tuple of str
        Line names, in sample order.
    params : tuple of (s,) float64 arrays
        Normalized arc-length parameters of each line's samples.
    halfwidths : tuple of (s,) float64 arrays, optional
        Per line and sample, the half-width (normalized arc length) of the window its
        point is the mean over (`window_mean`); None: each sample is the line's point
        at its parameter.
    """

    names: tuple[str, ...]
    params: tuple[FloatArray, ...]
    halfwidths: tuple[FloatArray, ...] | None = None

    @property
    def count(self) -> int:
        """Total number of samples."""
        return int(sum(len(p) for p in self.params))

    @property
    def plain(self) -> LineSampling:
        """The same samples without windows: each the line's point at its parameter."""
        return LineSampling(names=self.names, params=self.params)

    def line_index(self) -> FloatArray:
        """(count,) index of the line each sample belongs to."""
        return np.concatenate([np.full(len(p), i) for i, p in enumerate(self.params)])

    def evaluate(self, lines: Mapping[str, FloatArray], label: str = "lines") -> FloatArray:
        """Sample points of ``lines`` at the fixed parameters.

        Parameters
        ----------
        lines : mapping of str to (k, 3) float64 array
            Validated lines (see `check_lines`) with the same names.
        label : str, optional
            Quoted in the error message.

        Returns
        -------
        (count, 3) float64 array

        Raises
        ------
        LineError
            If the names differ from the sampled ones.
        """
        if set(lines) != set(self.names):
            missing = sorted(set(self.names) - set(lines))
            extra = sorted(set(lines) - set(self.names))
            raise LineError(
                f"{label}: action lines must be the rest lines {sorted(self.names)}; "
                f"missing {missing}, unexpected {extra}"
            )
        out = np.empty((self.count, 3))
        start = 0
        for i, (n, t) in enumerate(zip(self.names, self.params, strict=True)):
            part = out[start : start + len(t)]
            if self.halfwidths is None:
                _polyline_at_kernel(lines[n], t, part)
            else:
                P = np.ascontiguousarray(lines[n], dtype=np.float64)
                _window_mean_kernel(P, P, t, self.halfwidths[i], part)
            start += len(t)
        return out


def sample_lines(
    rest: Mapping[str, FloatArray],
    *,
    spacing: float,
    min_samples: int = 17,
    window: float = 0.0,
) -> LineSampling:
    """Choose arc-length samples for each rest line.

    Parameters
    ----------
    rest : mapping of str to (k, 3) float64 array
        Validated rest lines.
    spacing : float
        Target distance between samples (mesh units).
    min_samples : int, optional
        Minimum number of samples per line.
    window : float, optional
        Half-width (mesh units, along the rest line) of the window each sample is the
        line's mean over (`window_mean`), narrowed towards the line's ends so that they
        stay its ends; 0: each sample is the line's point.

    Returns
    -------
    LineSampling
        Uniform samples in normalized arc length, merged with the rest
        line's own vertices. The same parameters are evaluated on any current
        line, whatever its number of points: arc-length matching with a
        sampling fixed per muscle, so the normal matrix is factorised once.
    """
    names = tuple(sorted(rest))
    params = []
    widths = []
    for n in names:
        P = rest[n]
        length = float(np.sum(np.linalg.norm(np.diff(P, axis=0), axis=1)))
        k = max(min_samples, int(np.ceil(length / spacing)) + 1)
        t = np.union1d(np.linspace(0.0, 1.0, k), _arclength(P))
        # merge parameters closer than a tenth of the uniform step
        keep = np.concatenate([[True], np.diff(t) > 0.1 / (k - 1)])
        t = t[keep]
        t[-1] = 1.0
        params.append(t)
        widths.append(np.minimum(np.minimum(window / length, t), 1.0 - t).clip(0.0, None))
    if not window > 0:
        return LineSampling(names=names, params=tuple(params))
    return LineSampling(names=names, params=tuple(params), halfwidths=tuple(widths))


def within_reach(
    sampling: LineSampling, outside: FloatArray, reach: float, *, keep: int = 5
) -> tuple[LineSampling, dict[str, tuple[float, float, float]]]:
    """The samples of each line from its first to its last within ``reach`` of the muscle.

    A model's path runs from bone to bone, tendons included, while a segmented muscle
    mesh usually holds the belly alone: the samples of a path's tendons lie beyond the
    muscle's ends, where their mean value coordinates extrapolate the cage and a joint
    that turns the tendon (the knee under the semitendinosus) would bend the whole
    muscle with it. Such a tail is not bound. Samples between the first and the last
    within reach are all kept, however far they stray (a skeleton outside its muscle,
    as the sartorius's, still drives it).

    Parameters
    ----------
    sampling : LineSampling
        The rest lines' samples.
    outside : (count,) float64 array
        Each sample's distance outside the muscle (0 inside it).
    reach : float
        Largest distance outside the muscle of a bound sample at a line's ends.
    keep : int, optional
        Fewest samples kept per line (around its nearest sample, where fewer lie
        within reach); a line none of whose samples lies within reach is kept whole.

    Returns
    -------
    sampling : LineSampling
        The kept samples (the same parameters: a current line is sampled as before).
    cut : dict of str to (float, float, float)
        Per line with samples left out: the arc-length fractions left out at its
        start and at its end, and the farthest of them from the muscle.
    """
    outside = np.asarray(outside, dtype=np.float64)
    params: list[FloatArray] = []
    widths: list[FloatArray] = []
    cut: dict[str, tuple[float, float, float]] = {}
    start = 0
    for i, (name, t) in enumerate(zip(sampling.names, sampling.params, strict=True)):
        w = t if sampling.halfwidths is None else sampling.halfwidths[i]
        d = outside[start : start + len(t)]
        start += len(t)
        near = np.flatnonzero(d <= reach)
        if not len(near) or len(t) <= keep:
            params.append(t)
            widths.append(w)
            continue
        a, b = int(near[0]), int(near[-1])
        if b - a + 1 < keep:
            a = min(max(0, int(np.argmin(d)) - keep // 2), len(t) - keep)
            b = a + keep - 1
        params.append(t[a : b + 1])
        widths.append(w[a : b + 1])
        if a > 0 or b < len(t) - 1:
            dropped = np.r_[d[:a], d[b + 1 :]]
            cut[name] = (float(t[a]), float(1.0 - t[b]), float(dropped.max()))
    halfwidths = None if sampling.halfwidths is None else tuple(widths)
    return LineSampling(names=sampling.names, params=tuple(params), halfwidths=halfwidths), cut


def csv_rows(
    path: Path, header: list[str], *, error: type[ValueError]
) -> Iterator[tuple[int, list[str]]]:
    """Rows of a CSV file with a fixed header, as (row number, fields); blank rows skipped.

    Raises
    ------
    ValueError
        Of class ``error``, naming the file: a header other than ``header``
        (compared case-insensitively), a row with another number of fields,
        or a file that is not UTF-8 text.
    """
    try:
        with open(path, newline="", encoding="utf-8-sig") as fh:
            reader = csv.reader(fh)
            got = [h.strip().lower() for h in next(reader, [])]
            if got != header:
                raise error(f"{path}: header must be '{','.join(header)}', got '{','.join(got)}'")
            for row_no, row in enumerate(reader, start=2):
                if not row or all(not c.strip() for c in row):
                    continue
                if len(row) != len(header):
                    raise error(
                        f"{path}: row {row_no} has {len(row)} fields, expected {len(header)}"
                    )
                yield row_no, row
    except UnicodeDecodeError:
        raise error(f"{path}: not a text CSV file") from None


def read_lines_csv(path: PathLike) -> dict[str, FloatArray]:
    """Read action lines from a CSV file with header ``line,x,y,z``.

    Parameters
    ----------
    path : str or os.PathLike
        One row per point; the points of each line in order; ``line`` is a
        name or an index. Several lines per file are allowed.

    Returns
    -------
    dict of str to (k, 3) float64 array
        Validated lines (see `check_lines`).

    Raises
    ------
    LineError
        If the file is missing, the header is wrong, a value is not a number,
        or a line is invalid.
    """
    p = Path(path)
    if not p.is_file():
        raise LineError(f"{p}: no such action-line file")
    pts: dict[str, list[list[float]]] = {}
    for row_no, row in csv_rows(p, ["line", "x", "y", "z"], error=LineError):
        try:
            xyz = [float(c) for c in row[1:]]
        except ValueError:
            raise LineError(f"{p}: row {row_no} has a non-numeric coordinate: {row}") from None
        pts.setdefault(row[0].strip(), []).append(xyz)
    if not pts:
        raise LineError(f"{p}: no action-line points found")
    return check_lines(pts, name=str(p))


def placement_problem(V: FloatArray, lines: Mapping[str, FloatArray]) -> str | None:
    """Why rest lines cannot belong to the mesh ``V`` (units or frames mixed up), or None.

    A line may leave the muscle (tendons, attachments on the bones, a path running
    on down a tendon far past its muscle: gait2392's tensor fasciae latae, 400 mm
    down the iliotibial band), but one whose nearest quarter of points lies more
    than half the muscle's size outside its bounding box cannot be meant for it; nor can lines whose longest is
    shorter than 2 % of the muscle's size (metres against millimetres).

    Parameters
    ----------
    V : (n, 3) float64 array
        The muscle's vertices.
    lines : mapping of str to (k, 3) float64 array
        Points along each rest line (its points, or samples of it).

    Returns
    -------
    str or None
        The problem, in words, for an error message.
    """
    lo, hi = V.min(axis=0), V.max(axis=0)
    size = float(np.linalg.norm(hi - lo))
    span = max(float(np.linalg.norm(np.diff(P, axis=0), axis=1).sum()) for P in lines.values())
    if span < 0.02 * size:
        return f"the longest line measures {span:.3g} and the muscle {size:.3g} corner to corner"
    for name, P in lines.items():
        out = np.linalg.norm(np.maximum(0, np.maximum(lo - P, P - hi)), axis=1)
        gap = float(np.quantile(out, 0.25))
        if gap > 0.5 * size:
            return (
                f"line '{name}' lies {gap:.3g} away from the muscle (its bounding box; the "
                f"muscle measures {size:.3g} corner to corner)"
            )
    return None
