"""The scene layer's error and its hint for misspelt names."""

from __future__ import annotations

import difflib
from collections.abc import Sequence

__all__ = ["SceneError", "suggest"]


class SceneError(ValueError):
    """A scene, model, motion or line file that cannot be used (the message says why)."""


def suggest(name: str, valid: Sequence[str]) -> str:
    """A hint naming the nearest valid names, then the valid names (the first 30)."""
    valid = list(valid)
    close = difflib.get_close_matches(name, valid, n=3, cutoff=0.5)
    shown = ", ".join(valid[:30])
    more = f" (and {len(valid) - 30} more)" if len(valid) > 30 else ""
    if close:
        return f"did you mean {' or '.join(repr(c) for c in close)}? Valid names: {shown}{more}"
    return f"valid names: {shown}{more}"
