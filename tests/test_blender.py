"""The Blender add-on in real Blender (the ``bpy`` module from PyPI, headless).

Every operator runs as a script calls it (``bpy.ops.procmod.*()``): jobs that run procmod go
to a worker process with this interpreter, and the operator returns once the objects are in
the scene. What the modal (UI) path adds is only a timer calling the same
:meth:`Runner.tick`; a test checks that a tick never blocks while the worker works.
"""

import json
import math
import re
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

bpy = pytest.importorskip("bpy", reason="the bpy module (Blender 4.5 as a Python module) is not installed: "
                                        "pip install --no-deps bpy==4.5.15 (.ci/run installs it)")
from mathutils import Matrix, Vector  # noqa: E402  (comes with bpy)

from procmod.core import run_forward  # noqa: E402
from procmod.geometry.camera import Camera  # noqa: E402
from procmod.geometry.solid import part_triangles  # noqa: E402
from procmod.models import get_model  # noqa: E402
from procmod.targets import load_target_file  # noqa: E402

import procmod.blender as addon_package  # noqa: E402


@pytest.fixture(scope="module")
def registered():
    addon_package.register()
    from procmod.blender import addon
    yield addon
    addon_package.unregister()


@pytest.fixture
def context(registered, tmp_path):
    bpy.ops.wm.read_factory_settings(use_empty=True)
    bpy.context.scene.procmod.output_dir = str(tmp_path / "runs")
    return bpy.context


def _one_line_error(call, match):
    with pytest.raises(RuntimeError) as info:
        call()
    message = str(info.value)
    assert re.search(match, message), message
    assert "Traceback" not in message and message.strip().count("\n") == 0, message
    return message


def _mesh_object(name, kind="cube", location=(0, 0, 0), scale=(1, 1, 1)):
    if kind == "cube":
        bpy.ops.mesh.primitive_cube_add(size=2, location=location)
    elif kind == "plane":
        bpy.ops.mesh.primitive_plane_add(size=2, location=location)
    else:
        bpy.ops.mesh.primitive_cylinder_add(radius=0.3, depth=3, vertices=12, location=location)
    obj = bpy.context.active_object
    obj.name = name
    obj.scale = scale
    bpy.context.view_layer.update()
    return obj


def _select(*objects):
    bpy.ops.object.select_all(action="DESELECT")
    for obj in objects:
        obj.select_set(True)


def _parent(child, parent):
    """Parent keeping the child where it is in the world (as Ctrl+P does)."""
    child.parent = parent
    child.matrix_parent_inverse = parent.matrix_world.inverted()


def _exported(context, roots, folder):
    """The example hierarchies of ``roots`` as the add-on exports them, read by procmod's
    asset reader (the one procmod learn uses)."""
    from procmod.blender import scene
    from procmod.geometry.assets import read_assets
    _select(*roots)
    examples, _ = scene.write_examples(scene.example_roots(context.selected_objects), folder)
    return read_assets(examples)


def _world_vertices(obj):
    return np.array([tuple(obj.matrix_world @ v.co) for v in obj.data.vertices])


# ---- registration ------------------------------------------------------------------------------------

def test_register_adds_the_operators_and_the_panel_and_unregister_removes_them(registered):
    names = ("sample", "infer", "learn", "stop", "add_layers", "remove_layer", "new_mask", "open_report")
    assert all(hasattr(bpy.types, f"PROCMOD_OT_{n}") for n in names)
    assert hasattr(bpy.types, "PROCMOD_PT_panel") and bpy.types.PROCMOD_PT_panel.bl_category == "procmod"
    addon_package.unregister()
    try:
        assert not hasattr(bpy.types, "PROCMOD_OT_sample") and not hasattr(bpy.types.Scene, "procmod")
    finally:
        addon_package.register()
    assert bpy.ops.procmod.sample.poll()


# ---- sample -----------------------------------------------------------------------------------------

def test_samples_become_collections_of_parts_placed_as_procmod_places_them(context):
    settings = context.scene.procmod
    settings.model, settings.seed, settings.count = "spaceship", 3, 2
    assert bpy.ops.procmod.sample() == {"FINISHED"}
    collections = sorted(bpy.data.collections, key=lambda c: c.name)
    assert [c.name for c in collections] == ["procmod spaceship sample 0 (seed 3)", "procmod spaceship sample 1 (seed 3)"]
    context.view_layer.update()
    to_blender = Matrix(((1, 0, 0), (0, 0, -1), (0, 1, 0)))
    for i, collection in enumerate(collections):
        roots = [o for o in collection.objects if o.type == "EMPTY"]
        parts = sorted((o for o in collection.objects if o.type == "MESH"), key=lambda o: o["procmod_part"])
        assert len(roots) == 1
        origin = np.array(roots[0].matrix_world.translation)
        geometry = run_forward(get_model("spaceship"), np.random.default_rng([3, i])).geometry()
        assert len(parts) == len(geometry)
        for obj, part in zip(parts, geometry):
            assert obj["procmod_tag"] == part.tag and obj.active_material.name == f"procmod {part.tag}"
            # the object's vertices are procmod's triangles' corners, turned z-up, at the root
            expected = part_triangles(part, 24).reshape(-1, 3) @ np.array(to_blender).T + origin
            got = _world_vertices(obj)
            assert np.allclose(got.min(0), expected.min(0), atol=1e-4)
            assert np.allclose(got.max(0), expected.max(0), atol=1e-4)
        assert all(o.parent is not None for o in parts)  # under the root or their call's parent part
    # alike parts (same shape and size) share one mesh; a part's size is in its mesh, not its object
    meshes = {}
    objects = [o for c in collections for o in c.objects if o.type == "MESH"]
    for obj in objects:
        size = tuple(np.round(np.ptp([tuple(v.co) for v in obj.data.vertices], axis=0), 6))
        meshes.setdefault((obj["procmod_tag"], len(obj.data.vertices), size), set()).add(obj.data.name)
        assert np.allclose(obj.matrix_world.to_scale(), 1.0)
    assert all(len(names) == 1 for names in meshes.values()) and len(meshes) < 0.7 * len(objects)


