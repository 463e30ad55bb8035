"""The README's screenshot: ``sandbox serve`` on a scene, a headless Chromium page after the
world has run for a while.

    python benchmarks/web_screenshot.py --scene playground --wait 20 --out docs/web_sandbox.png
"""

from __future__ import annotations

import argparse
import os
import re
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--scene", default="playground")
    ap.add_argument("--wait", type=float, default=20.0, help="seconds of simulation before the shot")
    ap.add_argument("--colour-by", default="shape", choices=["shape", "speed"])
    ap.add_argument("--out", default="docs/web_sandbox.png")
    args = ap.parse_args()
    from playwright.sync_api import sync_playwright

    from web.app import free_port
    from web.browser import CHROMIUM_ARGS, chromium_path

    port = free_port()
    env = {**os.environ, "TI_SKIP_VERSION_CHECK": "ON", "PYTHONUNBUFFERED": "1"}
    proc = subprocess.Popen([sys.executable, "-m", "sandbox.cli", "serve", args.scene, "--port", str(port),
                             "--arch", "cpu"], cwd=ROOT, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                            text=True)
    try:
        for line in proc.stdout:
            if re.search(r"sandbox serve: http", line):
                break
        else:
            raise SystemExit("the server did not start")
        with sync_playwright() as p:
            browser = p.chromium.launch(executable_path=chromium_path(), headless=True, args=CHROMIUM_ARGS)
            page = browser.new_page(viewport={"width": 1400, "height": 820})
            page.goto(f"http://localhost:{port}")
            page.get_by_role("button", name="Drop debris").wait_for(state="visible", timeout=120_000)
            if args.colour_by != "shape":
                page.get_by_label("Colour by", exact=True).click()
                page.get_by_role("option", name=args.colour_by, exact=True).click()
            close = page.get_by_role("button", name=re.compile("close", re.I))
            time.sleep(args.wait)
            for k in range(close.count()):  # the "software WebGL" notice covers the view
                try:
                    close.nth(k).click(timeout=1000)
                except Exception:
                    pass
            time.sleep(1.0)
            page.screenshot(path=args.out)
            browser.close()
        print(f"wrote {args.out}")
    finally:
        proc.terminate()
        proc.wait(timeout=15)


if __name__ == "__main__":
    main()
