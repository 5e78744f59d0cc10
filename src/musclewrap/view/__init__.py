"""The live viewer: a scene's muscles wrapping in the browser as joints are dragged.

``musclewrap view SCENE.toml`` (or `Viewer` from Python and Jupyter) serves a page
with a slider per driven coordinate and a time slider; every change is solved as a
run would solve that pose (`musclewrap.scene.LiveScene`). ``musclewrap view OUTDIR``
plays a finished run's series. Needs the ``[view]`` extra (trame).
"""

from __future__ import annotations

from typing import Any

__all__ = ["Viewer", "open_source", "viewer"]


def _need_trame() -> None:
    try:
        import trame  # noqa: F401
        import trame_vtk  # noqa: F401
    except ImportError:
        raise ImportError(
            "the viewer needs the [view] extra: pip install 'musclewrap[view]' (trame, trame-vtk)"
        ) from None


def __getattr__(name: str) -> Any:
    if name in ("Viewer", "open_source"):
        _need_trame()
        from . import _app

        return getattr(_app, name)
    raise AttributeError(name)


def viewer(source: Any, **kw: Any) -> Any:
    """A `Viewer` of a scene file, a `LiveScene`, a run's folder or a `Series`."""
    _need_trame()
    from ._app import Viewer, open_source

    if isinstance(source, str) or hasattr(source, "__fspath__"):
        source = open_source(source)
    return Viewer(source, **kw)