def test_a_scene_in_centimetres_gets_models_and_targets_at_their_size(context, tmp_path):
    """procmod's models are in metres. In a scene of Unit Scale 0.01 (centimetres) a
    sampled ship came in 100x too small and a 200 cm cube was read as a 200 m target;
    now the ship is in centimetres, the cube a 2 m target, and examples go to learn in
    metres too (so its samples come back at the examples' size)."""
    from procmod.blender import scene
    context.scene.unit_settings.scale_length = 0.01
    settings = context.scene.procmod
    settings.model, settings.seed, settings.count = "spaceship", 3, 1
    assert bpy.ops.procmod.sample() == {"FINISHED"}
    context.view_layer.update()
    (collection,) = bpy.data.collections
    root = next(o for o in collection.objects if o.type == "EMPTY")
    origin = np.array(root.matrix_world.translation)
    parts = sorted((o for o in collection.objects if o.type == "MESH"), key=lambda o: o["procmod_part"])
    geometry = run_forward(get_model("spaceship"), np.random.default_rng([3, 0])).geometry()
    to_blender = np.array(((1, 0, 0), (0, 0, -1), (0, 1, 0)))
    for obj, part in zip(parts, geometry):
        expected = 100.0 * part_triangles(part, 24).reshape(-1, 3) @ to_blender.T + origin
        got = _world_vertices(obj)
        assert np.allclose(got.min(0), expected.min(0), atol=1e-3) and np.allclose(got.max(0), expected.max(0),
                                                                                    atol=1e-3)
    cube = _mesh_object("Cube", location=(0, 0, 100), scale=(100, 100, 100))  # 200 cm across
    scene.write_world_mesh(context, cube, tmp_path / "cube.obj")
    lines = (tmp_path / "cube.obj").read_text().splitlines()
    vertices = np.array([[float(v) for v in line.split()[1:4]] for line in lines if line.startswith("v ")])
    assert np.allclose(vertices.min(0), [-1, 0, -1]) and np.allclose(vertices.max(0), [1, 2, 1])
    leg = _mesh_object("Leg", location=(0, 50, 30), scale=(5, 5, 30))
    _parent(leg, cube)
    context.view_layer.update()
    (example,) = _exported(context, [cube], tmp_path / "examples").assets
    (top,) = example.roots
    assert np.allclose(top.transform[:3, 3], [0, 1, 0], atol=1e-6)  # 100 cm up, in metres, y-up
    (child,) = top.children
    assert np.allclose(child.transform[:3, 3], [0, 0.3, -0.5], atol=1e-6)


def test_a_sampled_tree_exports_to_gltf_as_it_shows(context, tmp_path):
    """Parts held their size as their objects' scale, so a box or a branch scaled unevenly
    skewed every turned child in its frame; Blender's glTF exporter, whose nodes hold
    translation, rotation and scale only, wrote a sampled tree's branches ~1,500 times too
    far out (and the add-on's Learn read its own samples that way)."""
    import trimesh

    settings = context.scene.procmod
    settings.model, settings.seed, settings.count = "tree", 1, 1
    assert bpy.ops.procmod.sample() == {"FINISHED"}
    context.view_layer.update()
    parts = [o for o in bpy.data.objects if o.type == "MESH"]
    assert any(o.parent is not None and o.parent.type == "MESH" for o in parts)  # the calls' nesting is kept
    world = np.concatenate([_world_vertices(o) for o in parts]) @ np.array(Matrix(((1, 0, 0), (0, 0, 1), (0, -1, 0)))).T
    bpy.ops.object.select_all(action="SELECT")
    bpy.ops.export_scene.gltf(filepath=str(tmp_path / "tree.glb"), export_format="GLB", use_selection=True)
    exported = trimesh.load(tmp_path / "tree.glb", force="mesh").bounds
    assert np.allclose(exported, [world.min(0), world.max(0)], atol=1e-3), (exported, world.min(0), world.max(0))


def test_a_learned_model_needs_its_program(context):
    context.scene.procmod.model = "PROGRAM"
    _one_line_error(lambda: bpy.ops.procmod.sample(), "choose the learned program")


# ---- control: volume ----------------------------------------------------------------------------------

def test_control_toward_a_scene_mesh_stops_early_keeping_the_best_and_writes_the_cli_run(context, registered,
                                                                                         monkeypatch):
    settings = context.scene.procmod
    # a slab where spaceships are built (procmod z in [-5, 5] is Blender y), and a pillar to avoid
    fill = _mesh_object("Slab", location=(0, 0, 0.5), scale=(1.5, 4.5, 0.6))
    avoid = _mesh_object("Pillar", location=(3, 0, 0.5), scale=(0.5, 0.5, 1.0))
    _select(fill)
    assert bpy.ops.procmod.add_layers(role="FILL") == {"FINISHED"}
    _select(avoid)
    assert bpy.ops.procmod.add_layers(role="AVOID") == {"FINISHED"}
    settings.engine, settings.population, settings.budget, settings.voxel_size = "ga", 10, "120s", 0.25
    ticks = []
    tick = registered.Runner.tick

    def timed_tick(self, context):
        start = time.perf_counter()
        done = tick(self, context)
        ticks.append(time.perf_counter() - start)
        if "evaluations" in self.job.message and not (self.job.folder / "stop").exists():
            bpy.ops.procmod.stop()  # what the panel's Stop button does, once the engine is running
        return done

    monkeypatch.setattr(registered.Runner, "tick", timed_tick)
    start = time.perf_counter()
    assert bpy.ops.procmod.infer() == {"FINISHED"}
    assert time.perf_counter() - start < 60  # stopped long before the budget
    assert max(ticks) < 0.2 and len(ticks) > 5  # the UI's timer never waits for the work
    (best,) = bpy.data.collections
    assert best.name.startswith("procmod best ga")
    status = context.window_manager.procmod_status
    run = Path(status.report).parent
    assert {p.name for p in run.iterdir()} == {"best.glb", "best.json", "best.obj", "best.png", "convergence.svg",
                                               "history.csv", "report.html", "samples.png", "settings.json"}
    settings_json = json.loads((run / "settings.json").read_text())
    assert any("stopped from Blender" in n for n in settings_json["notes"])
    command = settings_json["command"]
    assert command.startswith("procmod infer spaceship --target ") and "--budget 120s" in command
    target = load_target_file(Path(command.split("--target ")[1].split(" ")[0]) / "target.json")
    # the slab is 3 x 9 x 1.2 units in Blender (x, y, z): 3 x 1.2 x 9 in procmod's y-up frame,
    # 12 x 4 x 36 voxel centres of 0.25 (4 of the 1.2: the grid starts 2 voxels below the pillar)
    assert (target.combined == 1).sum() == 12 * 4 * 36
    assert target.combined.min() == -3  # the pillar: the slab's outside (-1) and its own inside (-2)


