"""Between Blender's scene and procmod's files (imports bpy; no procmod library code).

procmod's models are y-up (the glTF convention), Blender is z-up: a procmod point (x, y, z)
is the Blender point (x, -z, y), as Blender's glTF importer places it. Everything that
crosses goes through :data:`TO_BLENDER` / :data:`TO_PROCMOD`, and through the scene's Unit
Scale (:func:`unit_scale`): procmod's models are in metres, so in a scene of centimetres
(Unit Scale 0.01) a 9.5 m spaceship is 950 units long and a 200 cm cube a 2 m target (the
scale had been ignored: the ship came in 9.5 cm long beside a target 100x too large).

Errors the scene can cause (a non-mesh target, an empty selection, a mask of the wrong
shape) raise :class:`SceneError` with one line for the operator to report.
"""

from __future__ import annotations

import hashlib
import json
import math
import shutil
from pathlib import Path

import bpy
import numpy as np
from mathutils import Matrix, Vector

TO_BLENDER = Matrix(((1, 0, 0, 0), (0, 0, -1, 0), (0, 1, 0, 0), (0, 0, 0, 1)))
TO_PROCMOD = TO_BLENDER.inverted()
CYLINDER_SEGMENTS = 24
MESH_TYPES = {"MESH"}
GEOMETRY_TYPES = {"MESH", "CURVE", "SURFACE", "META", "FONT"}  # what an instance may be that has a mesh


class SceneError(Exception):
    """Something in the scene that procmod cannot use; the message is one line."""


def _matrix16(values) -> Matrix:
    return Matrix([values[0:4], values[4:8], values[8:12], values[12:16]])


def unit_scale(context=None) -> float:
    """Metres per Blender unit: the scene's Unit Scale (Scene > Units; 1 by default)."""
    scale = float((context or bpy.context).scene.unit_settings.scale_length)
    return scale if math.isfinite(scale) and scale > 0 else 1.0


def to_procmod_point(point, scale: float = 1.0) -> list:
    """A Blender point in procmod's frame, ``scale`` metres per Blender unit."""
    return [float(v) * scale for v in (TO_PROCMOD @ Vector(point))]


def to_procmod_direction(direction) -> list:
    return [float(v) for v in (TO_PROCMOD.to_3x3() @ Vector(direction))]


# ---- parts -> objects ----------------------------------------------------------------------------

def _srgb_to_linear(c: float) -> float:
    return c / 12.92 if c <= 0.04045 else ((c + 0.055) / 1.055) ** 2.4


def material_for(tag: str, colour) -> bpy.types.Material:
    """The material of a part tag, ``procmod <tag>``: reused when the file has one (so a
    restyled material stays), else made in the tag's colour (procmod's palette, sRGB)."""
    name = f"procmod {tag}"
    material = bpy.data.materials.get(name)
    if material is not None:
        return material
    material = bpy.data.materials.new(name)
    rgba = tuple(_srgb_to_linear(c / 255) for c in colour) + (1.0,)
    material.diffuse_color = rgba  # the viewport's solid mode
    material.use_nodes = True
    bsdf = material.node_tree.nodes.get("Principled BSDF")
    if bsdf is not None:
        bsdf.inputs["Base Color"].default_value = rgba
        bsdf.inputs["Roughness"].default_value = 0.7
    return material


def _unit_box():
    vertices = [(x, y, z) for x in (-0.5, 0.5) for y in (-0.5, 0.5) for z in (-0.5, 0.5)]
    faces = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]
    return vertices, faces


