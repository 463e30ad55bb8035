"""Headless Chromium for the browser test and the web benchmarks: where it is and how to start
it on a machine with no display and a closed network (apis.md section 1.9)."""

from __future__ import annotations

import os
import shutil
from pathlib import Path

CHROMIUM_ARGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-background-networking",
                 "--disable-component-update", "--disable-sync", "--no-first-run"]


def chromium_path() -> str | None:
    """``$SANDBOX_CHROMIUM``, Debian's /usr/bin/chromium, or a chromium on PATH; None when none."""
    for candidate in (os.environ.get("SANDBOX_CHROMIUM"), "/usr/bin/chromium", shutil.which("chromium"),
                      shutil.which("chromium-browser")):
        if candidate and Path(candidate).exists():
            return candidate
    return None
