"""Arrays kept on disk between runs, keyed by a hash of what they were made from."""

from __future__ import annotations

import contextlib
import zipfile
from collections.abc import Callable
from pathlib import Path

import numpy as np

from ._hashing import cache_key, digest, digest_arrays
from .mesh import atomic_path

__all__ = ["cached_arrays", "cached_measure", "digest"]


def cached_arrays(
    path: Path | None, build: Callable[[], dict[str, np.ndarray]]
) -> dict[str, np.ndarray]:
    """Read the arrays at ``path``, or build them and write them there.

    The file holds a hash of its arrays; a file that is damaged, from another
    version or fails that check is rebuilt. A cache that cannot be written is
    not an error: the arrays are returned all the same.

    Parameters
    ----------
    path : pathlib.Path or None
        The ``.npz`` file (its name should carry the key); None: no cache.
    build : callable
        Makes the arrays (a dict of names to arrays) when needed.

    Returns
    -------
    dict of str to numpy.ndarray
    """
    if path is not None and path.is_file():
        try:
            with open(path, "rb") as fh, np.load(fh, allow_pickle=False) as z:
                arrays = {n: z[n] for n in z.files if n != "sha256"}
                sha = str(z["sha256"])
            if sha == digest_arrays(arrays):
                return arrays
        except (OSError, ValueError, KeyError, zipfile.BadZipFile):
            pass  # damaged: rebuilt below
    arrays = {n: np.asarray(a) for n, a in build().items()}
    if path is not None:
        with contextlib.suppress(OSError):
            path.parent.mkdir(parents=True, exist_ok=True)
            with atomic_path(path) as tmp, open(tmp, "wb") as fh:
                np.savez(fh, sha256=np.array(digest_arrays(arrays)), **arrays)
    return arrays


def cached_measure(
    cache_dir: Path | None,
    kind: str,
    parts: list[np.ndarray | str],
    build: Callable[[], dict[str, np.ndarray]],
) -> dict[str, np.ndarray]:
    """`cached_arrays` of a measure of arrays, keyed by the arrays themselves.

    ``kind`` names the measure and its version (change it where the measure changes);
    the package's version and its code are part of the key too (`cache_key`). A part may
    be a string (a setting, or the `digest` of a large array the caller keys many measures
    by). The file is
    ``cache_dir/measure-<kind>-<key>.npz``; ``cache_dir`` None: no cache.
    """
    path = None
    if cache_dir is not None:
        key = cache_key(
            *(a if isinstance(a, str) else np.ascontiguousarray(a) for a in parts), kind
        )
        path = Path(cache_dir) / f"measure-{kind}-{key[:32]}.npz"
    return cached_arrays(path, build)