def test_bad_volume_targets_are_one_line_reports(context):
    settings = context.scene.procmod
    _one_line_error(lambda: bpy.ops.procmod.infer(), "no layers")
    camera = bpy.data.objects.new("Cam", bpy.data.cameras.new("Cam"))
    context.scene.collection.objects.link(camera)
    _select(camera)
    _one_line_error(lambda: bpy.ops.procmod.add_layers(role="FILL"), "'Cam' \\(camera\\) is not a mesh")
    kit = bpy.data.collections.new("Kit")
    instance = bpy.data.objects.new("Kit.001", None)
    instance.instance_type, instance.instance_collection = "COLLECTION", kit
    context.scene.collection.objects.link(instance)
    _select(instance)
    _one_line_error(lambda: bpy.ops.procmod.add_layers(role="FILL"), "instance of collection 'Kit'")
    bpy.ops.object.select_all(action="DESELECT")
    _one_line_error(lambda: bpy.ops.procmod.add_layers(role="FILL"), "nothing is selected")
    plane = _mesh_object("Sheet", kind="plane")
    _select(plane)
    bpy.ops.procmod.add_layers(role="FILL")
    _one_line_error(lambda: bpy.ops.procmod.infer(), "'Sheet' \\(mesh\\) is flat, so it has no inside")
    assert not list(Path(settings.output_dir).glob("infer-*")), "a failed job left its run folders"
    bpy.data.objects.remove(plane)
    _one_line_error(lambda: bpy.ops.procmod.infer(), "target layer 1 has no object")
    assert bpy.ops.procmod.remove_layer() == {"FINISHED"} and len(settings.layers) == 0


# ---- control: silhouette ------------------------------------------------------------------------------

def _camera(kind, location, look_at, aspect=(160, 120)):
    data = bpy.data.cameras.new(kind)
    data.type = kind
    if kind == "ORTHO":
        data.ortho_scale = 14.0
    else:
        data.lens = 35.0
    obj = bpy.data.objects.new(kind, data)
    bpy.context.scene.collection.objects.link(obj)
    obj.location = location
    obj.rotation_euler = (Vector(look_at) - Vector(location)).to_track_quat("-Z", "Y").to_euler()
    bpy.context.scene.render.resolution_x, bpy.context.scene.render.resolution_y = aspect
    bpy.context.view_layer.update()
    return obj


@pytest.mark.parametrize("kind,aspect", [("PERSP", (160, 120)), ("PERSP", (90, 160)), ("ORTHO", (160, 120))])
def test_a_blender_camera_sees_points_where_procmods_camera_does(context, kind, aspect):
    from bpy_extras.object_utils import world_to_camera_view

    from procmod.blender import scene
    obj = _camera(kind, (9, -14, 7), (0.5, 0.3, 2.0), aspect)
    width, height = aspect
    spec = scene.camera_spec(context, obj, width, height)
    camera = Camera(tuple(spec["eye"]), tuple(spec["look_at"]), tuple(spec["up"]), spec["projection"], spec["fov"],
                    width, height)
    rng = np.random.default_rng(0)
    for point in rng.uniform(-3, 3, size=(20, 3)):
        ndc = world_to_camera_view(context.scene, obj, Vector(point))
        pixel = camera.project(np.array(scene.to_procmod_point(point)))
        assert pixel[0] == pytest.approx(ndc.x * width, abs=1e-3)
        assert pixel[1] == pytest.approx((1 - ndc.y) * height, abs=1e-3)


def _painted_mask(width, height, box):
    image = bpy.data.images.new("mask", width=width, height=height, alpha=False)
    pixels = np.ones((height, width, 4), dtype=np.float32)
    x0, y0, x1, y1 = box  # rows from the top, as the mask is seen
    pixels[y0:y1, x0:x1, :3] = 0.0
    image.pixels.foreach_set(pixels[::-1].ravel())  # Blender's rows run bottom-up
    return image


def test_control_toward_a_painted_mask_under_the_active_camera(context):
    settings = context.scene.procmod
    camera = _camera("ORTHO", (0, -30, 4), (0, 0, 4), (80, 80))
    context.scene.camera = camera
    settings.target_kind, settings.model, settings.engine = "SILHOUETTE", "tree", "ga"
    settings.population, settings.budget = 10, "2gens"
    _one_line_error(lambda: bpy.ops.procmod.infer(), "no mask image")
    settings.mask = _painted_mask(60, 80, (20, 10, 40, 70))
    _one_line_error(lambda: bpy.ops.procmod.infer(), "60x80 pixels but the camera frame")
    assert bpy.ops.procmod.new_mask() == {"FINISHED"}
    assert tuple(settings.mask.size) == (128, 128)
    _one_line_error(lambda: bpy.ops.procmod.infer(), "no dark pixel")
    settings.mask = _painted_mask(80, 80, (30, 10, 50, 70))
    assert bpy.ops.procmod.infer() == {"FINISHED"}
    (best,) = bpy.data.collections
    assert best.name.startswith("procmod best ga")
    run = Path(context.window_manager.procmod_status.report).parent
    target = json.loads((run.with_name(run.name + ".target") / "target.json").read_text())
    assert target["format"] == "procmod-silhouette/1"
    view = target["views"][0]["camera"]
    assert view["projection"] == "orthographic" and view["fov"] == pytest.approx(14.0)
    assert np.allclose(view["eye"], [0, 4, 30], atol=1e-6) and np.allclose(view["up"], [0, 1, 0], atol=1e-6)
    scene_camera = context.scene.camera
    context.scene.camera = None
    settings.camera = None
    _one_line_error(lambda: bpy.ops.procmod.infer(), "no camera")
    context.scene.camera = scene_camera


# ---- learn -----------------------------------------------------------------------------------------------

