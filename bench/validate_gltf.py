"""Every kind of GLB procmod writes, checked by the Khronos glTF-Validator (not our code).

    npm install --prefix ~/gltfv gltf-validator    # once, anywhere outside the repository
    python bench/validate_gltf.py --validator ~/gltfv/node_modules/gltf-validator [--out DIR] [--quick]

Writes, under ``--out`` (default: a temporary folder), the files a user gets: ``procmod sample``
of the three 3D models (``sample_000.glb`` and the GLBs inside ``contact_sheet.html``),
``procmod infer`` runs on a volume and on a silhouette target (``best.glb`` and the GLBs of
``report.html``'s viewer, target layers included; left out with ``--quick``), ``procmod
strings`` shapes written as GLB (the shipped shape sets and the pavilion GLB folder), and edge
cases through the API: no parts, one part, zero and huge sizes, mirrored, sheared and singular
placements, unicode and quoted tags, more parts than :data:`MAX_PART_NODES`, one mesh of more
than 65,535 vertices, an empty and a one-triangle viewer layer. Then runs the validator (Node)
on each and prints a line per file: errors, warnings, infos, hints, and each error's and
warning's message. Exit status 1 when any file has an error or a warning (hints, such as a
missing ``bufferView.target``, and infos, such as a zero-size box's degenerate triangles, pass).
``--validator`` defaults to ``$GLTF_VALIDATOR``.
"""

from __future__ import annotations

import argparse
import base64
import json
import os
import re
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from procmod.geometry.export import colour_of  # noqa: E402
from procmod.geometry.mesh_export import MAX_PART_NODES, export_mesh, glb_bytes  # noqa: E402
from procmod.geometry.solid import Box, Cylinder, Mesh, compose, rotation, scaling, translation  # noqa: E402
from procmod.viewer.layers import mesh_glb  # noqa: E402

# reads each file named on the command line, prints one JSON object per file: the validator's issues
NODE_SCRIPT = r"""
const fs = require('fs'), path = require('path');
const validator = require(process.argv[1]);
(async () => {
  for (const f of process.argv.slice(2)) {
    const load = (u) => new Promise((ok, no) => {
      try { ok(new Uint8Array(fs.readFileSync(path.join(path.dirname(f), decodeURIComponent(u))))); }
      catch (e) { no(e.toString()); } });
    try {
      const r = await validator.validateBytes(new Uint8Array(fs.readFileSync(f)),
                                              {uri: f, maxIssues: 100, externalResourceFunction: load});
      console.log(JSON.stringify({file: f, issues: r.issues}));
    } catch (e) { console.log(JSON.stringify({file: f, failed: String(e)})); }
  }
})();
"""


def edge_case_parts() -> dict:
    """Part lists of the edge cases (name -> parts)."""
    n = 300  # a 300 x 300 grid: 90,000 vertices, past uint16 indices
    grid = np.stack(np.meshgrid(np.arange(n), np.arange(n), indexing="ij"), -1).reshape(-1, 2)
    quad = (np.arange(n - 1)[:, None] * n + np.arange(n - 1)[None, :]).reshape(-1)
    faces = np.r_[np.c_[quad, quad + n, quad + 1], np.c_[quad + 1, quad + n, quad + n + 1]]
    return {
        "empty": [],
        "one_box": [Box((1, 2, 3))],
        "one_cylinder": [Cylinder(0.5, 2.0)],
        "cone": [Cylinder(0.5, 2.0, top_radius=0.0)],
        "negative_length": [Cylinder(1.0, -2.0)],
        "zero_box": [Box((0, 0, 0))],
        "huge_box": [Box((1e12, 1e12, 1e12), translation(1e12, 0, 0))],
        "tiny_box": [Box((1e-12, 1e-12, 1e-12))],
        "mirrored": [Box((1, 2, 3), scaling(-1, 1, 1))],
        "sheared": [Box((1, 1, 1), (1, 0.5, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1))],
        "singular": [Box((1, 1, 1), scaling(0, 1, 1))],
        "turned_scaled": [Box((1, 1, 1), compose(translation(1, 2, 3), rotation("z", 0.3), scaling(2, 3, 4)))],
        "names": [Box((1, 1, 1), tag='tür"m\'\\ 塔 🚀'), Box((1, 1, 1), translation(2, 0, 0), tag=""),
                  Box((1, 1, 1), translation(4, 0, 0), tag="world"), Box((1, 1, 1), translation(6, 0, 0), tag="world")],
        "linked_copies": [Box((1, 1, 1), translation(i, 0, 0), tag="b") for i in range(50)],
        "many_parts": [Box((1, 1, 1), translation(i, 0, 0), tag=f"t{i % 3}") for i in range(MAX_PART_NODES + 1)],
        "big_mesh": [Mesh(np.c_[grid, np.zeros(len(grid))].astype(float), faces)],
    }


