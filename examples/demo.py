"""What `make demo` shows.

1. A contact sheet of forward samples of each 2D model and of the spaceship (whose
   samples also come as OBJ and GLB meshes).
2. ``vines`` controlled toward the glyph "a" by two engines (SMC and the genetic
   algorithm) at the same wall-time budget, each with an HTML report.
3. Neurally-guided vs unguided SMC with 10 particles on glyphs, side by side, with the
   guide that ships with procmod (``vines-scribbles``, trained on scribbles only).

Run: python examples/demo.py OUT_DIR
"""

import sys
import time
from pathlib import Path

from procmod.cli import main
from procmod.data import target_image
from procmod.geometry import contact_sheet, save_image_atomic
from procmod.guide import Guide
from procmod.infer import smc
from procmod.models import get_model
from procmod.render import derivation_image
from procmod.targets import ShapeMatch


def guided_vs_unguided(out: Path, glyphs: str = "agsRk3", particles: int = 10) -> Path:
    """A sheet: per glyph, the target, unguided SMC and guided SMC (same particle count)."""
    model, guide = get_model("vines"), Guide.load("vines-scribbles")
    smc(model, ShapeMatch(target_image("glyph:a")), particles=2, seed=0, guide=guide)  # compile first
    tiles, labels = [], []
    for char in glyphs:
        target = ShapeMatch(target_image(f"glyph:{char}"))
        underlay = target.display_mask(160)
        for name, g in (("unguided", None), ("guided", guide)):
            began = time.perf_counter()
            result = smc(model, target, particles=particles, seed=0, guide=g)
            seconds = time.perf_counter() - began
            tiles.append(derivation_image(result.best, 160, underlay=underlay))
            labels.append(f"{char} {name} {result.best_score:.2f} {seconds:.2f}s")
    path = out / "guided-vs-unguided.png"
    out.mkdir(parents=True, exist_ok=True)
    save_image_atomic(contact_sheet(tiles, columns=4, labels=labels), path)
    return path


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
sheet = guided_vs_unguided(out)
print()
print("Forward samples:")
for name in models:
    print(f"  {out / name / 'contact_sheet.png'}")
print("vines controlled toward the glyph 'a' (a budget of 8 s each; SMC finishes the pass it is in):")
for report in reports:
    print(f"  {report}")
print(f"guided vs unguided SMC, 10 particles, glyphs (best similarity, seconds): {sheet}")