def _castles(count=4):
    """Keeps (a shared cube mesh) each with towers (a shared cylinder mesh) parented to it."""
    keep_mesh = _mesh_object("k", "cube").data
    tower_mesh = _mesh_object("t", "cylinder").data
    for name in ("k", "t"):
        bpy.data.objects.remove(bpy.data.objects[name])
    roots = []
    for e in range(count):
        keep = bpy.data.objects.new(f"keep{e}", keep_mesh)
        bpy.context.scene.collection.objects.link(keep)
        keep.location, keep.scale = (8 * e, 0, 1), (1 + 0.1 * e, 1, 1)
        bpy.context.view_layer.update()
        towers = 2 + e % 3
        for i in range(towers):
            tower = bpy.data.objects.new(f"tower{e}_{i}", tower_mesh)
            bpy.context.scene.collection.objects.link(tower)
            angle = 2 * math.pi * i / towers
            tower.location = (8 * e + 1.5 * math.cos(angle), 1.5 * math.sin(angle), 1.5)
            tower.parent = keep
            tower.matrix_parent_inverse = keep.matrix_world.inverted()
        roots.append(keep)
    bpy.context.view_layer.update()
    return roots


def test_selected_hierarchies_become_examples_with_one_part_per_shared_mesh(context, tmp_path):
    from procmod.blender import scene
    from procmod.geometry.assets import read_assets
    from procmod.learn.examples import examples_from_assets
    roots = _castles(3)
    _select(roots[0], roots[1], roots[2], *roots[1].children)  # children of a selected root are in it already
    chosen = scene.example_roots(context.selected_objects)
    assert chosen == roots
    examples, names = scene.write_examples(chosen, tmp_path)
    # the reader procmod learn uses on a user's own glTF export
    example_set = examples_from_assets(read_assets(examples))
    # meshes named as Blender names its primitives are named after their first object
    assert sorted(example_set.parts) == ["keep", "tower0"]
    assert [e.size() for e in example_set.examples] == [3, 4, 5]
    part = example_set.parts["tower0"]
    tower = next(c for c in example_set.examples[1].children
                 if np.allclose(c.transform[:3, 3], list(scene.TO_PROCMOD @ bpy.data.objects["tower1_0"].location),
                                atol=1e-5))
    blender_tower = bpy.data.objects["tower1_0"]
    placed = np.asarray(part.vertices) @ tower.transform[:3, :3].T + tower.transform[:3, 3]
    world = np.array([list(scene.TO_PROCMOD @ blender_tower.matrix_world @ v.co) for v in blender_tower.data.vertices])
    # the part placed by its node covers the object's own mesh in the world (up to the part's own frame)
    assert np.allclose(np.sort(placed, axis=0), np.sort(world[:, :3], axis=0), atol=1e-5)
    assert json.loads(names.read_text()) == {f"example{i:03d}.glb": root.name for i, root in enumerate(roots)}
    assert sorted(o.name for o in context.selected_objects) == sorted(
        o.name for o in (*roots, *roots[1].children))  # the selection is left as it was


def test_a_part_turned_under_an_unevenly_scaled_parent_is_refused_naming_both(context, tmp_path):
    """A leg turned 20 degrees under a seat scaled flat (Ctrl+P with the seat's scale not
    applied) is skewed in the seat's frame: the glTF exporter wrote it elsewhere at another
    shape (0.2 x 0.8 x 5.9 instead of 0.2 x 1.0 x 0.5) and it was learned so, silently."""
    seat = _mesh_object("Seat", location=(0, 0, 1), scale=(1, 1, 0.1))
    leg = _mesh_object("Leg", location=(0.8, 0.8, 0.5), scale=(0.1, 0.1, 0.5))
    leg.rotation_euler = (math.radians(20), 0, 0)
    context.view_layer.update()
    _parent(leg, seat)
    context.view_layer.update()
    from procmod.blender import scene
    with pytest.raises(scene.SceneError, match="'Leg' \\(mesh\\) is turned under 'Seat'.*apply the scale of 'Seat'"):
        scene.write_examples([seat], tmp_path)
    leg.rotation_euler = (0, 0, 0)  # upright, its axes stay square in the seat's frame: exported as it shows
    context.view_layer.update()
    _parent(leg, seat)
    context.view_layer.update()
    asset_set = _exported(context, [seat], tmp_path / "upright")
    assert sorted(asset_set.parts) == ["Leg", "Seat"]


def test_a_part_without_faces_is_named_by_learns_note_not_dropped_silently(context, tmp_path):
    """A wire (loose edges only) parented under a seat draws nothing, so it is no part;
    Blender's exporter had written it as an empty node, so learn left it out with no word."""
    from procmod.blender import scene
    from procmod.geometry.assets import faceless_note
    seat = _mesh_object("Seat", location=(0, 0, 1), scale=(1, 1, 0.1))
    mesh = bpy.data.meshes.new("wire")
    mesh.from_pydata([(0, 0, 0), (1, 0, 0), (1, 1, 0)], [(0, 1), (1, 2)], [])
    wire = bpy.data.objects.new("Wire", mesh)
    context.scene.collection.objects.link(wire)
    _parent(wire, seat)
    context.view_layer.update()
    _select(seat)
    examples, _ = scene.write_examples(scene.example_roots(context.selected_objects), tmp_path)
    note = faceless_note([examples])
    assert note is not None and "'Wire' in example000.glb draws no faces" in note, note
    asset_set = _exported(context, [seat], tmp_path / "again")
    assert sorted(asset_set.parts) == ["Seat"]  # read as before: the wire is no part
    seat_only = _mesh_object("Stool")
    _select(seat_only)
    alone, _ = scene.write_examples(scene.example_roots(context.selected_objects), tmp_path / "stool")
    assert faceless_note([alone]) is None


def test_the_addons_weight_limit_is_the_target_files():
    from procmod.blender import addon
    from procmod.targets import files
    assert addon.MAX_WEIGHT == files.MAX_WEIGHT


def test_a_runs_folder_under_home_is_the_users_home(context, tmp_path, monkeypatch):
    """"~/runs" made a folder named "~" in Blender's working folder."""
    from procmod.blender import addon
    monkeypatch.setenv("HOME", str(tmp_path / "home"))
    monkeypatch.chdir(tmp_path)
    context.scene.procmod.output_dir = "~/runs"
    assert addon._output_dir(context.scene.procmod) == tmp_path / "home" / "runs"
    assert not (tmp_path / "~").exists()


