"""What `make demo` shows.

1. A contact sheet of forward samples of each 2D model and of the spaceship (whose
   samples also come as OBJ and GLB meshes).
2. ``vines`` controlled toward the glyph "a" by two engines (SMC and the genetic
   algorithm) at the same wall-time budget, each with an HTML report.

Run: python examples/demo.py OUT_DIR
"""

import sys
from pathlib import Path

from procmod.cli import main

out = Path(sys.argv[1] if len(sys.argv) > 1 else "demo-output")
models = ("chain", "vines", "lightning", "spaceship")
for name in models:
    if main(["sample", name, "-n", "16", "--seed", "0", "--out", str(out / name), "--size", "256"]):
        sys.exit(2)
reports = []
for engine, option, value in (("smc", "--particles", "600"), ("ga", "--population", "200")):
    folder = out / f"vines-to-a-{engine}"
    if main(["infer", "vines", "--target", "glyph:a", "--engine", engine, option, value,
             "--budget", "8s", "--seed", "0", "--out", str(folder)]):
        sys.exit(2)
    reports.append(folder / "report.html")
print()
print("Forward samples:")
for name in models:
    print(f"  {out / name / 'contact_sheet.png'}")
print("vines controlled toward the glyph 'a' (8 s each):")
for report in reports:
    print(f"  {report}")
