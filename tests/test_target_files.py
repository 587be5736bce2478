"""Hostile and careless 3D target files (issues 28.2 and 25.5): every case goes through
``procmod infer`` and must exit 2 with exactly one stderr line naming the file and the
field (by its JSON path), print no traceback, leave nothing behind, and be refused before
any engine runs."""

import json
import struct
from pathlib import Path

import numpy as np
import pytest
import trimesh
from PIL import Image

import procmod.infer
from procmod.cli import main

NPY = {"format": "procmod-volume/1", "grid": {"origin": [0, 0, 0], "voxel_size": 0.25}, "layers": [{"file": "v.npy"}]}
MESH = {"format": "procmod-volume/1", "voxel_size": 0.25, "layers": [{"file": "box.obj"}]}
CAM = {"eye": [0, 0, 10], "look_at": [0, 0, 0], "projection": "orthographic", "fov": 4}


def _with(base: dict, **change) -> dict:
    spec = json.loads(json.dumps(base))
    for key, value in change.items():
        *path, last = key.split("__")
        node = spec
        for p in path:
            node = node[int(p)] if p.isdigit() else node[p]
        if value is _DROP:
            del node[last]
        else:
            node[last] = value
    return spec


_DROP = object()


def _npy_header(path: Path, descr: str, shape: tuple) -> None:
    """An .npy file whose header claims ``shape`` and holds no data."""
    header = f"{{'descr': '{descr}', 'fortran_order': False, 'shape': {shape}, }}"
    header += " " * (118 - len(header)) + "\n"
    path.write_bytes(b"\x93NUMPY\x01\x00" + len(header).to_bytes(2, "little") + header.encode())


def _sil(view_change: dict, camera_change: dict | None = None, kind: str = "mesh", file: str = "box.obj") -> dict:
    view = {kind: file, "camera": dict(CAM, **(camera_change or {}))}
    view.update(view_change)
    return {"format": "procmod-silhouette/1", "views": [view]}


