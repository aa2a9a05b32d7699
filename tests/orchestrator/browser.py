"""A report seen in a real browser: headless Chromium's DOM and first-screen screenshot.

`make setup` installs Chromium when it is missing (`make browser-deps`, root needed).
Without root the install cannot run; only then do the browser tests skip, saying so.
"""

from __future__ import annotations

import os
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

SCREEN = (1280, 900)   # the first screen a reader sees
# background colours of the report's verdict cells (orchestrator/report.py _CSS)
PASS_RGB, FAIL_RGB = (0xd6, 0xf0, 0xd6), (0xf8, 0xd0, 0xd0)
_FLAGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
          "--disable-background-networking", "--disable-component-update", "--disable-sync",
          "--hide-scrollbars"]


def chromium() -> str:
    """Path of the Chromium binary; skip (no root: the install cannot run) or fail."""
    exe = shutil.which("chromium") or shutil.which("chromium-browser")
    if exe:
        return exe
    if os.geteuid() != 0:
        pytest.skip("no chromium, and `make browser-deps` (apt-get) needs root: the report "
                    "is not checked in a browser on this machine")
    pytest.fail("chromium is missing: run `make browser-deps` (or `make setup`)")


def render(html: Path, out_dir: Path):
    """The DOM Chromium builds from ``html`` and a screenshot of its first screen.

    Parameters
    ----------
    html : Path
        Report file.
    out_dir : Path
        Folder for ``report.png`` (the screenshot) and the browser's profile.

    Returns
    -------
    dom : str
        ``--dump-dom`` output.
    png : Path
        Screenshot of a ``SCREEN`` window.
    """
    exe = chromium()
    out_dir.mkdir(parents=True, exist_ok=True)
    png = out_dir / "report.png"
    url = html.resolve().as_uri()

    def run(*args, profile):
        flags = _FLAGS + [f"--user-data-dir={out_dir / profile}",
                          f"--window-size={SCREEN[0]},{SCREEN[1]}"]
        return subprocess.run([exe, *flags, *args, url], capture_output=True, text=True,
                              timeout=120, check=True).stdout

    dom = run("--dump-dom", profile="profile-dom")
    run(f"--screenshot={png}", profile="profile-shot")
    return dom, png


def verdict_bands(png: Path) -> int:
    """Verdict rows visible in a screenshot: runs of pixel rows holding a pass or FAIL
    cell colour (the table's 1 px borders separate the rows)."""
    from PIL import Image

    rgb = np.asarray(Image.open(png).convert("RGB")).astype(int)
    hit = np.zeros(rgb.shape[0], bool)
    for colour in (PASS_RGB, FAIL_RGB):
        hit |= (np.abs(rgb - colour).sum(axis=2) <= 6).sum(axis=1) >= 20
    return int(np.count_nonzero(hit[1:] & ~hit[:-1]) + hit[0])


def ink(png: Path) -> float:
    """Fraction of the screenshot's pixels that are not white."""
    from PIL import Image

    rgb = np.asarray(Image.open(png).convert("RGB")).astype(int)
    return float(np.mean(rgb.sum(axis=2) < 3 * 245))
