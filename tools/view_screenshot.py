"""A picture of ``musclewrap view``'s page, as docs/view.png shows it.

Starts ``musclewrap view SCENE --no-browser`` on a free loopback port, opens it in the OS's
Chromium (headless, through Playwright), sets each slider named with ``--set`` and waits for
its pose, then writes the page's screenshot:

    python tools/view_screenshot.py examples/lhdl_walk.toml docs/view.png --set hip_flexion_r=45
"""

from __future__ import annotations

import argparse
import shutil
import subprocess
import sys
import time
from pathlib import Path


def main() -> None:  # noqa: D103
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("scene", type=Path, help="a scene .toml or a run's folder")
    ap.add_argument("png", type=Path)
    ap.add_argument("--set", action="append", default=[], metavar="COORDINATE=VALUE")
    ap.add_argument("--size", type=int, nargs=2, default=(1100, 640), metavar=("W", "H"))
    a = ap.parse_args()
    from playwright.sync_api import sync_playwright

    from musclewrap.view._app import free_port

    port = free_port()
    cmd = [sys.executable, "-m", "musclewrap.cli", "view", str(a.scene), "--port", str(port)]
    proc = subprocess.Popen(
        [*cmd, "--no-browser"], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL
    )
    try:
        with sync_playwright() as pw:
            exe = shutil.which("chromium") or shutil.which("chromium-browser")
            browser = pw.chromium.launch(executable_path=exe, headless=True)
            page = browser.new_page(viewport={"width": a.size[0], "height": a.size[1]})
            t = time.monotonic()
            while True:
                try:
                    page.goto(f"http://127.0.0.1:{port}/", timeout=5000)
                    break
                except Exception:  # noqa: BLE001  # not serving yet
                    if proc.poll() is not None or time.monotonic() - t > 120:
                        raise SystemExit("the viewer did not start") from None
                    time.sleep(0.2)
            page.wait_for_function("window.mw && window.mw.last", timeout=120_000)
            for item in a.set:
                name, _, value = item.partition("=")
                before = page.evaluate("window.mw.last.serial")
                page.get_by_label(name).fill(value)
                page.wait_for_function(f"window.mw.last.serial != {before}", timeout=120_000)
            page.wait_for_timeout(1500)  # the camera set, the picture drawn
            page.screenshot(path=str(a.png))
            browser.close()
    finally:
        proc.terminate()
        proc.wait(timeout=30)
    print(f"wrote {a.png}")


if __name__ == "__main__":
    main()