def _unit_cylinder(top: float, segments: int = CYLINDER_SEGMENTS):
    """Radius 1 at z = 0 and ``top`` at z = 1 (a cone when ``top`` is 0), closed."""
    ring = [(math.cos(2 * math.pi * i / segments), math.sin(2 * math.pi * i / segments)) for i in range(segments)]
    vertices = [(x, y, 0.0) for x, y in ring]
    if top > 0:
        vertices += [(top * x, top * y, 1.0) for x, y in ring]
        faces = [(i, (i + 1) % segments, segments + (i + 1) % segments, segments + i) for i in range(segments)]
        faces += [tuple(range(segments - 1, -1, -1)), tuple(range(segments, 2 * segments))]
    else:
        vertices.append((0.0, 0.0, 1.0))
        faces = [(i, (i + 1) % segments, segments) for i in range(segments)]
        faces.append(tuple(range(segments - 1, -1, -1)))
    return vertices, faces


def _part_mesh(part: dict, sample: dict, cache: dict, colours: dict) -> tuple:
    """The (shared) mesh data and the matrix (procmod frame) of a part's object.

    A box's size and a cylinder's radius and length are in the mesh data, not in the
    object's scale: an object scaled non-uniformly skews every rotated child it holds, and
    Blender's glTF exporter, whose nodes hold translation, rotation and scale only, then
    writes the children elsewhere (a sampled tree came out a hundred times its size)."""
    kind, tag = part["kind"], part["tag"]
    if kind == "box":
        scale = tuple(float(v) for v in part["size"])
        key, build = ("box", tag, scale), _unit_box
    elif kind == "cylinder":
        radius, length = float(part["radius"]), float(part["length"])
        top = 1.0 if part.get("top_radius") is None else part["top_radius"] / radius
        scale = (radius, radius, length)
        key, build = ("cylinder", tag, round(top, 6), scale), (lambda: _unit_cylinder(top))
    else:
        entry = sample["meshes"][part["mesh"]]
        key = ("mesh", tag, hashlib.sha1(json.dumps(entry).encode()).hexdigest())  # alike across samples
        scale, build = (1.0, 1.0, 1.0), (lambda: (entry["vertices"], entry["faces"]))
    mesh = cache.get(key)  # alike parts (same shape and size) share their mesh
    if mesh is None:
        vertices, faces = build()
        mesh = bpy.data.meshes.new(f"procmod {kind} {tag}")
        mesh.from_pydata([tuple(c * s for c, s in zip(v, scale)) for v in vertices], [], [tuple(f) for f in faces])
        mesh.validate()
        mesh.update()
        mesh.materials.append(material_for(tag, colours.get(tag, (128, 128, 128))))
        cache[key] = mesh
    return mesh, _matrix16(part["transform"])


# How far from square two axes of an object's matrix may be (the sine of the angle) and still
# be written as translation, rotation and scale: procmod.learn.examples.SHEAR_TOLERANCE, the
# learner's own limit (this module holds no library code: the add-on ships without it).
SHEAR_TOLERANCE = 2e-3


def _square_axes(matrix: Matrix, tolerance: float = SHEAR_TOLERANCE) -> bool:
    """True when the axes (columns) of ``matrix``'s 3x3 part are at right angles: it is a
    rotation (or mirror) times a scale along each axis, as a glTF node holds."""
    columns = [matrix.col[i].to_3d() for i in range(3)]
    return all(abs(columns[i].dot(columns[j])) <= tolerance * columns[i].length * columns[j].length
               for i, j in ((0, 1), (0, 2), (1, 2)))


def _unskewed(matrix: Matrix, tolerance: float = 1e-6) -> bool:
    """True when ``matrix``'s 3x3 part is a rotation (or mirror) times one scale: any child,
    however turned, keeps square axes in its frame."""
    lengths = [matrix.col[i].to_3d().length for i in range(3)]
    top = max(lengths)
    return top > 0.0 and all(abs(n - top) <= tolerance * top for n in lengths) and _square_axes(matrix, tolerance)