def test_the_addons_skew_limit_is_the_learners():
    from procmod.blender import scene
    from procmod.learn import examples
    assert scene.SHEAR_TOLERANCE == examples.SHEAR_TOLERANCE


def test_a_chair_of_scaled_cubes_learns_a_seat_a_back_and_legs(context, tmp_path):
    """The add-on wrote its own examples file, where every cube of a chair scaled into a
    seat, a back and legs (the scale not applied, as Blender users leave it) was one part
    type: its program sampled chairs of 1, 2 or 10 boxes. The add-on now exports glTF
    and reads it as procmod learn reads a user's export."""
    roots = []
    for e in range(3):
        seat = _mesh_object(f"Seat.{e:03d}", location=(4 * e, 0, 0.5), scale=(0.5, 0.5, 0.05))
        parts = [_mesh_object(f"Back.{e:03d}", location=(4 * e, 0.48, 0.9), scale=(0.5, 0.03, 0.4))]
        for k, (x, y) in enumerate([(-0.45, -0.45), (0.45, -0.45), (-0.45, 0.45), (0.45, 0.45)]):
            parts.append(_mesh_object(f"Leg.{4 * e + k:03d}", location=(4 * e + x, y, 0.25),
                                      scale=(0.04, 0.04, 0.25 + 0.02 * e)))
        for part in parts:
            _parent(part, seat)
        roots.append(seat)
    bpy.context.view_layer.update()
    asset_set = _exported(context, roots, tmp_path)
    assert sorted(asset_set.parts) == ["Back", "Leg", "Seat"]
    assert [sorted(n.part for n in a.nodes()) for a in asset_set.assets] == [["Back"] + ["Leg"] * 4 + ["Seat"]] * 3


def test_an_example_the_learner_refuses_is_named_by_its_objects(context):
    """The add-on's examples are its own temporary files: a message names the objects."""
    settings = context.scene.procmod
    roots = []
    for e in range(2):
        body = _mesh_object(f"Body{e}", location=(4 * e, 0, 0))
        _parent(_mesh_object(f"Flat{e}", location=(4 * e, 0, 2), scale=(1, 0, 1)), body)  # scaled to nothing
        roots.append(body)
    bpy.context.view_layer.update()
    _select(*roots)
    settings.count, settings.learn_particles = 1, 1
    message = _one_line_error(lambda: bpy.ops.procmod.learn(), "Flat0")
    assert "the hierarchy of 'Body0'" in message and "example000.glb" not in message, message


def test_a_part_is_learned_as_the_viewport_shows_it(context, tmp_path):
    """Modifiers were left out: a half modelled with a Mirror modifier was learned as half."""
    roots = []
    for e in range(2):
        root = _mesh_object(f"Body{e}", location=(10 * e, 0, 0))
        wing = _mesh_object(f"Wing{e}", location=(10 * e, 0, 0))
        for vertex in wing.data.vertices:
            vertex.co.x += 2.0  # the half at x 1..3 of its own frame
        wing.modifiers.new("mirror", "MIRROR")  # and its mirror image at x -3..-1
        _parent(wing, root)
        roots.append(root)
    bpy.context.view_layer.update()
    asset_set = _exported(context, roots, tmp_path)
    wing = next(n for n in asset_set.assets[0].nodes() if n.name == "Wing0")
    part = asset_set.parts[wing.part]
    assert len(part.faces) == 24 and np.ptp(np.asarray(part.vertices), axis=0).max() == pytest.approx(6.0)


def test_hidden_parts_are_in_their_example_and_excluded_ones_are_told(context, tmp_path):
    """Exported by selection, a child hidden in the viewport or made unselectable was left
    out of its example without a word; one in an excluded collection stopped the operator
    with an internal error."""
    roots = []
    for e, how in enumerate(("hide", "hide_viewport", "hide_select")):
        root = _mesh_object(f"Root{e}", location=(4 * e, 0, 0))
        leaf = _mesh_object(f"Leaf{e}", location=(4 * e, 0, 3), scale=(0.5, 0.5, 0.5))
        _parent(leaf, root)
        if how == "hide":
            leaf.hide_set(True)
        else:
            setattr(leaf, how, True)
        roots.append(root)
    bpy.context.view_layer.update()
    assert [len(a.nodes()) for a in _exported(context, roots, tmp_path).assets] == [2, 2, 2]
    leaves = [bpy.data.objects[f"Leaf{e}"] for e in range(3)]
    assert (leaves[0].hide_get(), leaves[1].hide_viewport, leaves[2].hide_select) == (True, True, True)  # as they were
    excluded = bpy.data.collections.new("Excluded")
    context.scene.collection.children.link(excluded)
    context.scene.collection.objects.unlink(leaves[0])
    excluded.objects.link(leaves[0])
    context.view_layer.layer_collection.children["Excluded"].exclude = True
    _select(*roots)
    _one_line_error(lambda: bpy.ops.procmod.learn(), "'Leaf0' .*excluded from the view layer.*include the collection")
    # a collection disabled in viewports (the monitor icon): the exporter left its part out, silently
    context.view_layer.layer_collection.children["Excluded"].exclude = False
    excluded.hide_viewport = True
    before = (leaves[0].hide_get(), leaves[0].hide_viewport, leaves[0].hide_select)
    _one_line_error(lambda: bpy.ops.procmod.learn(), "'Leaf0' .*disabled in viewports.*enable the collection")
    # its examples folder, begun, is gone: it had been left, and pushed the next run's number up (h66)
    assert not list(Path(context.scene.procmod.output_dir).glob("learn-*")), "a refused learn left a folder"
    assert excluded.hide_viewport and (leaves[0].hide_get(), leaves[0].hide_viewport,
                                       leaves[0].hide_select) == before  # left as it was


def test_learning_needs_a_selection_of_hierarchies(context):
    _one_line_error(lambda: bpy.ops.procmod.learn(), "nothing is selected")
    empty = bpy.data.objects.new("group", None)
    context.scene.collection.objects.link(empty)
    for name in ("a", "b"):
        _mesh_object(name).parent = empty
    _select(empty)
    _one_line_error(lambda: bpy.ops.procmod.learn(), "'group' \\(empty\\) is not a mesh and has 2 top-level")
    # a collection instance holds meshes that are no objects of the scene: say how to make them real
    kit = bpy.data.collections.new("Kit")
    kit.objects.link(bpy.data.objects.new("kit part", bpy.data.meshes.new("kit mesh")))
    instance = bpy.data.objects.new("Kit.001", None)
    instance.instance_type, instance.instance_collection = "COLLECTION", kit
    context.scene.collection.objects.link(instance)
    _select(instance)
    _one_line_error(lambda: bpy.ops.procmod.learn(), "instance of collection 'Kit'.*Make Instances Real")


