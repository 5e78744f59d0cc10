"""Sphinx configuration of musclewrap's documentation (``docs/``).

Build: ``pip install -e ".[docs]"`` then ``sphinx-build -W -b html docs docs/_build/html``.
The scene reference and the output columns are generated here, before the build, from the
package's own tables (`musclewrap.scene.SCENE_KEYS`, `musclewrap.scene.OUTPUT_COLUMNS`). The
gallery's scripts run at build time; ``MUSCLEWRAP_DOCS_FRAMES`` (default 12) caps the frames
of the runs they make, to keep the build short.
"""

from __future__ import annotations

import os
from pathlib import Path

import pyvista

import musclewrap
from musclewrap.scene import OUTPUT_COLUMNS, SCENE_KEYS

HERE = Path(__file__).resolve().parent

project = "musclewrap"
author = "the musclewrap developers"
copyright = "2026, the musclewrap developers"  # noqa: A001
version = release = musclewrap.__version__

extensions = [
    "sphinx.ext.autodoc",
    "sphinx.ext.autosummary",
    "sphinx.ext.mathjax",
    "numpydoc",
    "myst_parser",
    "sphinx_gallery.gen_gallery",
]
source_suffix = {".rst": "restructuredtext", ".md": "markdown"}
myst_heading_anchors = 3
exclude_patterns = ["_build", "gallery_src", "gallery/*.ipynb", "gallery/*.py", "gallery/*.zip"]
html_theme = "pydata_sphinx_theme"
html_title = f"musclewrap {release}"
html_theme_options = {
    "navigation_with_keys": False,
    "show_toc_level": 2,
    "footer_start": ["copyright"],
}
html_static_path: list[str] = []
autosummary_generate = True
autodoc_typehints = "none"
numpydoc_show_class_members = False
numpydoc_class_members_toctree = False
default_role = "py:obj"
nitpicky = False
html_scaled_image_link = False  # pictures side by side, not links to themselves
smartquotes = False  # quotes as written (the tests find the docstrings' text on the pages)

# the gallery: scripts run at build time, PyVista's pictures scraped off-screen
pyvista.OFF_SCREEN = True
if not os.environ.get("DISPLAY"):  # EGL straight away, as the run's renderers: no X to try first
    os.environ.setdefault("VTK_DEFAULT_OPENGL_WINDOW", "vtkEGLRenderWindow")
pyvista.BUILDING_GALLERY = True
os.environ.setdefault("MUSCLEWRAP_DOCS_FRAMES", "12")
sphinx_gallery_conf = {
    "examples_dirs": ["gallery_src"],
    "gallery_dirs": ["gallery"],
    "filename_pattern": r"/plot_",
    "image_scrapers": ("pyvista", "matplotlib"),
    "download_all_examples": False,
    "remove_config_comments": True,
    "within_subsection_order": "FileNameSortKey",
    "abort_on_example_error": True,
    "show_memory": False,
}


def _table(rows: list[tuple[str, str]], head: tuple[str, str]) -> list[str]:
    out = [".. list-table::", "   :header-rows: 1", "   :widths: 25 75", ""]
    for a, b in [head, *rows]:
        out += [f"   * - {a}", f"     - {b}"]
    return out + [""]


def _generate() -> None:
    """The scene keys and the output columns, as reST tables, from the package's tables."""
    gen = HERE / "generated"
    gen.mkdir(exist_ok=True)
    lines: list[str] = []
    for table, keys in SCENE_KEYS.items():
        title = "The top level" if not table else f"``[{table}]``"
        if table == "registration.landmark":
            title = "``[[registration.landmark]]``"
        lines += [title, "~" * len(title), ""]
        lines += _table([(f"``{k}``", v) for k, v in keys.items()], ("key", "meaning"))
    (gen / "scene_keys.rst").write_text("\n".join(lines))
    lines = []
    for name, cols in OUTPUT_COLUMNS.items():
        title = f"``{name}``"
        lines += [title, "~" * len(title), ""]
        lines += _table([(f"``{k}``", v) for k, v in cols.items()], ("column", "meaning"))
    (gen / "output_columns.rst").write_text("\n".join(lines))


_generate()