def build_sample(context, sample: dict, name: str, origin=(0.0, 0.0, 0.0), cache=None):
    """One collection holding a root empty at ``origin`` and an object per part (parented as
    the derivation's calls nest, mesh data shared between alike parts, a material per tag).
    Returns the collection."""
    cache = {} if cache is None else cache
    collection = bpy.data.collections.new(name)
    context.scene.collection.children.link(collection)
    root = bpy.data.objects.new(name, None)
    root.empty_display_type = "PLAIN_AXES"
    root.location = origin
    root["procmod_sample"] = sample.get("label", name)
    collection.objects.link(root)
    root_world = Matrix.Translation(Vector(origin))
    to_blender = Matrix.Scale(1.0 / unit_scale(context), 4) @ TO_BLENDER  # procmod's metres in the scene's units
    objects, worlds, holders = [], [], []
    for part in sample["parts"]:
        mesh, local = _part_mesh(part, sample, cache, sample.get("colours", {}))
        obj = bpy.data.objects.new(f"{part['tag']}", mesh)
        obj["procmod_tag"] = part["tag"]
        obj["procmod_part"] = len(objects)  # the part's index in its derivation's geometry
        collection.objects.link(obj)
        world = root_world @ to_blender @ local
        # under the part of the call that made it, or that part's nearest holder whose frame is
        # not skewed (a learned part scaled unevenly cannot hold turned children: see _part_mesh)
        holder = None if part.get("parent") is None else holders[part["parent"]]
        parent, parent_world = (root, root_world) if holder is None else (objects[holder], worlds[holder])
        obj.parent = parent
        # Keep-transform parenting: the inverse of the parent's world matrix goes in the
        # parent-inverse slot, so the object's own matrix is its world matrix.
        obj.matrix_parent_inverse = parent_world.inverted()
        obj.matrix_basis = world
        holders.append(len(objects) if _unskewed(world) else holder)
        objects.append(obj)
        worlds.append(world)
    return collection


def build_samples(context, samples: list, prefix: str, start=None, gap: float = 1.0) -> list:
    """Collections for several samples, side by side along +x from ``start`` (the 3D cursor)."""
    start = Vector(context.scene.cursor.location) if start is None else Vector(start)
    cache, collections, x = {}, [], 0.0
    scale = unit_scale(context)
    for i, sample in enumerate(samples):
        lo, hi = (np.asarray(b, dtype=np.float64) / scale for b in sample.get("bounds", [[-1, -1, -1], [1, 1, 1]]))
        if i > 0:
            x += -lo[0]  # the sample's left edge touches the gap after the previous one
        origin = start + Vector((x, 0.0, 0.0))
        collections.append(build_sample(context, sample, f"{prefix} {sample.get('label', i)}", origin, cache))
        x += hi[0] + gap * max(hi[0] - lo[0], 1e-3) * 0.25
    return collections


# ---- objects -> files ----------------------------------------------------------------------------

def describe(obj) -> str:
    return f"{obj.name!r} ({obj.type.lower()})"


def instance_hint(obj) -> str:
    """For an empty that instances a collection (Shift+A > Collection Instance, or a linked
    asset): what to do, since its meshes are not objects procmod can read."""
    collection = getattr(obj, "instance_collection", None)
    if obj.type == "EMPTY" and getattr(obj, "instance_type", "") == "COLLECTION" and collection is not None:
        return (f"; it is an instance of collection {collection.name!r}: make its objects real first "
                "(Object > Apply > Make Instances Real)")
    return ""


def check_mesh_object(obj, role: str) -> None:
    if obj is None:
        raise SceneError(f"{role} has no object (was it deleted?): pick a mesh or remove the layer")
    if obj.type not in MESH_TYPES:
        raise SceneError(f"{role} {describe(obj)} is not a mesh: pick a mesh object{instance_hint(obj)}")


def write_obj(path: Path, vertices, triangles) -> None:
    lines = [f"v {x:.9g} {y:.9g} {z:.9g}" for x, y, z in vertices]
    lines += [f"f {a + 1} {b + 1} {c + 1}" for a, b, c in triangles]
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")


