"""The rule that musclewrap never writes over its inputs, for the CLI and for scenes."""

from __future__ import annotations

from collections.abc import Iterable
from pathlib import Path

__all__ = ["overwrite_clash"]


def overwrite_clash(
    inputs: Iterable[str | Path | None],
    files: Iterable[str | Path | None],
    folders: Iterable[str | Path] = (),
) -> tuple[Path, str] | None:
    """The first output that would write over an input or over another output.

    Parameters
    ----------
    inputs : paths (None entries are skipped)
        Files read.
    files : paths (None entries are skipped)
        Files to be written.
    folders : paths, optional
        Folders written into: an input anywhere inside one clashes too.

    Returns
    -------
    (path, what) or None
        The clashing path as given (an output file, or the input inside an output
        folder) and ``"an input"`` or ``"another output"``.
    """
    given = [Path(p) for p in inputs if p is not None]
    seen: dict[Path, str] = {p.resolve(): "an input" for p in given}
    roots = [Path(d).resolve() for d in folders]
    for p in given:
        if any(p.resolve().is_relative_to(d) for d in roots):
            return p, "an input"
    for p in files:
        if p is None:
            continue
        r = Path(p).resolve()
        if r in seen:
            return Path(p), seen[r]
        seen[r] = "another output"
    return None
