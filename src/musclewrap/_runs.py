"""Contiguous runs of a count: how frames and pictures are shared out."""

from __future__ import annotations

import numpy as np

__all__ = ["contiguous_runs"]


def contiguous_runs(n: int, parts: int) -> list[range]:
    """``range(n)`` cut into at most ``parts`` contiguous runs of about equal length, none empty."""
    edges = np.linspace(0, n, max(1, min(parts, n)) + 1).round().astype(int)
    return [range(a, b) for a, b in zip(edges[:-1], edges[1:], strict=True) if b > a]