def mesh_triangles(mesh) -> tuple:
    """Vertices (local) and triangles of a mesh datablock."""
    mesh.calc_loop_triangles()
    vertices = [tuple(v.co) for v in mesh.vertices]
    triangles = [tuple(t.vertices) for t in mesh.loop_triangles]
    return vertices, triangles


def _world_triangles(evaluated, matrix, vertices: list, triangles: list, scale: float = 1.0) -> None:
    """Append an evaluated object's mesh, placed by ``matrix`` into procmod's frame
    (``scale`` metres per Blender unit)."""
    mesh = evaluated.to_mesh()
    try:
        local, faces = mesh_triangles(mesh)
        offset = len(vertices)
        m = Matrix.Scale(scale, 4) @ TO_PROCMOD @ matrix
        vertices.extend(tuple(m @ Vector(v)) for v in local)
        triangles.extend((a + offset, b + offset, c + offset) for a, b, c in faces)
    finally:
        evaluated.to_mesh_clear()


def write_world_meshes(context, objs: list, paths: list) -> None:
    """Each object's evaluated mesh (modifiers applied) in procmod's world frame, as OBJ at
    its path, with the instances it shows (a Geometry Nodes "Instance on Points",
    instancing by vertices or faces): the target is what the viewport shows. The scene's
    instances are walked once for all the objects (once per object took 40 s for 10,000
    target layers, Blender's UI frozen before the job's progress showed, h91)."""
    depsgraph = context.evaluated_depsgraph_get()
    scale = unit_scale(context)
    # by the object itself: objects of one name from linked libraries are others (h93)
    found = {obj.as_pointer(): ([], [], False) for obj in objs}  # -> vertices, triangles, whether it instances
    for inst in depsgraph.object_instances:  # an instance's object is valid during its step only
        key = inst.parent.original.as_pointer() if inst.is_instance and inst.parent is not None else None
        if key in found:
            vertices, triangles, _ = found[key]
            found[key] = (vertices, triangles, True)
            if inst.object.type in GEOMETRY_TYPES:
                _world_triangles(inst.object, inst.matrix_world, vertices, triangles, scale)
    for obj, path in zip(objs, paths):
        vertices, triangles, instanced = found[obj.as_pointer()]
        vertices, triangles = list(vertices), list(triangles)  # (an object in two layers: its own lists each)
        if not instanced or obj.show_instancer_for_viewport:
            evaluated = obj.evaluated_get(depsgraph)
            _world_triangles(evaluated, evaluated.matrix_world, vertices, triangles, scale)
        if not triangles:
            raise SceneError(f"the mesh of {describe(obj)} has no faces")
        extent = np.ptp(np.asarray(vertices), axis=0)
        if extent.min() <= 1e-9 * max(extent.max(), 1e-300):
            raise SceneError(f"target layer {describe(obj)} is flat, so it has no inside to fill or avoid: give it "
                             "thickness (Solidify) or use another object")
        write_obj(path, vertices, triangles)


def write_world_mesh(context, obj, path: Path) -> None:
    """:func:`write_world_meshes` of one object."""
    write_world_meshes(context, [obj], [path])


