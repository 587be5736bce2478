"""Every mesh and URDF file the pybullet wheel ships, read by procmod: loads, or one line.

    python bench/real_assets.py [--random-urdfs 60] [--voxels 24]

Meshes nobody here made — robots' links (STL, OBJ, COLLADA), objects (the Stanford bunny,
a duck, a teddy as a convex decomposition of overlapping pieces), the 1000 random URDF
objects (a seeded sample of ``--random-urdfs``), planes, terrain, a cloth sheet — each copied
into a folder of its own with a ``procmod-volume/1`` file naming it as the one layer,
voxel size 1/``--voxels`` of its largest extent (as procmod's mesh reader reads it), and loaded as
``procmod infer`` would load it. Every file must either load with an inside or be refused
by a :class:`procmod.core.ProcmodError` (one line); anything else is a bug. Files over 3 MB
are left out (reading them is slow, not different). Then every URDF (the random objects'
sampled the same way) is read as ``procmod learn`` and ``procmod strings`` read an example
hierarchy (:func:`procmod.geometry.assets.read_assets`): links, joints, their meshes, the
part library; the same rule holds. Needs ``pip install pybullet``.

Writes bench/results/real_assets.json: counts, each refusal's message, each bug, and the
load time of the slowest files.
"""

from __future__ import annotations

import argparse
import json
import random
import shutil
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from procmod.core import ProcmodError  # noqa: E402
from procmod.data import target_from_spec  # noqa: E402
from procmod.geometry.assets import read_assets  # noqa: E402
from procmod.geometry.mesh_files import load_mesh_file  # noqa: E402

SUFFIXES = {".obj", ".stl", ".ply", ".off", ".glb", ".gltf", ".dae"}
MAX_BYTES = 3 << 20


def asset_files(root: Path, suffixes: set, random_urdfs: int) -> list:
    """The files with these suffixes, those of random_urdfs/ a seeded sample."""
    files = sorted(p for p in root.rglob("*") if p.suffix.lower() in suffixes and p.is_file()
                   and p.stat().st_size <= MAX_BYTES)
    sampled = [p for p in files if "random_urdfs" in p.parts]
    random.Random(0).shuffle(sampled)
    return [p for p in files if "random_urdfs" not in p.parts] + sorted(sampled[:random_urdfs])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--random-urdfs", type=int, default=60)
    parser.add_argument("--voxels", type=int, default=24, help="voxels along the largest extent (default 24)")
    args = parser.parse_args()
    try:
        import pybullet_data
    except ImportError:
        sys.exit("real_meshes: pip install pybullet (its pybullet_data holds the meshes)")

    root = Path(pybullet_data.getDataPath())
    rows = []
    with tempfile.TemporaryDirectory() as work:
        for i, path in enumerate(asset_files(root, SUFFIXES, args.random_urdfs)):
            folder = Path(work) / f"m{i}"
            folder.mkdir()
            shutil.copy(path, folder / path.name)
            try:  # procmod's reading: a COLLADA file in its declared units, its polygons right
                extent = float(max(load_mesh_file(path, force="mesh", process=False).extents))
            except Exception:  # noqa: BLE001 -- whatever the reader makes of it, procmod must say it in one line
                extent = 1.0
            spec = {"format": "procmod-volume/1", "score": "svol",
                    "voxel_size": extent / args.voxels if extent > 0 else 1.0,
                    "layers": [{"file": path.name, "w_fill": 1.0, "w_avoid": 0.0}]}
            (folder / "target.json").write_text(json.dumps(spec))
            t0 = time.perf_counter()
            try:
                target_from_spec(str(folder / "target.json"))
                outcome, message = "loaded", ""
            except ProcmodError as exc:
                outcome, message = "refused", str(exc).replace(str(folder), "FOLDER")
            except Exception as exc:  # noqa: BLE001 -- the bench's whole point
                outcome, message = "bug", f"{type(exc).__name__}: {exc}"
            rows.append({"file": str(path.relative_to(root)), "outcome": outcome, "message": message,
                         "one_line": "\n" not in message, "seconds": round(time.perf_counter() - t0, 3)})
            if outcome != "loaded":
                print(f"{rows[-1]['file']}: {outcome}: {message[:150]}", flush=True)
    urdf_rows = []
    for path in asset_files(root, {".urdf"}, args.random_urdfs // 3):
        t0 = time.perf_counter()
        try:
            assets = read_assets([path])
            outcome, message = "loaded", f"{len(assets.assets[0].nodes())} parts, {len(assets.parts)} distinct"
        except ProcmodError as exc:
            outcome, message = "refused", str(exc).replace(str(root), "pybullet_data")
        except Exception as exc:  # noqa: BLE001
            outcome, message = "bug", f"{type(exc).__name__}: {exc}"
        urdf_rows.append({"file": str(path.relative_to(root)), "outcome": outcome, "message": message,
                          "one_line": "\n" not in message, "seconds": round(time.perf_counter() - t0, 3)})
        if outcome != "loaded":
            print(f"{urdf_rows[-1]['file']}: {outcome}: {message[:150]}", flush=True)
    result = {"command": "python bench/real_assets.py " + " ".join(sys.argv[1:])}
    for kind, table in (("volume_targets", rows), ("urdf_hierarchies", urdf_rows)):
        counts = {k: sum(r["outcome"] == k for r in table) for k in ("loaded", "refused", "bug")}
        result[kind] = {"files": len(table), "counts": counts,
                        "multi_line_messages": sum(not r["one_line"] for r in table),
                        "not_loaded": [r for r in table if r["outcome"] != "loaded"],
                        "slowest": sorted(table, key=lambda r: -r["seconds"])[:5]}
        print(f"{kind}: {len(table)} files: {counts}")
    out = ROOT / "bench" / "results" / "real_assets.json"
    out.write_text(json.dumps(result, indent=1) + "\n")
    print(f"wrote {out}")


if __name__ == "__main__":
    main()