# (id, spec, the message after "<id>.json: ")
CASES = [
    ("voxel-size-0", _with(MESH, voxel_size=0), "voxel_size must be positive, got 0"),
    ("voxel-size-nan", _with(MESH, voxel_size=float("nan")), "voxel_size must be a finite number, got NaN"),
    ("voxel-size-string", _with(MESH, voxel_size="fine"), "voxel_size must be a finite number, got \"fine\""),
    ("voxel-size-missing", _with(MESH, voxel_size=_DROP), "mesh layers need \"voxel_size\""),
    ("format-missing", _with(MESH, format=_DROP), "has no \"format\"; a 3D target file's is \"procmod-volume/1\" or "
                                                  "\"procmod-silhouette/1\""),
    ("format-other", _with(MESH, format="procmod-volume/2"), "\"format\" is \"procmod-volume/2\"; a 3D target file's "
                                                            "is"),
    ("voxel-size-negative", _with(MESH, voxel_size=-0.5), "voxel_size must be positive, got -0.5"),
    ("voxel-size-tiny", _with(MESH, voxel_size=1e-4), "voxel_size 0.0001 around the mesh layers (12000x12000x12000"),
    ("grid-voxel-size-0", _with(NPY, grid__voxel_size=0), "grid.voxel_size must be positive, got 0"),
    # sizes and places float64 cannot square or divide (a division by zero, a traceback)
    ("grid-voxel-size-1e-300", _with(NPY, grid__voxel_size=1e-300), "grid.voxel_size must lie in 1e-12..1e+12, "
     "got 1e-300"),
    ("grid-voxel-size-1e300", _with(NPY, grid__voxel_size=1e300), "grid.voxel_size must lie in 1e-12..1e+12"),
    ("voxel-size-1e300", _with(MESH, voxel_size=1e300), "voxel_size must lie in 1e-12..1e+12, got 1e+300"),
    ("origin-1e308", _with(NPY, grid__origin=[1e308, 0, 0]), "grid.origin must lie within +-1e+12, got [1e+308"),
    ("grid-voxel-size-nan", _with(NPY, grid__voxel_size=float("nan")), "grid.voxel_size must be a finite number"),
    ("grid-voxel-size-string", _with(NPY, grid__voxel_size="1"), "grid.voxel_size must be a finite number, got \"1\""),
    ("grid-voxel-size-missing", _with(NPY, grid__voxel_size=_DROP), "grid needs 'voxel_size'"),
    ("grid-missing", _with(NPY, grid=_DROP), "an .npy layer needs \"grid\""),
    ("grid-not-object", _with(NPY, grid=[0, 0, 0]), "grid must be a JSON object, got [0, 0, 0]"),
    ("origin-number", _with(NPY, grid__origin=5), "grid.origin must be three numbers, got 5"),
    ("origin-nan", _with(NPY, grid__origin=[float("nan"), 0, 0]), "grid.origin[0] must be a finite number, got NaN"),
    ("origin-two", _with(NPY, grid__origin=[0, 0]), "grid.origin must be three numbers, got [0, 0]"),
    ("grid-shape-mismatch", _with(NPY, grid__shape=[4, 4, 4]), "grid.shape [4, 4, 4] differs from the .npy layers'"),
    ("mesh-grid-without-shape", _with(MESH, voxel_size=_DROP, grid={"origin": [0, 0, 0], "voxel_size": 0.25}),
     "with only mesh layers, \"grid\" needs \"shape\""),
    ("voxel-sizes-disagree", _with(NPY, voxel_size=0.5), "voxel_size 0.5 and grid.voxel_size 0.25 disagree"),
    ("w-self-string", _with(NPY, w_self="high"), "w_self must be a finite number, got \"high\""),
    ("w-self-negative", _with(NPY, w_self=-1), "w_self must be at least 0, got -1"),
    ("w-self-inf", _with(NPY, w_self=float("inf")), "w_self must be a finite number, got Infinity"),
    ("w-fill-inf", _with(NPY, layers__0__w_fill=float("inf")), "layers[0].w_fill must be a finite number, got Infinity"),
    ("w-fill-bool", _with(NPY, layers__0__w_fill=True), "layers[0].w_fill must be a finite number, got true"),
    ("w-avoid-nan", _with(NPY, layers__0__w_avoid=float("nan")), "layers[0].w_avoid must be a finite number, got NaN"),
    ("score-unknown", _with(NPY, score="iou"), "score must be \"svol\" or \"proxy\", got \"iou\""),
    ("proxy-two-layers", _with(NPY, score="proxy", layers=[{"file": "v.npy"}, {"file": "v.npy"}]),
     "\"score\": \"proxy\" compares the ship with one target volume; layers has 2"),
    # weights a proxy score has no use for were dropped without a word
    ("proxy-weights", _with(NPY, score="proxy", w_self=50, layers__0__w_fill=1000), "\"score\": \"proxy\" takes no "
     "weights (it is the fraction of voxels where the ship and the target agree: w_fill 1, w_avoid -1, w_self 0), so "
     "w_self, layers[0].w_fill would be left unused"),
    # nothing to gain anywhere: every derivation scored 0 or less, and the temperature fell to 1e-9
    ("nothing-to-fill", _with(NPY, layers__0__w_fill=-1, layers__0__w_avoid=-1), "nothing to fill: no voxel gains"),
    ("all-zero-weights", _with(NPY, layers__0__w_fill=0, layers__0__w_avoid=0), "nothing to fill: no voxel gains"),
    ("layers-missing", _with(NPY, layers=_DROP), "layers must be a non-empty list"),
    ("layers-string", _with(NPY, layers="v.npy"), "layers must be a non-empty list"),
    ("layer-not-object", _with(NPY, layers=["v.npy"]), "layers[0] must be a JSON object, got \"v.npy\""),
    ("layer-no-file", _with(NPY, layers=[{"w_fill": 1}]), "layers[0] needs \"file\""),
    ("file-empty", _with(NPY, layers__0__file=""), "layers[0].file: expected a relative file path"),
    ("file-dot", _with(NPY, layers__0__file="."), "layers[0].file: \".\" names a folder, not a file"),
    ("file-up", _with(NPY, layers__0__file="../.."), "layers[0].file: \"../..\" is not a voxel grid (.npy) or mesh file"),
    ("file-absolute", _with(NPY, layers__0__file="/etc/hostname.npy"), "layers[0].file: \"/etc/hostname.npy\" is an "
                                                                        "absolute path"),
    ("file-missing", _with(NPY, layers__0__file="nope.npy"), "layers[0].file: voxel grid (.npy) or mesh file "),
    ("file-folder", _with(NPY, layers__0__file="folder.npy"), "layers[0].file: "),
    ("file-wrong-kind", _with(NPY, layers__0__file="notes.txt"), "layers[0].file: \"notes.txt\" is not a voxel grid"),
    ("file-number", _with(NPY, layers__0__file=5), "layers[0].file: expected a relative file path (a non-empty "
                                                   "string), got 5"),
    ("npy-huge-header", _with(NPY, layers__0__file="huge.npy"), "layers[0].file: a voxel grid of shape (10000, 10000, "
                                                                "10000) (10000x10000x10000 = 1,000,000,000,000 voxels) "
                                                                "would need at least"),
    ("npy-2d", _with(NPY, layers__0__file="flat.npy"), "layers[0].file: a voxel grid must be a 3D array, got shape "
                                                       "(8, 8)"),
    ("npy-nan", _with(NPY, layers__0__file="nan.npy"), "layers[0].file: the voxel grid holds NaN or infinity"),
    ("npy-empty", _with(NPY, layers__0__file="zeros.npy"), "layers[0].file: the voxel grid is empty"),
    ("npy-objects", _with(NPY, layers__0__file="objects.npy"), "layers[0].file: the voxel grid must hold numbers, "
                                                               "got dtype object"),
    ("npy-truncated", _with(NPY, layers__0__file="truncated.npy"), "layers[0].file: cannot read the voxel grid"),
    ("npy-not-npy", _with(NPY, layers__0__file="text.npy"), "layers[0].file: cannot read the voxel grid"),
    ("npy-shapes-differ", _with(NPY, layers=[{"file": "v.npy"}, {"file": "v6.npy"}]),
     "layers[1].file: shape (6, 6, 6) differs from the first .npy layer's (8, 8, 8)"),
    # meshes (issue 25.5)
    ("mesh-unreadable", _with(MESH, layers__0__file="garbage.glb"), "layers[0].file: cannot read the mesh"),
    ("mesh-empty-file", _with(MESH, layers__0__file="empty.obj"), "layers[0].file: "),
    ("mesh-no-faces", _with(MESH, layers__0__file="points.obj"), "layers[0].file: "),
    ("mesh-zero-area", _with(MESH, layers__0__file="lines.obj"), "layers[0].file: every face of the mesh has zero "
                                                                 "area"),
    ("mesh-nan", _with(MESH, layers__0__file="nan.obj"), "layers[0].file: every face of the mesh is on a vertex that "
                                                         "is not a finite number (NaN or infinity), e.g. vertex 0 = "
                                                         "[nan, -0.5, -0.5]"),
    ("mesh-10M-ply", _with(MESH, layers__0__file="huge.ply"), "layers[0].file: "),
    ("mesh-10M-stl", _with(MESH, layers__0__file="huge.stl"), "layers[0].file: "),
    ("mesh-sheet", _with(MESH, layers__0__file="sheet.obj"), "layers[0].file: no voxel centre of the"),
    ("mesh-soup", _with(MESH, voxel_size=1 / 64, layers__0__file="soup.ply"), "layers[0].file has 30,000 open edges in "
                                                                              "10,000 boundary loops"),
    # silhouettes
    ("sil-eye-1e300", _sil({}, {"eye": [0, 4, 1e300]}), "views[0].camera.eye must lie within +-1e+12"),
    # keys that were ignored without a word, leaving the view meaning something else
    ("sil-width-in-view", _sil({"width": 64}), 'views[0].width belongs inside its "camera" object'),
    ("sil-hits", _sil({"hits": 2.0}), "views[0] has 'hits', which procmod does not read; did you mean 'hit'"),
    ("sil-look-at", _sil({}, {"look-at": [0, 0, 0]}), "views[0].camera has 'look-at', which procmod does not "
                                                       "read; did you mean 'look_at'"),
    ("sil-fov-tiny", _sil({}, {"fov": 1e-300}), "views[0].camera.fov is the height of the view in world units "
                                                "and must lie in 1e-12..1e+12, got 1e-300"),
    ("sil-fov-tiny-perspective", _sil({}, {"fov": 1e-300, "projection": "perspective"}),
     "views[0].camera.fov is the vertical field of view in degrees and must lie from 1e-06 to under 180"),
    ("sil-image-empty", _sil({}, kind="image", file=""), "views[0].image: expected a relative file path"),
    ("sil-image-dot", _sil({}, kind="image", file="."), "views[0].image: \".\" names a folder"),
    ("sil-image-up", _sil({}, kind="image", file="../.."), "views[0].image: "),
    ("sil-image-absolute", _sil({}, kind="image", file="/etc/hostname"), "views[0].image: \"/etc/hostname\" is an "
                                                                        "absolute path"),
    ("sil-image-missing", _sil({}, kind="image", file="nope.png"), "views[0].image: picture file "),
    ("sil-image-not-image", _sil({}, kind="image", file="notes.txt"), "views[0].image: not an image Pillow can read"),
    ("sil-weights-wrong-kind", _sil({}, kind="weights", file="sketch.png"), "views[0].weights: \"sketch.png\" is not a "
                                                                            "weights file"),
    ("sil-weights-nan", _sil({}, kind="weights", file="nan2d.npy"), "views[0].weights: the weights holds NaN"),
    ("sil-mesh-missing", _sil({}, file="nope.obj"), "views[0].mesh: mesh file "),
    ("sil-mesh-wrong-kind", _sil({}, file="notes.txt"), "views[0].mesh: \"notes.txt\" is not a mesh file"),
    ("sil-mesh-nan", _sil({}, file="nan.obj"), "views[0].mesh: every face of the mesh is on a vertex that is not"),
    ("sil-mesh-10M", _sil({}, file="huge.ply"), "views[0].mesh: "),
    ("sil-mesh-misses", _sil({}, {"eye": [50, 0, 10], "look_at": [50, 0, 0]}), "views[0].mesh: the mesh covers no "
                                                                                  "pixel centre of the 128x128 view"),
    ("sil-mesh-width-0", _sil({}, {"width": 0}), "views[0].camera.width must be a whole number from 1 to 100,000, "
                                                 "got 0"),
    ("sil-mesh-width-string", _sil({}, {"width": "wide"}), "views[0].camera.width must be a whole number"),
    ("sil-mesh-view-huge", _sil({}, {"width": 100000, "height": 100000}), "views[0].camera: a 100000x100000 view is "
                                                                          "10000 megapixels"),
    ("sil-two-kinds", _sil({"image": "sketch.png"}), "views[0] gives 'image' and 'mesh'; give one of them"),
    ("sil-image-width", _sil({}, {"width": 64}, kind="image", file="sketch.png"),
     "views[0].camera.width: a picture's or weights' size is its own"),
    ("sil-hit-inf", _sil({"hit": float("inf")}), "views[0].hit must be a finite number, got Infinity"),
    # near misses outside a silhouette's views, ignored without a word: a target placed otherwise
    ("vol-mesh-scle", _with(MESH, mesh_scle=0.5), "the file has 'mesh_scle', which procmod does not read; did you "
                                                  "mean 'mesh_scale'?"),
    ("vol-margin", _with(MESH, marign=0.5), "the file has 'marign', which procmod does not read; did you mean "
                                            "'margin'?"),
    ("vol-origin-outside-grid", _with(NPY, origin=[0, 0, 0]), "origin belongs inside its \"grid\" object"),
    ("vol-grid-shap", _with(NPY, grid__shap=[8, 8, 8]), "grid has 'shap', which procmod does not read; did you mean "
                                                        "'shape'?"),
    ("vol-layer-w-avod", _with(NPY, layers__0__w_avod=-5), "layers[0] has 'w_avod', which procmod does not read; did "
                                                           "you mean 'w_avoid'?"),
    ("sil-mesh-scael", dict(_sil({}), mesh_scael=0.5), "the file has 'mesh_scael', which procmod does not read; did "
                                                       "you mean 'mesh_scale'?"),
    ("sil-view-mesh-scale", _sil({"mesh_scale": 0.05}), "views[0].mesh_scale belongs at the file's top level, where "
                                                        "it applies to every mesh of the file"),
    ("sil-view-mesh-scle", _sil({"mesh_scle": 2}), "views[0].mesh_scle (did you mean 'mesh_scale'?) belongs at the "
                                                   "file's top level"),
    ("vol-layer-mesh-scale", _with(MESH, layers__0__mesh_scale=100), "layers[0].mesh_scale belongs at the file's top "
                                                                     "level"),
    ("vol-layer-voxel-size", _with(MESH, layers__0__voxel_size=0.5), "layers[0].voxel_size belongs at the file's top "
                                                                     "level"),
    ("sil-image-grey", _sil({}, kind="image", file="grey.png"), "views[0].image: no pixel is dark enough to hit "
                                                                "(under 85 of 255; the darkest is 100)"),
]