def camera_spec(context, camera_obj, width: int, height: int, look_distance: float | None = None) -> dict:
    """A Blender camera as a ``procmod-silhouette/1`` camera seeing ``width`` x ``height`` pixels.

    Blender's camera looks down its local -z with +y up; its field of view spans the larger
    side of the frame (sensor fit Auto) or the side the fit names. ``look_at`` lies on the
    view axis at ``look_distance`` (default: where the axis passes the world origin).
    """
    if camera_obj is None:
        raise SceneError("no camera: set the scene's camera or pick one for the silhouette target")
    if camera_obj.type != "CAMERA":
        raise SceneError(f"the silhouette camera {describe(camera_obj)} is not a camera")
    cam = camera_obj.data
    if cam.type not in ("PERSP", "ORTHO"):
        raise SceneError(f"camera {camera_obj.name!r} is {cam.type.lower()}; use a perspective or orthographic camera")
    if abs(cam.shift_x) > 1e-6 or abs(cam.shift_y) > 1e-6:
        raise SceneError(f"camera {camera_obj.name!r} has a lens shift, which procmod's cameras lack; set it to 0")
    render = context.scene.render
    aspect = (render.resolution_x * render.pixel_aspect_x) / (render.resolution_y * render.pixel_aspect_y)
    if abs(width / height - aspect) > 0.02 * aspect:
        raise SceneError(f"the mask is {width}x{height} pixels but the camera frame (the scene's render size) is "
                         f"{render.resolution_x}x{render.resolution_y}: give the mask the frame's shape "
                         "('New mask' makes one)")
    world = camera_obj.matrix_world.normalized()
    eye = world.translation
    forward = -(world.to_3x3() @ Vector((0, 0, 1))).normalized()
    up = (world.to_3x3() @ Vector((0, 1, 0))).normalized()
    if look_distance is None:
        look_distance = forward.dot(-eye)
        if not look_distance > 1e-3:
            look_distance = 10.0
    look_at = eye + forward * look_distance
    fit = cam.sensor_fit
    horizontal = fit == "HORIZONTAL" or (fit == "AUTO" and aspect >= 1)
    scale = unit_scale(context)
    if cam.type == "ORTHO":
        fov = (cam.ortho_scale / aspect if horizontal else cam.ortho_scale) * scale  # a width, in metres
        projection = "orthographic"
    else:
        sensor = cam.sensor_height if fit == "VERTICAL" else cam.sensor_width
        half = sensor / (2 * cam.lens)  # tan of half the angle across the fitted side
        fov = math.degrees(2 * math.atan(half / aspect if horizontal else half))
        projection = "perspective"
    return {"eye": to_procmod_point(eye, scale), "look_at": to_procmod_point(look_at, scale),
            "up": to_procmod_direction(up),
            "projection": projection, "fov": float(fov)}


def mask_weights(image, hit: float, avoid: float) -> np.ndarray:
    """A mask image as silhouette weights (row 0 at the top): dark = ``hit``, light =
    ``avoid``, mid grey or transparent = don't care (procmod's reading of a picture)."""
    if image is None:
        raise SceneError("no mask image: make one with 'New mask' and paint where the model should be in black")
    width, height = image.size
    if width == 0 or height == 0:
        raise SceneError(f"the mask image {image.name!r} has no pixels (is its file missing?)")
    pixels = np.empty(width * height * 4, dtype=np.float32)
    image.pixels.foreach_get(pixels)
    rgba = pixels.reshape(height, width, 4)[::-1]
    grey = rgba[..., :3].mean(axis=-1)
    weights = np.where(grey < 1 / 3, hit, np.where(grey > 2 / 3, avoid, 0.0))
    weights[rgba[..., 3] < 0.5] = 0.0
    if not (weights > 0).any():
        raise SceneError(f"the mask {image.name!r} has no dark pixel to hit: paint where the model should be in black")
    return weights.astype(np.float64)


def new_mask(context, name: str = "procmod mask", height: int = 128):
    """A white image (all 'avoid') in the shape of the camera frame, to paint into."""
    render = context.scene.render
    aspect = (render.resolution_x * render.pixel_aspect_x) / (render.resolution_y * render.pixel_aspect_y)
    image = bpy.data.images.new(name, width=max(1, round(height * aspect)), height=height, alpha=False)
    image.generated_color = (1.0, 1.0, 1.0, 1.0)
    return image


# ---- example hierarchies -------------------------------------------------------------------------

def _mesh_descendants(obj) -> list:
    """The nearest mesh objects below ``obj`` (through empties and other non-mesh objects)."""
    out = []
    for child in obj.children:
        if child.type in MESH_TYPES:
            out.append(child)
        else:
            out.extend(_mesh_descendants(child))
    return out


