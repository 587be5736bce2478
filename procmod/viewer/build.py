"""Rebuild ``procmod/viewer/procmod-viewer.js`` from ``js/viewer.js`` and three.js from npm.

    python procmod/viewer/build.py          # needs node + npm and the npm registry

The bundle is committed (package data), so installing or using procmod needs neither node
nor the network; this script only says how it was made, and remakes it after a change to
``js/viewer.js`` or to the versions below. It installs the pinned packages into a scratch
folder, bundles the viewer with esbuild into one classic (non-module) script, since pages
opened from disk (file://) may not load ES modules, and writes three.js's licence beside the
bundle and at its top.
"""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

THREE_VERSION = "0.187.0"
ESBUILD_VERSION = "0.28.2"
HERE = Path(__file__).resolve().parent
BUNDLE = HERE / "procmod-viewer.js"
LICENCE = HERE / "three-LICENSE.txt"


def build() -> None:
    if shutil.which("npm") is None:
        sys.exit("build.py needs node and npm on the PATH")
    with tempfile.TemporaryDirectory(prefix="procmod-viewer-build-") as scratch:
        work = Path(scratch)
        (work / "package.json").write_text(json.dumps({"name": "procmod-viewer-build", "private": True}))
        subprocess.run(["npm", "install", "--no-audit", "--no-fund", f"three@{THREE_VERSION}",
                        f"esbuild@{ESBUILD_VERSION}"], cwd=work, check=True)
        shutil.copy(HERE / "js" / "viewer.js", work / "viewer.js")
        out = work / "bundle.js"
        subprocess.run([str(work / "node_modules" / ".bin" / "esbuild"), "viewer.js", "--bundle", "--format=iife",
                        "--minify", "--target=es2020", "--legal-comments=none", f"--outfile={out}"],
                       cwd=work, check=True)
        licence = (work / "node_modules" / "three" / "LICENSE").read_text(encoding="utf-8")
        header = (f"/*! procmod 3D viewer (procmod/viewer/js/viewer.js) bundled with three.js {THREE_VERSION} "
                  f"by esbuild {ESBUILD_VERSION}.\nthree.js licence:\n\n{licence.strip()}\n*/\n")
        BUNDLE.write_text(header + out.read_text(encoding="utf-8"), encoding="utf-8")
        LICENCE.write_text(licence, encoding="utf-8")
    print(f"wrote {BUNDLE} ({BUNDLE.stat().st_size:,} bytes) and {LICENCE}")


if __name__ == "__main__":
    build()
