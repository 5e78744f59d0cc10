"""The built documentation (``sphinx-build -W -b html docs docs/_build/html``, run by ``.ci/run``
before the tests): every public name has its rendered page with its docstring, every gallery
example its pictures, and the generated tables every scene key and output column. Required in
CI; elsewhere skipped when the site has not been built."""

import html
import os
import re
from pathlib import Path

import pytest

import musclewrap
import musclewrap.scene
from musclewrap.scene import OUTPUT_COLUMNS, SCENE_KEYS

SITE = Path(os.environ.get("MUSCLEWRAP_DOCS_BUILD", Path(__file__).resolve().parents[1] / "docs"
                           / "_build" / "html"))  # fmt: skip
GALLERY = ("plot_method", "plot_demo", "plot_python_api", "plot_lhdl_walk", "plot_moment_arms",
           "plot_batch")  # fmt: skip


@pytest.fixture(scope="module")
def site() -> Path:
    if not (SITE / "index.html").is_file():
        if os.environ.get("CI"):
            pytest.fail(f"the documentation is not built at {SITE}: .ci/run builds it first")
        pytest.skip(f"documentation not built at {SITE}")
    return SITE


def _text(path: Path) -> str:
    """The page's visible text, roughly: tags dropped, entities decoded, spaces collapsed."""
    raw = re.sub(r"<(script|style)\b.*?</\1>", " ", path.read_text(), flags=re.S)
    raw = re.sub(r"</?(p|div|td|th|tr|li|dt|dd|h\d|br|section|table)\b[^>]*>", " ", raw)
    return " ".join(html.unescape(re.sub(r"<[^>]+>", "", raw)).split())


def _public() -> list[tuple[str, object]]:
    names = [(f"musclewrap.{n}", getattr(musclewrap, n)) for n in musclewrap.__all__
             if n != "__version__"]  # fmt: skip
    return names + [(f"musclewrap.scene.{n}", getattr(musclewrap.scene, n))
                    for n in musclewrap.scene.__all__]  # fmt: skip


@pytest.mark.parametrize("name,obj", _public(), ids=[n for n, _ in _public()])
def test_every_public_name_has_its_rendered_docstring(site, name, obj):
    page = site / "api" / "generated" / f"{name}.html"
    assert page.is_file(), f"{name} has no page in the API reference"
    text = _text(page)
    doc = (obj.__doc__ or "") if callable(obj) else ""
    if doc and not isinstance(obj, (dict, list)):
        summary = " ".join(doc.strip().split("\n\n")[0].split())
        # the summary line as rendered: backquoted names lose their quotes
        plain = re.sub(r"`~?([^`]+)`", r"\1", re.sub(r"``([^`]+)``", r"\1", summary))
        assert plain[:60] in text, (name, plain[:60])
    assert name.rsplit(".", 1)[1] in text


def test_the_api_index_links_every_public_name(site):
    text = (site / "api.html").read_text()
    for name, _ in _public():
        assert f"api/generated/{name}.html" in text, name


def test_every_gallery_example_ran_and_shows_its_pictures(site):
    index = (site / "gallery" / "index.html").read_text()
    for ex in GALLERY:
        assert f"{ex}.html" in index, ex
        page = (site / "gallery" / f"{ex}.html").read_text()
        images = re.findall(r'src="((?:\.\./)?_images/sphx_glr_' + ex + r'_\d+\.png)"', page)
        assert images, f"{ex}: no picture on its page"
        for src in images:
            png = (site / "gallery" / src).resolve()
            assert png.is_file() and png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n", png
            assert png.stat().st_size > 5_000, png  # a picture, not a blank
    # the method's page shows the method example's pictures
    method = (site / "method.html").read_text()
    assert method.count("sphx_glr_plot_method_00") >= 4


def test_the_scene_keys_and_output_columns_pages_list_every_one(site):
    scenes = _text(site / "scenes.html")
    for table, keys in SCENE_KEYS.items():
        for key, meaning in keys.items():
            assert key in scenes, (table, key)
            assert " ".join(meaning.replace("``", "").split())[:40] in scenes, (table, key)
    outputs = _text(site / "outputs.html")
    for name, cols in OUTPUT_COLUMNS.items():
        assert name in outputs
        for col in cols:
            assert col in outputs, (name, col)


def test_the_site_opens_in_a_real_browser_and_shows_its_pictures(site, chromium):
    """Headless Chromium (the OS's, driven by Playwright; nothing downloaded) loads the index
    and a gallery page from a loopback server; every picture on them has loaded (a decoded
    image with its size), and the gallery page shows its example's code and its output."""
    import functools
    import http.server
    import threading

    from playwright import sync_api as playwright

    exe = chromium
    handler = functools.partial(http.server.SimpleHTTPRequestHandler, directory=str(site))
    server = http.server.ThreadingHTTPServer(("127.0.0.1", 0), handler)
    thread = threading.Thread(target=server.serve_forever, daemon=True)
    thread.start()
    base = f"http://127.0.0.1:{server.server_address[1]}"
    try:
        with playwright.sync_playwright() as pw:
            browser = pw.chromium.launch(executable_path=exe, headless=True)
            page = browser.new_page(viewport={"width": 1280, "height": 900})
            for path, least in (("index.html", 1), ("gallery/plot_lhdl_walk.html", 2)):
                page.goto(f"{base}/{path}", wait_until="load")
                sizes = page.eval_on_selector_all(
                    "article img",
                    "els => els.map(e => [e.complete, e.naturalWidth, e.naturalHeight])",
                )
                assert len(sizes) >= least, (path, sizes)
                assert all(ok and w > 100 and h > 100 for ok, w, h in sizes), (path, sizes)
            text = page.inner_text("article")
            assert "run_scene(" in text and "muscle-frames, unconverged 0" in text
            assert page.title().startswith("A scene on the real data")
            browser.close()
    finally:
        server.shutdown()
        server.server_close()
        thread.join()


def test_the_readme_is_the_front_door_and_its_links_lead_to_the_guide():
    """Two commands first, then the guide's pages, each of which exists and is in the site's
    table of contents (no site build needed)."""
    root = Path(__file__).resolve().parents[1]
    readme = (root / "README.md").read_text()
    block = readme.split("```", 2)[1].strip().splitlines()
    assert block == [
        "python3 -m venv .venv && . .venv/bin/activate && pip install -e . && "
        "musclewrap demo -o demo_out",
        "bash .ci/run",
    ]
    links = re.findall(r"\]\((docs/[^)]+)\)", readme)
    pages = [x for x in links if x.endswith((".md", ".rst"))]
    assert len(pages) >= 7
    index = (root / "docs" / "index.rst").read_text()
    for x in links:
        assert (root / x).is_file(), x
    for x in pages:
        assert f"   {Path(x).stem}\n" in index, x
    assert len(readme.splitlines()) < 120  # the front door; the guide holds the rest