def example_roots(selected) -> list:
    """The root part of each selected hierarchy: a selected object under no other selected
    one; an empty stands for the one mesh below it."""
    selected = list(selected)
    if not selected:
        raise SceneError("nothing is selected: select the root object of each example hierarchy")
    chosen = set(selected)
    roots = []
    for obj in selected:
        parent, inside = obj.parent, False
        while parent is not None:
            inside = inside or parent in chosen
            parent = parent.parent
        if inside:
            continue
        if obj.type in MESH_TYPES:
            roots.append(obj)
            continue
        below = _mesh_descendants(obj)
        if len(below) != 1:
            raise SceneError(f"{describe(obj)} is not a mesh and has {len(below)} top-level mesh parts below it; an "
                             "example is one root part with its children: parent the parts under one of them"
                             + instance_hint(obj))
        roots.append(below[0])
    roots.sort(key=lambda o: o.name)
    return roots


def _scale_glb_roots(path: Path, scale: float) -> None:
    """Scale a GLB's scene uniformly by ``scale`` about the origin, in place: each root
    node's transform scaled (Blender's glTF exporter writes Blender units, whatever the
    scene's Unit Scale; the examples then go to procmod in metres, as targets do, so that
    the learned program samples back at the size the examples have in the scene)."""
    if scale == 1.0:
        return
    import struct
    data = path.read_bytes()
    length = struct.unpack("<I", data[12:16])[0]
    header = json.loads(data[20:20 + length])
    rest = data[20 + length:]  # the binary chunk, as it was
    scene = header.get("scenes", [{}])[header.get("scene", 0)]
    for index in scene.get("nodes", []):
        node = header["nodes"][index]
        if "matrix" in node:  # column-major: a uniform scale about the origin scales every entry but the last row
            node["matrix"] = [v * scale if k % 4 != 3 else v for k, v in enumerate(node["matrix"])]
        else:  # T R S: a uniform scale commutes with the turn
            node["translation"] = [v * scale for v in node.get("translation", [0.0, 0.0, 0.0])]
            node["scale"] = [v * scale for v in node.get("scale", [1.0, 1.0, 1.0])]
    text = json.dumps(header).encode("utf-8")
    text += b" " * (-len(text) % 4)
    body = struct.pack("<I4s", len(text), b"JSON") + text + rest
    path.write_bytes(struct.pack("<4sII", b"glTF", 2, 12 + len(body)) + body)