# In the default suite (about 10 s): as a slow test it was skipped, and "Learn from
# selection" failed for every user for a sitting (procmod.learn.learn lacked `note`)
def test_learn_from_the_scene_then_sample_the_learned_program(context, monkeypatch):
    settings = context.scene.procmod
    roots = _castles(4)
    _select(*roots)
    settings.count, settings.learn_particles = 2, 1
    assert bpy.ops.procmod.learn() == {"FINISHED"}
    assert settings.model == "PROGRAM" and Path(settings.program).name == "program.json"
    # the examples the program names outlive the job (they were its temporary folder's)
    info = json.loads(Path(settings.program).read_text())["info"]
    examples = Path(settings.program).parent / info["example_files"][0]
    assert examples.resolve() == Path(f"{Path(settings.program).parent}.examples/examples").resolve()
    assert len(list(examples.glob("*.glb"))) == 4
    learned = [c for c in bpy.data.collections if "learned sample" in c.name]
    assert len(learned) == 2
    meshes = {o.data.name for c in learned for o in c.objects if o.type == "MESH"}
    assert meshes == {"procmod mesh keep", "procmod mesh tower0"}  # alike parts share their mesh
    settings.seed = 5
    assert bpy.ops.procmod.sample() == {"FINISHED"}
    assert sum("sample" in c.name for c in bpy.data.collections) == 4
    # the program's folder, typed relative to Blender's working folder: it was checked there
    # and opened from the job's temporary folder ("program file ... does not exist")
    program = Path(settings.program)
    monkeypatch.chdir(program.parent.parent)
    settings.program, settings.count = program.parent.name, 1
    assert bpy.ops.procmod.sample() == {"FINISHED"}
    assert any(c.name.startswith(f"procmod {program.parent.name} sample") for c in bpy.data.collections)


# ---- the add-on zip in Blender -----------------------------------------------------------------------------

def test_the_addon_zip_installs_and_enables_in_blender(tmp_path):
    from procmod.blender.package import write_addon_zip
    archive = write_addon_zip(tmp_path / "procmod_blender.zip")
    script = f"""
import bpy, addon_utils
bpy.ops.preferences.addon_install(filepath={str(archive)!r})
addon_utils.enable("procmod_blender", default_set=True)
assert hasattr(bpy.types, "PROCMOD_PT_panel")
bpy.context.scene.procmod.count = 1
assert bpy.ops.procmod.sample() == {{"FINISHED"}}
print("objects", len(bpy.data.objects))
"""
    env = {"BLENDER_USER_RESOURCES": str(tmp_path / "user"), "PATH": "/usr/bin:/bin", "HOME": str(tmp_path)}
    run = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=300, env=env)
    assert run.returncode == 0, run.stdout[-2000:] + run.stderr[-3000:]
    assert re.search(r"objects \d+", run.stdout)
    assert list((tmp_path / "user").rglob("procmod_blender/default_python.txt"))
    # unregistered by the exit hook and by Blender's add-on shutdown: once, no traceback at exit
    # (bpy's own import prints a NumPy-1.x module's traceback: not ours)
    assert "unregister" not in run.stderr and "procmod_status" not in run.stderr, run.stderr[-3000:]


def test_a_script_that_leaves_the_addon_registered_still_exits():
    # the bpy module hung at exit while an operator class was registered
    script = "import procmod.blender as addon\naddon.register()\nprint('registered')\n"
    try:
        run = subprocess.run([sys.executable, "-c", "import bpy\n" + script], capture_output=True, text=True,
                             timeout=120)
    except subprocess.TimeoutExpired:
        pytest.fail("python did not exit with the add-on registered")
    assert run.returncode == 0 and "registered" in run.stdout, run.stderr[-2000:]


def test_two_meshes_added_with_fill_are_one_target_both_to_fill(context):
    """Each Fill mesh was a layer of its own (1 inside, -1 outside): inside either one
    scored 1 - 1 = 0, so the target had nothing to gain and control ran without a word."""
    settings = context.scene.procmod
    cubes = [_mesh_object(f"Blob{i}", location=(0, 0, z), scale=(1.5, 1.5, 1.5)) for i, z in enumerate((1.0, 5.0))]
    _select(*cubes)
    assert bpy.ops.procmod.add_layers(role="FILL") == {"FINISHED"}
    settings.engine, settings.population, settings.budget, settings.voxel_size = "ga", 4, "1gens", 0.5
    assert bpy.ops.procmod.infer() == {"FINISHED"}
    report = Path(context.window_manager.procmod_status.report)
    target = load_target_file(Path(str(report.parent) + ".target") / "target.json")
    # two cubes of 3 units at voxel size 0.5: 6 x 6 x 6 voxels each, every one of them gaining 1
    assert (target.combined == 1).sum() == 2 * 6 ** 3 and target.combined.max() == 1
    assert target.best_attainable == 2 * 6 ** 3


def test_a_geometry_nodes_scatter_is_the_target_the_viewport_shows(context):
    """A mesh whose Geometry Nodes make instances (Instance on Points) has no faces of its
    own: it was refused as "has no faces" though the viewport shows eight cubes."""
    settings = context.scene.procmod
    base = _mesh_object("Scatter")  # a 2-unit cube: its 8 corners get a 1-unit cube each
    tree = bpy.data.node_groups.new("scatter", "GeometryNodeTree")
    tree.interface.new_socket("Geometry", in_out="INPUT", socket_type="NodeSocketGeometry")
    tree.interface.new_socket("Geometry", in_out="OUTPUT", socket_type="NodeSocketGeometry")
    given, result = tree.nodes.new("NodeGroupInput"), tree.nodes.new("NodeGroupOutput")
    points, instance, cube = (tree.nodes.new(t) for t in ("GeometryNodeMeshToPoints", "GeometryNodeInstanceOnPoints",
                                                          "GeometryNodeMeshCube"))
    tree.links.new(given.outputs[0], points.inputs[0])
    tree.links.new(points.outputs[0], instance.inputs[0])
    tree.links.new(cube.outputs[0], instance.inputs["Instance"])
    tree.links.new(instance.outputs[0], result.inputs[0])
    base.modifiers.new("scatter", "NODES").node_group = tree
    _select(base)
    assert bpy.ops.procmod.add_layers(role="FILL") == {"FINISHED"}
    settings.engine, settings.population, settings.budget, settings.voxel_size = "ga", 4, "1gens", 0.5
    assert bpy.ops.procmod.infer() == {"FINISHED"}
    report = Path(context.window_manager.procmod_status.report)
    target = load_target_file(Path(str(report.parent) + ".target") / "target.json")
    assert (target.combined == 1).sum() == 8 * 2 ** 3  # eight 1-unit cubes, 2 x 2 x 2 voxels each


