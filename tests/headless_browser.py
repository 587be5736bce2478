"""Load a page in headless Chromium (Debian's ``chromium``) and read what it drew.

One Chromium run both dumps the DOM after the page's scripts ran and takes a screenshot.
The flags keep Chromium off the network (the machine's is closed, and the pages must need
none: every host name resolves to nothing) and give WebGL a software renderer
(SwiftShader), as a machine without a GPU needs.
"""

from __future__ import annotations

import re
import shutil
import subprocess
import tempfile
from pathlib import Path

import numpy as np
from PIL import Image

FLAGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
         "--disable-background-networking", "--disable-component-update", "--disable-sync",
         "--enable-unsafe-swiftshader", "--use-angle=swiftshader", "--host-resolver-rules=MAP * ~NOTFOUND",
         "--hide-scrollbars"]
BACKGROUND = (243, 244, 246)  # the viewer's clear colour (procmod/viewer/js/viewer.js)


def chromium() -> str | None:
    """The Chromium executable, or None."""
    return shutil.which("chromium") or shutil.which("chromium-browser")


def load(page: Path, width: int = 1200, height: int = 1000, budget_ms: int = 20000):
    """``(dom, screenshot as an (h, w, 3) uint8 array)`` of ``page`` after its scripts ran."""
    exe = chromium()
    with tempfile.TemporaryDirectory(prefix="procmod-chromium-") as scratch:
        shot = Path(scratch) / "shot.png"
        run = subprocess.run([exe, *FLAGS, f"--user-data-dir={scratch}/profile", f"--window-size={width},{height}",
                              f"--virtual-time-budget={budget_ms}", f"--screenshot={shot}", "--dump-dom",
                              Path(page).resolve().as_uri()],
                             capture_output=True, text=True, timeout=120)
        assert shot.exists(), f"chromium wrote no screenshot (exit {run.returncode}): {run.stderr[-2000:]}"
        image = np.asarray(Image.open(shot).convert("RGB"))
    return run.stdout, image


def views(dom: str) -> list[dict]:
    """The viewer's view elements in the DOM: their status and drawn rectangle."""
    out = []
    for tag in re.findall(r"<div[^>]*data-procmod-view=\"\d+\"[^>]*>", dom):
        status = re.search(r'data-status="([^"]*)"', tag)
        rect = re.search(r'data-rect="([^"]*)"', tag)
        out.append({"status": status.group(1) if status else None,
                    "rect": tuple(int(v) for v in rect.group(1).split(",")) if rect else None})
    return out


def drawn_fraction(image: np.ndarray, rect, skip_top: int = 0, tolerance: int = 12) -> float:
    """Fraction of the pixels inside ``rect`` (left, top, width, height; the top ``skip_top``
    rows left out, where the legend sits) that differ from the viewer's background."""
    left, top, width, height = rect
    box = image[top + 1 + skip_top:top + height - 1, left + 1:left + width - 1].astype(np.int16)
    assert box.size, f"the view's rectangle {rect} lies outside the screenshot {image.shape}"
    return float((np.abs(box - BACKGROUND).max(axis=-1) > tolerance).mean())