def write_examples(roots, folder: Path) -> tuple:
    """Export each example hierarchy (a root with its descendants) as a GLB file with
    Blender's own glTF exporter into ``folder/examples/``; returns ``(that folder, names
    file)``. ``names.json`` maps each file's name to its root object, so that the
    learner's messages can name the example.

    The files go through the reader ``procmod learn`` uses on exported glTF
    (:mod:`procmod.geometry.assets`), so the add-on learns what a user's export would:
    meshes that are one mesh moved, turned or mirrored are one part; a primitive scaled
    into a seat, a back and legs is three parts, each with its size (an earlier add-on
    wrote its own examples file, in which every unapplied-scale cube of a chair was one
    part type); a symmetric part is placed the least turned way. Modifiers are applied
    (the exporter's "Apply Modifiers"): a part is learned as the viewport shows it, a
    mirrored half with its Mirror modifier whole (the add-on's own file left modifiers
    out). A part hidden in the viewport or made
    unselectable is part of its example all the same (shown for the export, then hidden
    again); one in a collection excluded from the view layer or disabled in viewports
    cannot be exported: that is a :class:`SceneError` saying what to do.
    """
    layer = bpy.context.view_layer
    in_layer = set(layer.objects)  # by identity: a linked object may share a local one's name
    members = []
    for root in roots:
        objects = [o for o in (root, *root.children_recursive) if o.type in MESH_TYPES or o.type == "EMPTY"]
        for obj in objects:  # no lights, cameras or curves as parts
            if obj not in in_layer:
                raise SceneError(f"{describe(obj)}, a part of {describe(root)}'s hierarchy, is in a collection "
                                 "excluded from the view layer, so it cannot be exported with it: include the "
                                 "collection (its checkbox in the Outliner) or unparent the object")
        members.append(objects)
    for objects in members:
        for obj in objects[1:]:  # a root is written in the world frame; its descendants in their parents'
            local = obj.parent.matrix_world.inverted_safe() @ obj.matrix_world
            if not _square_axes(local):
                raise SceneError(f"{describe(obj)} is turned under {describe(obj.parent)}, whose scale is uneven: "
                                 "in its parent's frame its shape is skewed, which a glTF node cannot hold, so the "
                                 f"example would be learned wrong; apply the scale of {obj.parent.name!r} (select "
                                 "it, Object > Apply > Scale) or unparent the object")
    if "gltf" not in dir(bpy.ops.export_scene):
        raise SceneError("Blender's glTF 2.0 exporter is disabled, and learning reads the examples through it: "
                         "enable 'glTF 2.0 format' in Edit > Preferences > Add-ons")
    out = folder / "examples"
    made = not folder.exists()  # a refusal below leaves no folder behind (it had pushed the next run's number up)
    out.mkdir(parents=True, exist_ok=True)
    selected, active = [o for o in layer.objects if o.select_get()], layer.objects.active
    # the exporter leaves edit (or any other) mode for object mode and does not come back
    mode = active.mode if active is not None else "OBJECT"
    hidden = [(o, o.hide_get(), o.hide_viewport, o.hide_select) for objects in members for o in objects]
    names = {}
    try:
        for obj, *_ in hidden:
            obj.hide_viewport = obj.hide_select = False
            obj.hide_set(False)
        for obj, *_ in hidden:
            if not obj.visible_get():  # a collection disabled in viewports (the monitor icon): not exported
                raise SceneError(f"{describe(obj)}, a part of an example, is in a collection disabled in viewports, "
                                 "so it cannot be exported with its hierarchy: enable the collection (its monitor "
                                 "icon in the Outliner) or unparent the object")
        for i, (root, objects) in enumerate(zip(roots, members)):
            for obj in layer.objects:
                obj.select_set(False)
            for obj in objects:
                obj.select_set(True)
            file = out / f"example{i:03d}.glb"
            # loose edges and points exported (as lines and points primitives, which the
            # reader leaves out): by default a mesh without faces became an empty in the
            # file, dropped with no word; now procmod learn's note names it (faceless_note)
            done = bpy.ops.export_scene.gltf(filepath=str(file), use_selection=True, export_format="GLB",
                                             export_apply=True, export_yup=True, export_animations=False,
                                             export_materials="NONE", use_mesh_edges=True, use_mesh_vertices=True,
                                             # as the viewport shows them: by default the exporter went to
                                             # frame 0 first (animated or driven parts learned there)
                                             export_current_frame=True)
            if "FINISHED" not in done or not file.is_file():
                raise SceneError(f"Blender's glTF exporter could not write {describe(root)}'s hierarchy")
            _scale_glb_roots(file, unit_scale())
            names[file.name] = root.name
    except BaseException:
        if made:
            shutil.rmtree(folder, ignore_errors=True)
        raise
    finally:
        for obj, hide, viewport, select in hidden:
            obj.hide_viewport, obj.hide_select = viewport, select
            obj.hide_set(hide)
        for obj in layer.objects:
            obj.select_set(obj in selected)
        layer.objects.active = active
        if active is not None and active.mode != mode:
            try:
                bpy.ops.object.mode_set(mode=mode)
            except RuntimeError:
                pass  # the mode cannot be entered here (nothing to edit): object mode it stays
    (folder / "names.json").write_text(json.dumps(names), encoding="utf-8")
    return out, folder / "names.json"