# the size messages, beyond the field
TAILS = {
    "mesh-empty-file": "empty.obj is empty",
    "mesh-no-faces": "points.obj holds no triangle faces",
    "mesh-10M-ply": "huge.ply has 10,000,000 faces; procmod reads target meshes of up to 4,000,000 faces (reading "
                    "this one would need about 4.0 GB of memory",
    "mesh-10M-stl": "huge.stl has 10,000,000 faces; procmod reads target meshes of up to 4,000,000 faces",
    "sil-mesh-10M": "huge.ply has 10,000,000 faces",
    "voxel-size-tiny": "= 1,728,000,000,000 voxels) would need at least 41.5 TB of memory",
    "sil-image-missing": "nope.png does not exist",
    "sil-mesh-missing": "nope.obj does not exist",
    "file-missing": "nope.npy does not exist",
    "file-folder": "folder.npy is a folder, not a voxel grid (.npy) or mesh file",
    "sil-image-up": "/../.. is a folder, not a picture file",
}


def _obj(path: Path, vertices, faces) -> None:
    lines = [f"v {x} {y} {z}" for x, y, z in vertices] + [f"f {a + 1} {b + 1} {c + 1}" for a, b, c in faces]
    path.write_text("\n".join(lines) + "\n")


@pytest.fixture(scope="module")
def inputs(tmp_path_factory):
    d = tmp_path_factory.mktemp("targets")
    mask = np.zeros((8, 8, 8), dtype=bool)
    mask[2:6, 2:6, 2:6] = True
    np.save(d / "v.npy", mask)
    np.save(d / "v6.npy", mask[:6, :6, :6])
    np.save(d / "flat.npy", mask[0])
    bad = mask.astype(float)
    bad[0, 0, 0] = np.nan
    np.save(d / "nan.npy", bad)
    np.save(d / "zeros.npy", np.zeros((8, 8, 8)))
    np.save(d / "objects.npy", np.array([[[None]]], dtype=object), allow_pickle=True)
    _npy_header(d / "huge.npy", "|b1", (10000, 10000, 10000))
    _npy_header(d / "truncated.npy", "|b1", (8, 8, 8))
    (d / "text.npy").write_text("not an array")
    (d / "folder.npy").mkdir()
    (d / "notes.txt").write_text("hello")
    np.save(d / "nan2d.npy", np.array([[1.0, np.nan]]))
    sketch = np.full((16, 16), 255, np.uint8)
    sketch[4:12, 4:12] = 0
    Image.fromarray(sketch).save(d / "sketch.png")
    Image.fromarray(np.where(sketch == 0, 100, 160).astype(np.uint8)).save(d / "grey.png")  # a pencil on grey paper
    box = trimesh.creation.box((1.0, 1.0, 1.0))
    _obj(d / "box.obj", box.vertices, box.faces)
    (d / "garbage.glb").write_bytes(b"glTF\x02\x00\x00\x00garbage")
    (d / "empty.obj").write_bytes(b"")
    (d / "points.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\n")
    _obj(d / "lines.obj", [[0, 0, 0], [1, 0, 0], [2, 0, 0], [3, 0, 0]], [[0, 1, 2], [1, 2, 3]])
    nan_box = box.vertices.copy()
    nan_box[:, 0] = np.nan  # every vertex: a box with one is read without the faces on it
    _obj(d / "nan.obj", nan_box, box.faces)
    (d / "huge.ply").write_bytes(b"ply\nformat binary_little_endian 1.0\nelement vertex 5000000\nproperty float x\n"
                                 b"property float y\nproperty float z\nelement face 10000000\n"
                                 b"property list uchar int vertex_indices\nend_header\n")
    (d / "huge.stl").write_bytes(b"binary stl".ljust(80, b" ") + struct.pack("<I", 10_000_000))
    _obj(d / "sheet.obj", [[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], [[0, 1, 2], [0, 2, 3]])
    # 10,000 separate small triangles all over a unit cube: no inside, and (at voxel size
    # 1/64) far too many holes to decide one: refused from a sample of the work
    rng = np.random.default_rng(0)
    soup = (rng.uniform(0, 1, size=(10_000, 1, 3)) + rng.normal(scale=0.02, size=(10_000, 3, 3))).reshape(-1, 3)
    trimesh.Trimesh(soup, np.arange(30_000).reshape(-1, 3), process=False).export(d / "soup.ply")
    for name, spec, _ in CASES:
        (d / f"{name}.json").write_text(json.dumps(spec))
    return d


@pytest.mark.parametrize("name,message", [(c[0], c[2]) for c in CASES], ids=[c[0] for c in CASES])
def test_refused_in_one_line_naming_file_and_field(inputs, tmp_path, capsys, monkeypatch, name, message):
    def engine_must_not_run(*args, **kwargs):
        raise AssertionError("the engine ran before the refusal")

    for engine in list(procmod.infer.ENGINES):
        monkeypatch.setitem(procmod.infer.ENGINES, engine, engine_must_not_run)
    before = sorted(p.name for p in tmp_path.iterdir())
    code = main(["infer", "spaceship", "--target", str(inputs / f"{name}.json"), "--engine", "ga",
                 "--out", str(tmp_path / "out")])
    out, err = capsys.readouterr()
    assert code == 2, (out, err)
    assert err.startswith("procmod: error: ") and err.count("\n") == 1, err
    assert "Traceback" not in err
    assert f"{name}.json: {message}" in err, err
    if name in TAILS:
        assert TAILS[name] in err, err
    assert sorted(p.name for p in tmp_path.iterdir()) == before  # nothing written, no --out
    assert len(err) < 600


def test_declared_face_counts(tmp_path):
    # read from headers and cheap scans, so that a 10^7-face file is refused unread
    from procmod.targets.files import declared_faces
    box = trimesh.creation.box()
    for suffix in (".stl", ".ply", ".off", ".glb"):
        box.export(tmp_path / f"b{suffix}")
        assert declared_faces(tmp_path / f"b{suffix}") == 12, suffix
    _obj(tmp_path / "b.obj", box.vertices, box.faces)
    assert declared_faces(tmp_path / "b.obj") == 12
    (tmp_path / "a.stl").write_text(box.export(file_type="stl_ascii"))
    assert declared_faces(tmp_path / "a.stl") == 12


def test_a_tools_own_keys_are_left_alone(inputs):
    """Only near misses are refused: a tool's keys that merely look alike stay readable."""
    from procmod.targets import load_target_file
    for spec in (dict(_sil({"mesh_source": "maya", "mesh_path": "/x"}), mesh_source="maya"),
                 _with(MESH, layers__0__mesh_url="http://x", voxels="fine", mesh_source="maya")):
        (inputs / "tool.json").write_text(json.dumps(spec))
        load_target_file(inputs / "tool.json")


def test_a_scan_with_a_nan_vertex_is_read_without_the_faces_on_it(tmp_path):
    """A scanner's dropout (one NaN vertex that faces use) refused the whole mesh (h132);
    its faces are left out now, with a note, and the hole they leave is bridged like any
    other: the target is the clean mesh's but for a few voxels at the hole."""
    from procmod.targets import load_target_file

    sphere = trimesh.creation.icosphere(2, radius=0.4)
    sphere.apply_translation((1.6, 0.5, 0.3))
    broken = sphere.vertices.copy()
    broken[3] = np.nan
    _obj(tmp_path / "clean.obj", sphere.vertices, sphere.faces)
    _obj(tmp_path / "scan.obj", broken, sphere.faces)
    on_it = int((sphere.faces == 3).any(axis=1).sum())
    masks = {}
    for name in ("clean", "scan"):
        (tmp_path / f"{name}.json").write_text(json.dumps(
            {"format": "procmod-volume/1", "voxel_size": 0.1, "layers": [{"file": f"{name}.obj"}]}))
        target = load_target_file(tmp_path / f"{name}.json")
        masks[name] = target.combined > 0
        notes = target.file_notes
    assert any(f"1 vertex is not a finite number (NaN or infinity); the {on_it} faces on it were left out" in n
               for n in notes), notes
    assert masks["clean"].sum() > 200 and (masks["clean"] != masks["scan"]).sum() <= 3
    view = {"mesh": "scan.obj", "camera": {"eye": [1.6, 0.5, 5.0], "look_at": [1.6, 0.5, 0.3], "fov": 20,
                                           "width": 32, "height": 32}}
    (tmp_path / "sil.json").write_text(json.dumps({"format": "procmod-silhouette/1", "views": [view]}))
    assert any("1 vertex is not a finite number" in n for n in load_target_file(tmp_path / "sil.json").file_notes)
    # the library's own voxelizer says so too, where it is given a list for its notes
    from procmod.targets import voxelize_mesh_file
    notes = []
    _, mask = voxelize_mesh_file(tmp_path / "scan.obj", 0.1, notes=notes)
    assert mask.sum() > 200 and any("1 vertex is not a finite number" in n for n in notes), notes