def write_edge_cases(out: Path) -> None:
    """The API's edge cases: each as ``export_mesh``'s GLB, the viewer's merged GLB, and two viewer layers."""
    out.mkdir(parents=True, exist_ok=True)
    for name, parts in edge_case_parts().items():
        export_mesh(parts, out / f"{name}.glb", colour_of)
        (out / f"{name}_viewer.glb").write_bytes(glb_bytes(parts, colour_of))
    (out / "layer_empty.glb").write_bytes(mesh_glb(np.zeros((0, 3)), np.zeros((0, 3), dtype=np.int64)))
    (out / "layer_one.glb").write_bytes(mesh_glb([[0, 0, 0], [1, 0, 0], [0, 1, 0]], [[0, 1, 2]]))


def write_cli_outputs(out: Path, quick: bool) -> None:
    """What ``procmod sample`` / ``infer`` write, and ``procmod strings`` shapes as GLB."""
    def procmod(*args):
        subprocess.run([sys.executable, "-m", "procmod", *args], cwd=ROOT, check=True, stdout=subprocess.DEVNULL)

    for model in ("spaceship", "tree", "city"):
        procmod("sample", model, "-n", "2", "--seed", "1", "--out", str(out / f"sample_{model}"))
    if not quick:
        procmod("infer", "spaceship", "--target", "scenes/spaceship_volume", "--engine", "ga", "--population", "8",
                "--budget", "3s", "--out", str(out / "infer_volume"))
        procmod("infer", "city", "--target", "scenes/city_skyline", "--engine", "ga", "--population", "8",
                "--budget", "3s", "--out", str(out / "infer_silhouette"))
    from procmod.strings.assets import read_shape_inputs
    from procmod.strings.render import write_shape_mesh

    sets = ROOT / "examples_sets" / "strings"
    (out / "strings").mkdir(parents=True, exist_ok=True)
    for source in [*sorted(sets.glob("*.json")), sets / "pavilion"]:
        shape_set = read_shape_inputs([source])
        for k, shape in enumerate(shape_set.shapes[:2]):
            write_shape_mesh(shape_set, shape, out / "strings" / f"{source.name.replace('.', '_')}_{k}.glb")


def page_glbs(out: Path) -> None:
    """The GLBs inline in the HTML pages under ``out`` (``"glb": "<base64>"``), each as a file."""
    for page in sorted(out.rglob("*.html")):
        for k, found in enumerate(re.finditer(r'"glb":\s*"([A-Za-z0-9+/=]*)"', page.read_text(encoding="utf-8"))):
            target = out / "pages" / f"{page.parent.name}_{page.stem}_{k}.glb"
            target.parent.mkdir(parents=True, exist_ok=True)
            target.write_bytes(base64.b64decode(found.group(1)))


def validate(files, validator: str) -> list[dict]:
    """The validator's report of each file (``{"file", "issues"}`` or ``{"file", "failed"}``)."""
    done = subprocess.run(["node", "-e", NODE_SCRIPT, str(Path(validator).resolve()), *map(str, files)],
                          capture_output=True, text=True, check=True)
    return [json.loads(line) for line in done.stdout.splitlines() if line.startswith("{")]


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--validator", default=os.environ.get("GLTF_VALIDATOR"),
                        help="the gltf-validator npm package's folder (default: $GLTF_VALIDATOR)")
    parser.add_argument("--out", help="folder for the files (default: a temporary one, removed after)")
    parser.add_argument("--quick", action="store_true", help="leave out the infer runs (~20 s)")
    args = parser.parse_args(argv)
    if not args.validator or not Path(args.validator).is_dir() or shutil.which("node") is None:
        parser.error("needs node and --validator (or $GLTF_VALIDATOR): the folder of `npm install gltf-validator`")
    out = Path(args.out) if args.out else Path(tempfile.mkdtemp(prefix="procmod-gltf-"))
    try:
        write_edge_cases(out / "edge")
        write_cli_outputs(out, args.quick)
        page_glbs(out)
        bad = 0
        for report in validate(sorted(out.rglob("*.glb")), args.validator):
            name = Path(report["file"]).relative_to(out)
            if "failed" in report:
                bad += 1
                print(f"{name}: validator failed: {report['failed']}")
                continue
            issues = report["issues"]
            print(f"{name}: {issues['numErrors']} errors, {issues['numWarnings']} warnings, "
                  f"{issues['numInfos']} infos, {issues['numHints']} hints")
            for message in issues["messages"]:
                if message["severity"] <= 1:
                    print(f"    {message['code']} {message.get('pointer', '')} {message['message']}")
            bad += issues["numErrors"] + issues["numWarnings"] > 0
        print(f"{bad} file(s) with errors or warnings" if bad else "every file valid (no errors, no warnings)")
        return 1 if bad else 0
    finally:
        if not args.out:
            shutil.rmtree(out, ignore_errors=True)


if __name__ == "__main__":
    sys.exit(main())
