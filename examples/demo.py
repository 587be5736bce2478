"""What `make demo` shows: a contact sheet of forward samples of every built-in model.

Run: python examples/demo.py OUT_DIR
"""

import sys
from pathlib import Path

from procmod.cli import main

out = Path(sys.argv[1] if len(sys.argv) > 1 else "demo-output")
for name in ("chain", "vines", "lightning"):
    code = main(["sample", name, "-n", "16", "--seed", "0", "--out", str(out / name), "--size", "256"])
    if code:
        sys.exit(code)
print()
print("Open these to see the models:")
for name in ("chain", "vines", "lightning"):
    print(f"  {out / name / 'contact_sheet.png'}")