def test_a_runs_folder_that_cannot_be_made_is_a_one_line_report(context, tmp_path):
    """A file in the Runs field's place was an internal error (NotADirectoryError) pointing
    at a traceback in the job's temporary folder."""
    settings = context.scene.procmod
    (tmp_path / "taken").write_text("x")
    settings.output_dir = str(tmp_path / "taken")
    _select(_mesh_object("Slab", scale=(1.5, 1.5, 0.6)))
    assert bpy.ops.procmod.add_layers(role="FILL") == {"FINISHED"}
    _one_line_error(lambda: bpy.ops.procmod.infer(), "cannot use .*taken' as the Runs folder \\(it or a folder above "
                                                      "it is a file\\): choose another folder")
    settings.output_dir = str(tmp_path / "taken" / "runs")
    _one_line_error(lambda: bpy.ops.procmod.infer(), "as the Runs folder")


def test_a_job_ended_by_a_user_error_leaves_no_temporary_folder(context, monkeypatch, tmp_path):
    """A job refused for the user's input kept its temporary folder (a copy of the target
    meshes) each time: only a failure whose worker.log may explain it keeps one."""
    from procmod.blender import jobs
    made = []
    job_folder = jobs.Job.__init__

    def recording(self, *args, **kwargs):
        job_folder(self, *args, **kwargs)
        made.append(self.folder)

    monkeypatch.setattr(jobs.Job, "__init__", recording)
    settings = context.scene.procmod
    _select(_mesh_object("Slab", scale=(1.5, 1.5, 0.6)))
    assert bpy.ops.procmod.add_layers(role="FILL") == {"FINISHED"}
    settings.budget = "lots"
    _one_line_error(lambda: bpy.ops.procmod.infer(), "cannot read budget 'lots'")
    assert made and not any(folder.exists() for folder in made)


def test_a_relative_runs_folder_is_blenders_working_folder(context, tmp_path, monkeypatch):
    """A Runs folder typed without // ("my_runs") was taken relative to the job's temporary
    folder, where the worker wrote the whole run, removed with it: the report said it was
    written and it did not exist."""
    monkeypatch.chdir(tmp_path)
    settings = context.scene.procmod
    settings.output_dir = "my_runs"
    slab = _mesh_object("Slab", location=(0, 0, 0.5), scale=(1.5, 4.5, 0.6))
    _select(slab)
    assert bpy.ops.procmod.add_layers(role="FILL") == {"FINISHED"}
    settings.engine, settings.population, settings.budget, settings.voxel_size = "ga", 6, "2gens", 0.5
    assert bpy.ops.procmod.infer() == {"FINISHED"}
    report = Path(context.window_manager.procmod_status.report)
    assert report.is_absolute() and report.is_file() and tmp_path / "my_runs" in report.parents


def test_many_target_layers_are_written_in_one_pass_with_their_instances(context, tmp_path):
    """The scene's instances were walked once per target layer: 10,000 layers took 40 s
    before a job's progress showed, Blender's UI frozen (h91). One pass for all layers
    writes what one layer at a time wrote: a plain cube, a mesh instancing a cube at its
    vertices (what the viewport shows), and one object in two layers."""
    from procmod.blender import scene

    cube = _mesh_object("Cube", location=(5, 0, 0))
    host = _mesh_object("Host", kind="plane", location=(0, 0, 0), scale=(3, 3, 3))
    dot = _mesh_object("Dot", location=(0, 0, 0), scale=(0.2, 0.2, 0.2))
    _parent(dot, host)
    host.instance_type = "VERTS"  # a small cube at each of the plane's four corners
    context.view_layer.update()
    objects = [cube, host, cube]
    scene.write_world_meshes(context, objects, [tmp_path / f"all{i}.obj" for i in range(3)])
    for i, obj in enumerate(objects):
        scene.write_world_mesh(context, obj, tmp_path / f"one{i}.obj")
        assert (tmp_path / f"all{i}.obj").read_text() == (tmp_path / f"one{i}.obj").read_text(), obj.name
    corners = np.array([[float(v) for v in line.split()[1:4]] for line in
                        (tmp_path / "all1.obj").read_text().splitlines() if line.startswith("v ")])
    assert len(corners) == 4 * 8 + 4 and np.allclose(np.abs(corners).max(0)[[0, 2]], 3.2)  # four cubes and the plane


def test_target_layers_of_one_name_from_linked_libraries_keep_their_own_instances(context, tmp_path):
    """Objects of one name linked from two libraries are two objects: the one pass over the
    scene's instances looked them up by name, and each got the other's (h93)."""
    from procmod.blender import scene

    for k, x in enumerate((0.0, 10.0)):
        host = _mesh_object("Host", kind="plane", location=(x, 0, 0), scale=(3, 3, 3))
        dot = _mesh_object("Dot", location=(x, 0, 0), scale=(0.2, 0.2, 0.2))
        _parent(dot, host)
        host.instance_type = "VERTS"
        bpy.data.libraries.write(str(tmp_path / f"lib{k}.blend"), {host, dot, host.data, dot.data})
        bpy.data.objects.remove(host)
        bpy.data.objects.remove(dot)
    linked = []
    for k in range(2):
        with bpy.data.libraries.load(str(tmp_path / f"lib{k}.blend"), link=True) as (_, into):
            into.objects = ["Host", "Dot"]
        for obj in into.objects:
            context.scene.collection.objects.link(obj)
        linked.append(next(o for o in into.objects if o.name == "Host"))
    context.view_layer.update()
    assert linked[0].name == linked[1].name and linked[0] != linked[1]
    scene.write_world_meshes(context, linked, [tmp_path / "all0.obj", tmp_path / "all1.obj"])
    for k, obj in enumerate(linked):
        scene.write_world_mesh(context, obj, tmp_path / f"one{k}.obj")
        assert (tmp_path / f"all{k}.obj").read_text() == (tmp_path / f"one{k}.obj").read_text()
    xs = [float(line.split()[1]) for line in (tmp_path / "all1.obj").read_text().splitlines() if line.startswith("v ")]
    assert min(xs) > 6.5  # the second library's host and its cubes, at x = 10


