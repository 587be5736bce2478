"""Write the Blender add-on as a zip to install from disk (a legacy add-on, Blender 4.2+).

    python -m procmod.blender.package --out procmod_blender.zip [--python PATH]

The zip holds the Blender side of :mod:`procmod.blender` as the package ``procmod_blender``
(no procmod library code: jobs run in procmod's environment) and ``default_python.txt``,
the Python its jobs run with: ``--python``, else the interpreter running this command, so
a zip made from procmod's environment finds it with no setting. In Blender: Edit >
Preferences > Add-ons > (the arrow at the top right) > Install from Disk..., then tick
"procmod".
"""

from __future__ import annotations

import argparse
import os
import shutil
import sys
import zipfile
from pathlib import Path

from ..core.io import open_atomic

HERE = Path(__file__).resolve().parent
ADDON_NAME = "procmod_blender"
FILES = ("__init__.py", "addon.py", "scene.py", "jobs.py")  # the modules Blender imports


def write_addon_zip(out: str | Path, python: str | None = None) -> Path:
    """Write the add-on zip to ``out``; returns its path."""
    out = Path(out)
    python = python or sys.executable
    out.parent.mkdir(parents=True, exist_ok=True)
    with open_atomic(out, "wb") as handle, zipfile.ZipFile(handle, "w", compression=zipfile.ZIP_DEFLATED) as archive:
        for name in FILES:
            archive.write(HERE / name, f"{ADDON_NAME}/{name}")
        archive.writestr(f"{ADDON_NAME}/default_python.txt", python + "\n")
    return out


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="python -m procmod.blender.package", description=__doc__.split("\n\n")[0])
    parser.add_argument("--out", default="procmod_blender.zip", help="the zip to write (default procmod_blender.zip)")
    parser.add_argument("--python", help="the Python jobs run with (default: the one running this command)")
    args = parser.parse_args(argv)
    if args.python is not None:
        # stored absolute: the add-on starts its workers in a job's folder, where a relative
        # path names nothing, and a typo would only show at the first job, inside Blender
        found = shutil.which(os.path.expanduser(args.python))
        if found is None:
            print(f"procmod.blender.package: error: --python {args.python!r} is not a program this machine can run; "
                  "give the path of the Python of procmod's environment (e.g. .venv/bin/python)", file=sys.stderr)
            return 2
        args.python = os.path.abspath(found)
    if Path(args.out).suffix.lower() != ".zip":  # Blender installs add-ons from a zip, whatever it is named
        print(f"procmod.blender.package: error: --out must be a .zip file (Blender installs add-ons from a zip), "
              f"got {args.out!r}", file=sys.stderr)
        return 2
    try:
        path = write_addon_zip(args.out, args.python)
    except OSError as exc:
        print(f"procmod.blender.package: error: cannot write {args.out}: {exc.strerror or exc}", file=sys.stderr)
        return 2
    print(f"wrote {path}: in Blender, Preferences > Add-ons > Install from Disk..., then enable 'procmod'")
    return 0


if __name__ == "__main__":
    sys.exit(main())
