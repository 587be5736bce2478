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


def load(page: Path, width: int = 1200, height: int = 1000, budget_ms: int = 20000, tries: int = 3,
         finished: str | None = None):
    """``(dom, screenshot as an (h, w, 3) uint8 array)`` of ``page`` after its scripts ran.

    A viewer page says it has finished on its root element (``data-procmod-viewer`` is
    ``drawn`` or ``error``). Chromium dumps the page when its virtual-time budget runs out,
    whether or not the page finished; on a loaded machine that can come before the first
    frame (CI once caught all four views of a contact page undrawn). A viewer page that has
    not finished is loaded again with twice the budget, up to ``tries`` loads in all. A test
    whose own script marks the page later gives that mark as ``finished`` (text the DOM
    holds once the script is done): a page without it is loaded again too.
    """
    for attempt in range(tries):
        dom, image = _load_once(page, width, height, budget_ms * 2 ** attempt)
        if not _viewer_unfinished(dom) and (finished is None or finished in dom):
            break
    return dom, image


def _viewer_unfinished(dom: str) -> bool:
    """True for a page with viewer data whose root element does not yet say drawn or error."""
    if 'id="procmod-viewer-data"' not in dom:
        return False
    root = re.search(r"<html[^>]*>", dom)
    return not (root and re.search(r'data-procmod-viewer="(drawn|error)"', root.group(0)))


def _load_once(page: Path, width: int, height: int, budget_ms: int):
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


def explain(dom: str) -> str:
    """What a failed check needs to see of a viewer page: its root element, its view elements
    and any error note the viewer wrote (the end of the DOM is only the inlined bundle)."""
    parts = re.findall(r"<html[^>]*>", dom)[:1] + re.findall(r"<div[^>]*data-procmod-view=[^>]*>", dom)
    parts += re.findall(r'<p class="procmod-view-error">[^<]*</p>', dom)
    return "\n".join(parts) or dom[:2000]


def drawn_fraction(image: np.ndarray, rect, skip_top: int = 0, tolerance: int = 12) -> float:
    """Fraction of the pixels inside ``rect`` (left, top, width, height; the top ``skip_top``
    rows left out, where the legend sits) that differ from the viewer's background."""
    left, top, width, height = rect
    box = image[top + 1 + skip_top:top + height - 1, left + 1:left + width - 1].astype(np.int16)
    assert box.size, f"the view's rectangle {rect} lies outside the screenshot {image.shape}"
    return float((np.abs(box - BACKGROUND).max(axis=-1) > tolerance).mean())