def test_examples_are_exported_at_the_frame_shown_and_edit_mode_is_kept(context, tmp_path):
    """Blender's glTF exporter went to frame 0 before writing (an animated leg was learned
    where frame 0 had it) and left edit mode for object mode without coming back (h134)."""
    from procmod.blender import scene
    from procmod.geometry.assets import read_assets
    from procmod.learn.examples import examples_from_assets
    seat = _mesh_object("Seat", location=(0, 0, 1), scale=(1, 1, 0.1))
    leg = _mesh_object("Leg", location=(0.8, 0.8, 0.5), scale=(0.1, 0.1, 0.5))
    _parent(leg, seat)
    for frame, x in ((0, 0.8), (10, -0.8)):
        leg.location.x = x
        leg.keyframe_insert("location", index=0, frame=frame)
    context.scene.frame_set(10)
    context.view_layer.update()
    _select(seat)
    context.view_layer.objects.active = seat
    bpy.ops.object.mode_set(mode="EDIT")
    examples, _ = scene.write_examples(scene.example_roots(context.selected_objects), tmp_path)
    assert seat.mode == "EDIT" and context.scene.frame_current == 10
    bpy.ops.object.mode_set(mode="OBJECT")
    (example,) = examples_from_assets(read_assets(examples)).examples
    (placed,) = example.children
    # Blender x is procmod x: the leg stands where frame 10 has it, not frame 0's +0.8
    assert placed.transform[0, 3] == pytest.approx(-0.8, abs=1e-4)


def test_repeat_last_does_not_run_a_job_that_would_freeze_blender(context, registered, monkeypatch):
    """Shift+R (Repeat Last) calls execute, which waits for the whole job with Blender frozen:
    the job operators are not registered (so not repeated), and refuse a repeat besides; a
    script's call after a panel's press (a registered run) is no repeat (h137)."""
    settings = context.scene.procmod
    settings.model, settings.count = "spaceship", 1
    for operator in (registered.PROCMOD_OT_sample, registered.PROCMOD_OT_infer, registered.PROCMOD_OT_learn):
        assert "REGISTER" not in operator.bl_options
    assert bpy.ops.procmod.sample("EXEC_DEFAULT", True) == {"FINISHED"}  # as a press, with its undo step
    assert bpy.ops.procmod.sample() == {"FINISHED"}
    monkeypatch.setattr(registered, "_repeated", lambda operator, context: True)
    count = len(bpy.data.collections)
    assert bpy.ops.procmod.sample() == {"CANCELLED"}
    assert registered.Runner.active is None and len(bpy.data.collections) == count


def test_a_job_whose_modal_run_blender_cancelled_stops_and_frees_the_panel(context, registered):
    """Opening a file removes every modal handler: with no cancel() the job stayed 'running',
    read by no one, and every later job was refused until Blender restarted (h134)."""
    from procmod.blender import jobs
    settings = context.scene.procmod
    job = jobs.Job("sample", {"model": "spaceship", "count": 50, "seed": 0}, sys.executable).start()
    runner = registered.Runner.active = registered.Runner(job, lambda context, result: "")

    class Cancelled:  # what Blender passes cancel(): the operator, its timer already gone with the file
        _timer, _runner = None, runner

    registered._JobOperator.cancel(Cancelled(), context)
    assert registered.Runner.active is None and job.done and job.result.get("cancelled")
    assert not job.folder.exists()
    # a job Stop had ended, not yet read by the timer when the file was opened: the panel
    # stayed "stopping..." and the job's folder was left (h138)
    stopped = jobs.Job("sample", {"model": "spaceship", "count": 50, "seed": 0}, sys.executable).start()
    Cancelled._runner = registered.Runner.active = registered.Runner(stopped, lambda context, result: "")
    context.window_manager.procmod_status.running = True
    stopped.kill()  # what Stop does to a sampling job
    registered._JobOperator.cancel(Cancelled(), context)
    assert registered.Runner.active is None and not context.window_manager.procmod_status.running
    assert not stopped.folder.exists()
    Cancelled._runner = runner
    # an operator's cancel or finish leaves another operator's job alone (h137: a job that
    # ended before its timer read it let a second start, and the first's timer finished it)
    other = jobs.Job("sample", {"model": "spaceship", "count": 50, "seed": 0}, sys.executable).start()
    registered.Runner.active = registered.Runner(other, lambda context, result: "")
    registered._JobOperator.cancel(Cancelled(), context)

    class Reporter:
        def report(self, kind, message):
            pass

    runner.finish(context, Reporter())
    assert registered.Runner.active.job is other and not other.done
    other.kill()
    other.cleanup()
    registered.Runner.active = None
    settings.model, settings.count = "spaceship", 1
    assert bpy.ops.procmod.sample() == {"FINISHED"}  # the panel runs jobs again


def test_learning_with_the_gltf_exporter_disabled_says_to_enable_it(context, tmp_path):
    """It had ended in 'internal error' (Blender's ops have no export_scene.gltf then)."""
    import addon_utils
    from procmod.blender import scene
    seat = _mesh_object("Seat")
    addon_utils.disable("io_scene_gltf2")
    try:
        with pytest.raises(scene.SceneError, match="enable 'glTF 2.0 format' in Edit > Preferences > Add-ons"):
            scene.write_examples([seat], tmp_path / "out")
    finally:
        addon_utils.enable("io_scene_gltf2")
    assert not (tmp_path / "out").exists()
    examples, _ = scene.write_examples([seat], tmp_path / "out")
    assert (examples / "example000.glb").is_file()
