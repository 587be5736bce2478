"""The add-on's Blender classes: settings, operators (``bpy.ops.procmod.*``) and the sidebar panel.

Operators that run procmod (``sample``, ``infer``, ``learn``) start a worker process
(:mod:`procmod.blender.jobs`). Invoked from the UI they are modal: a timer polls the worker,
the panel shows a progress bar and a Stop button, and the scene gets the objects when the
job ends. Called from a script or in background mode (``bpy.ops.procmod.sample()``), they
wait for the worker and return when the objects are in the scene. A problem in the scene
or the settings is reported in one line (an operator error; from a script, a
``RuntimeError`` with that line), never a traceback.
"""

from __future__ import annotations

import atexit
import tempfile
import time
import traceback
from pathlib import Path

import bpy
import numpy as np
from bpy.props import (BoolProperty, CollectionProperty, EnumProperty, FloatProperty, IntProperty, PointerProperty,
                       StringProperty)

from . import jobs, scene
from .scene import SceneError

ADDON = __package__  # "procmod.blender" (installed with procmod) or "procmod_blender" (the add-on zip)
MODELS = (("spaceship", "Spaceship", "seed 002's spaceship generator"),
          ("tree", "Tree", "seed 002's tree generator"),
          ("city", "City", "seed 002's city generator"),
          ("PROGRAM", "Learned program", "a program made by 'Learn' or 'procmod learn' (program.json)"))
# The target files' limit on a weight (procmod.targets.files.MAX_WEIGHT: the zip holds no
# library code; a test holds them equal). Blender clamps a field to it, an "inf" typed too.
MAX_WEIGHT = 1e6
ENGINES = (("ga", "GA", "genetic algorithm over derivation trees"), ("smc", "SMC", "sequential Monte Carlo"),
           ("sosmc", "SOSMC", "stochastically-ordered SMC"), ("mcmc", "MCMC", "reversible-jump MCMC, tempered"),
           ("forward", "Forward", "importance sampling from the prior"))


def _redraw(context) -> None:
    wm = context.window_manager
    for window in getattr(wm, "windows", ()):
        for area in window.screen.areas:
            area.tag_redraw()


# ---- settings --------------------------------------------------------------------------------------

def _is_mesh(self, obj) -> bool:
    return obj.type == "MESH"


def _is_camera(self, obj) -> bool:
    return obj.type == "CAMERA"


class PROCMOD_PG_layer(bpy.types.PropertyGroup):
    """One layer of a volume target: a mesh and its weights (seed 002 s s_vol)."""

    object: PointerProperty(name="Object", type=bpy.types.Object, poll=_is_mesh,
                            description="a mesh whose inside is the layer (holes and overlaps are fine)")
    w_fill: FloatProperty(name="Inside", default=1.0, min=-MAX_WEIGHT, max=MAX_WEIGHT,
                          description="score per voxel the model covers inside the mesh")
    w_avoid: FloatProperty(name="Outside", default=-1.0, min=-MAX_WEIGHT, max=MAX_WEIGHT,
                           description="score per voxel the model covers outside the mesh")


class PROCMOD_PG_settings(bpy.types.PropertyGroup):
    """procmod's settings of a scene (saved with the .blend file)."""

    model: EnumProperty(name="Model", items=MODELS, default="spaceship")
    program: StringProperty(name="Program", subtype="FILE_PATH",
                            description="a learned program: program.json or its folder")
    seed: IntProperty(name="Seed", default=0, min=0, description="sample i depends only on (seed, i)")
    count: IntProperty(name="Samples", default=4, min=1, max=1000)
    target_kind: EnumProperty(name="Target", items=(
        ("VOLUME", "Volume", "fill and avoid the insides of scene meshes"),
        ("SILHOUETTE", "Silhouette", "match a mask painted over a camera's view")), default="VOLUME")
    layers: CollectionProperty(type=PROCMOD_PG_layer)
    layer_index: IntProperty()
    voxel_size: FloatProperty(name="Voxel size", default=0.0, min=0.0, precision=3,
                              description="edge of the target's voxels (0: about 40,000 voxels around the layers)")
    w_self: FloatProperty(name="Self-intersection", default=0.0, min=0.0, max=MAX_WEIGHT,
                          description="score lost per extra hit of a voxel the model covers twice")
    camera: PointerProperty(name="Camera", type=bpy.types.Object, poll=_is_camera,
                            description="the silhouette target's camera (empty: the scene's camera)")
    mask: PointerProperty(name="Mask", type=bpy.types.Image,
                          description="black: where the model should be; white: where it should not; grey: either")
    hit: FloatProperty(name="Hit", default=1.0, min=-MAX_WEIGHT, max=MAX_WEIGHT,
                       description="score per covered black pixel")
    avoid: FloatProperty(name="Avoid", default=-1.0, min=-MAX_WEIGHT, max=MAX_WEIGHT,
                         description="score per covered white pixel")
    engine: EnumProperty(name="Engine", items=ENGINES, default="ga")
    population: IntProperty(name="Population", default=0, min=0,
                            description="particles, population or chains (0: the engine's default)")
    budget: StringProperty(name="Budget", default="20s", description="30s, 2m, 5000evals, 100gens; empty: the "
                                                                     "engine's default")
    output_dir: StringProperty(name="Runs", default="//procmod", subtype="DIR_PATH",
                               description="where run and learn folders go (// is the .blend file's folder)")
    learn_particles: IntProperty(name="Searches", default=2, min=1, max=64,
                                 description="parallel structure searches of the learner")


class PROCMOD_PG_status(bpy.types.PropertyGroup):
    """The running job, for the panel (not saved)."""

    running: BoolProperty()
    fraction: FloatProperty(min=0.0, max=1.0)
    message: StringProperty()
    report: StringProperty(subtype="FILE_PATH")


class PROCMOD_AP_preferences(bpy.types.AddonPreferences):
    bl_idname = ADDON

    python: StringProperty(
        name="Python", subtype="FILE_PATH",
        description="the python of an environment where procmod is installed (empty: $PROCMOD_PYTHON, else the "
                    "one the add-on was packaged with, else Blender's own)")

    def draw(self, context):
        self.layout.prop(self, "python")
        self.layout.label(text=f"Jobs run with: {_find_python(self.python)}")


def _find_python(preference: str) -> str:
    # the file browser writes "//..." (relative to the .blend) for a file path
    return jobs.find_python(bpy.path.abspath(preference.strip()) if preference.strip() else "")


def _python(context) -> str:
    addon = context.preferences.addons.get(ADDON)
    return _find_python(addon.preferences.python if addon is not None else "")


def _output_dir(settings) -> Path:
    """The panel's Runs folder, made if it is not there (a SceneError if it cannot be)."""
    text = settings.output_dir or "//procmod"
    if text.startswith("//") and not bpy.data.filepath:
        folder = Path(tempfile.gettempdir()) / "procmod" / text[2:]
    else:
        # made absolute here: a path relative to Blender's working folder ("my_runs") was taken
        # relative to the job's temporary folder by the worker, and removed with it
        folder = Path(bpy.path.abspath(text)).expanduser().resolve()
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as exc:  # a file of that name, a folder one may not write, a read-only disk
        reason = ("it or a folder above it is a file" if isinstance(exc, (FileExistsError, NotADirectoryError))
                  else exc.strerror or type(exc).__name__)
        raise SceneError(f"cannot use {str(folder)!r} as the Runs folder ({reason}): choose another folder in the "
                         "panel's Runs field") from None
    return folder


def _next_folder(base: Path, stem: str) -> Path:
    i = 1
    while any((base / f"{stem}-{i:03d}{kept}").exists() for kept in ("", ".target", ".examples")):
        i += 1
    return base / f"{stem}-{i:03d}"


def _model_spec(settings) -> str:
    if settings.model != "PROGRAM":
        return settings.model
    if not settings.program.strip():
        raise SceneError("choose the learned program (its program.json or folder), or a built-in model")
    # made absolute here, as the Runs folder is: the worker runs in the job's temporary folder
    path = Path(bpy.path.abspath(settings.program.strip())).expanduser().resolve()
    if path.is_dir():
        path = path / "program.json"  # the collections are named after the program's folder
    if not path.exists():
        hint = (" (a path starting // is relative to the saved .blend file; save it, or give the full path)"
                if settings.program.strip().startswith("//") and not bpy.data.filepath else "")
        raise SceneError(f"the learned program {str(path)!r} does not exist{hint}")
    return str(path)


# ---- running jobs -----------------------------------------------------------------------------------

class Runner:
    """A started job and what to do with its result; :meth:`tick` never blocks."""

    active = None  # the one running Runner (one job at a time)

    def __init__(self, job: jobs.Job, on_result):
        self.job, self.on_result = job, on_result

    def tick(self, context) -> bool:
        """Read the worker's progress into the panel; True once the job has ended."""
        done = self.job.poll()
        status = context.window_manager.procmod_status
        status.running = not done
        status.fraction = self.job.fraction or 0.0
        status.message = (f"{self.job.message} ({self.job.seconds:.0f} s)" if not done else status.message)
        _redraw(context)
        return done

    def finish(self, context, operator) -> set:
        """Put the result into the scene and report one line."""
        if Runner.active is self:
            Runner.active = None
        result = self.job.result or {"ok": False, "error": "no result"}
        status = context.window_manager.procmod_status
        status.running, status.fraction = False, 0.0
        if not result.get("ok"):
            status.message = result.get("error", "failed")
            if result.get("user_error") or result.get("cancelled"):
                self.job.cleanup()  # kept only when its worker.log may explain a failure
            operator.report({"WARNING"} if result.get("cancelled") else {"ERROR"}, status.message)
            return {"CANCELLED"}
        try:
            message = self.on_result(context, result)
        except SceneError as exc:
            self.job.cleanup()
            operator.report({"ERROR"}, str(exc))
            return {"CANCELLED"}
        self.job.cleanup()
        status.message = message
        status.report = result.get("report", status.report)
        operator.report({"INFO"}, message)
        _redraw(context)
        return {"FINISHED"}


def _repeated(operator, context) -> bool:
    """Whether Blender runs ``operator`` again: Repeat Last (Shift+R) and Repeat History call
    execute, which waits for the job, so Blender would be frozen for the whole run with no
    progress and no Stop. ``is_repeat`` alone also holds for a script's call after a panel
    press of the same operator (Blender compares the type with the last registered
    operator's; h137): a repeat runs the registered operator itself. (The job operators are
    not registered, so neither can happen; this guards a change of that.)"""
    if not operator.is_repeat():
        return False
    pointer = operator.as_pointer()
    return any(done.as_pointer() == pointer for done in context.window_manager.operators)


def _end_unread(job: jobs.Job) -> None:
    """Poll a stopped job no operator reads any more until it ends (killing it if it outlasts
    :data:`~procmod.blender.jobs.KILL_AFTER_STOP`), then remove its temporary folder: a
    persistent timer, which outlives the file load that cancelled the operator."""
    def poll():
        if not job.poll():
            return 0.5
        job.cleanup()
        return None

    bpy.app.timers.register(poll, first_interval=0.5, persistent=True)


class _JobOperator:
    """Shared by the operators that run a worker: :meth:`prepare` writes the job's files and
    returns ``(spec, on_result)``."""

    command = ""
    _timer = None
    _runner = None  # this operator's job: its timer reads only it (another may be active)

    def _start(self, context):
        if Runner.active is not None and not Runner.active.job.done:
            self.report({"ERROR"}, "a procmod job is running: wait for it or stop it first")
            return None
        job = jobs.Job(self.command, {}, _python(context))
        try:
            # a mesh being edited keeps its edits in edit mode's copy until it is left: the
            # job reads the mesh data, so write the edits there first (the user stays in
            # edit mode)
            for obj in getattr(context, "objects_in_mode", None) or ():
                if obj.mode == "EDIT":
                    obj.update_from_editmode()
            spec, on_result = self.prepare(context, job.folder)
        except SceneError as exc:
            self.report({"ERROR"}, str(exc))
            job.kill()
            job.cleanup()
            return None
        except Exception as exc:  # a bug: one line here, the traceback on the console
            traceback.print_exc()
            self.report({"ERROR"}, f"procmod: internal error ({type(exc).__name__}: {exc})")
            job.kill()
            job.cleanup()
            return None
        job.spec.update(spec)
        job.start()
        Runner.active = self._runner = Runner(job, on_result)
        status = context.window_manager.procmod_status
        status.running, status.fraction, status.message = True, 0.0, f"{self.command}: starting"
        return Runner.active

    def execute(self, context):
        if _repeated(self, context):
            self.report({"WARNING"}, f"procmod: press '{self.bl_label}' in the procmod panel to run it again (a "
                                     "repeated run would freeze Blender until it ended)")
            return {"CANCELLED"}
        runner = self._start(context)
        if runner is None:
            return {"CANCELLED"}
        while not runner.tick(context):
            time.sleep(0.05)
        return runner.finish(context, self)

    def invoke(self, context, event):
        if context.window is None:  # no event loop (background mode): wait instead
            return self.execute(context)
        runner = self._start(context)
        if runner is None:
            return {"CANCELLED"}
        wm = context.window_manager
        self._timer = wm.event_timer_add(0.25, window=context.window)
        wm.modal_handler_add(self)
        return {"RUNNING_MODAL"}

    def modal(self, context, event):
        if event.type != "TIMER":
            return {"PASS_THROUGH"}
        runner = self._runner
        if runner is None or not runner.tick(context):
            return {"PASS_THROUGH"}
        context.window_manager.event_timer_remove(self._timer)
        return runner.finish(context, self)

    def cancel(self, context):
        """Blender ends the modal run without a result: a file was opened or a new one made (their
        load removes every modal handler), or the window closed. Without this the job was read by
        no one and stayed 'running': every later job was refused until Blender restarted. A
        control run is stopped (the engine still writes its run, with its best so far, to the Runs
        folder); sampling and learning end at once."""
        if self._timer is not None:
            try:
                context.window_manager.event_timer_remove(self._timer)
            except (ReferenceError, RuntimeError, AttributeError):
                pass  # the window manager went with the old file
            self._timer = None
        runner, self._runner = self._runner, None
        if runner is None:
            return
        if Runner.active is runner:
            Runner.active = None
        if not runner.job.done:  # (a job Stop ended, not yet read by the timer, only needs its folder removed)
            if runner.job.command == "infer":
                runner.job.stop()
                _end_unread(runner.job)
            else:
                runner.job.kill()
        if runner.job.done:
            runner.job.cleanup()
        try:
            status = context.window_manager.procmod_status
            status.running, status.fraction = False, 0.0
            status.message = f"{runner.job.command}: cancelled (a file was opened or the window closed)"
        except (ReferenceError, AttributeError):
            pass


class PROCMOD_OT_sample(_JobOperator, bpy.types.Operator):
    """Sample the model into the scene: a collection per sample, an object per part"""

    bl_idname = "procmod.sample"
    bl_label = "Sample"
    bl_options = {"UNDO"}  # not REGISTER: Repeat Last would rerun it frozen
    command = "sample"

    def prepare(self, context, folder):
        settings = context.scene.procmod
        model = _model_spec(settings)
        spec = {"model": model, "count": settings.count, "seed": settings.seed}
        name = Path(model).parent.name if settings.model == "PROGRAM" else model

        def on_result(context, result):
            scene.build_samples(context, result["samples"], f"procmod {name}")
            return result["message"]

        return spec, on_result


def _target_spec(context, settings, folder: Path) -> dict:
    if settings.target_kind == "VOLUME":
        if len(settings.layers) == 0:
            raise SceneError("the volume target has no layers: select meshes and press 'Fill' or 'Avoid'")
        layers = []
        for i, layer in enumerate(settings.layers):
            scene.check_mesh_object(layer.object, f"target layer {i + 1}")
            layers.append({"mesh": f"layer{i}.obj", "object": layer.object.name, "w_fill": layer.w_fill,
                           "w_avoid": layer.w_avoid})
        scene.write_world_meshes(context, [layer.object for layer in settings.layers],
                                 [folder / entry["mesh"] for entry in layers])
        return {"kind": "volume", "layers": layers, "voxel_size": settings.voxel_size * scene.unit_scale(context),
                "w_self": settings.w_self}
    camera = settings.camera or context.scene.camera
    weights = scene.mask_weights(settings.mask, settings.hit, settings.avoid)
    spec = scene.camera_spec(context, camera, weights.shape[1], weights.shape[0])
    np.save(folder / "view0.npy", weights)
    return {"kind": "silhouette", "views": [{"weights": "view0.npy", "camera": spec}]}


class PROCMOD_OT_infer(_JobOperator, bpy.types.Operator):
    """Control the model toward the target with the engine; the best result becomes objects
    and the run folder holds what 'procmod infer' writes"""

    bl_idname = "procmod.infer"
    bl_label = "Control"
    bl_options = {"UNDO"}  # not REGISTER: Repeat Last would rerun it frozen
    command = "infer"

    def prepare(self, context, folder):
        settings = context.scene.procmod
        model = _model_spec(settings)
        target = _target_spec(context, settings, folder)
        out = _next_folder(_output_dir(settings), f"infer-{settings.engine}")
        spec = {"model": model, "target": target, "engine": settings.engine, "seed": settings.seed,
                "budget": settings.budget.strip(), "out": str(out), "target_folder": str(out) + ".target"}
        if settings.population > 0:
            spec["population"] = settings.population

        def on_result(context, result):
            scene.build_samples(context, result["samples"], "procmod", start=(0.0, 0.0, 0.0))
            return result["message"]

        return spec, on_result


class PROCMOD_OT_learn(_JobOperator, bpy.types.Operator):
    """Learn a program from the selected hierarchies (each selected root with its children is an
    example; meshes alike up to a move, turn, mirror or scale are one part) and sample it into the scene"""

    bl_idname = "procmod.learn"
    bl_label = "Learn from selection"
    bl_options = {"UNDO"}  # not REGISTER: Repeat Last would rerun it frozen
    command = "learn"

    def prepare(self, context, folder):
        settings = context.scene.procmod
        roots = scene.example_roots(context.selected_objects)
        out = _next_folder(_output_dir(settings), "learn")
        # kept beside the learn folder, as an infer run's target is: the program names its
        # examples (a job's temporary folder had been named, and deleted with the job)
        examples, names = scene.write_examples(roots, Path(f"{out}.examples"))
        spec = {"examples": str(examples), "names": str(names), "n_examples": len(roots), "out": str(out),
                "prepared_folder": f"{out}.examples",  # a learn that ends without a program removes it
                "particles": settings.learn_particles, "workers": 1, "seed": settings.seed, "count": settings.count}

        def on_result(context, result):
            # the scene's settings read again, not the ones above: an undo while the job ran
            # re-reads the scene, and a kept reference to its data then points at freed memory
            settings = context.scene.procmod
            settings.program = result["program"]
            settings.model = "PROGRAM"
            scene.build_samples(context, result["samples"], f"procmod {out.name}")
            return result["message"]

        return spec, on_result


class PROCMOD_OT_stop(bpy.types.Operator):
    """Stop the running job: an engine ends early and keeps its best result; sampling and learning end at once"""

    bl_idname = "procmod.stop"
    bl_label = "Stop"

    def execute(self, context):
        runner = Runner.active
        if runner is None or runner.job.done:
            self.report({"WARNING"}, "no procmod job is running")
            return {"CANCELLED"}
        runner.job.stop()
        context.window_manager.procmod_status.message = "stopping..."
        return {"FINISHED"}


class PROCMOD_OT_add_layers(bpy.types.Operator):
    """Add the selected meshes to the volume target"""

    bl_idname = "procmod.add_layers"
    bl_label = "Add target layers"
    bl_options = {"REGISTER", "UNDO"}

    role: EnumProperty(items=(("FILL", "Fill", "the model should fill the mesh (inside 1, outside -1)"),
                              ("AVOID", "Avoid", "the model should stay out of the mesh (inside -2, outside 0)")))

    def execute(self, context):
        selected = list(context.selected_objects)
        if not selected:
            self.report({"ERROR"}, "nothing is selected: select the target meshes first")
            return {"CANCELLED"}
        for obj in selected:
            if obj.type != "MESH":
                self.report({"ERROR"}, f"{scene.describe(obj)} is not a mesh: a target layer is a mesh object"
                                       + scene.instance_hint(obj))
                return {"CANCELLED"}
        settings = context.scene.procmod
        for obj in selected:
            layer = settings.layers.add()
            layer.object = obj
            layer.w_fill, layer.w_avoid = (1.0, -1.0) if self.role == "FILL" else (-2.0, 0.0)
        settings.layer_index = len(settings.layers) - 1
        return {"FINISHED"}


class PROCMOD_OT_remove_layer(bpy.types.Operator):
    """Remove the chosen layer from the volume target"""

    bl_idname = "procmod.remove_layer"
    bl_label = "Remove target layer"
    bl_options = {"REGISTER", "UNDO"}

    def execute(self, context):
        settings = context.scene.procmod
        if not 0 <= settings.layer_index < len(settings.layers):
            self.report({"ERROR"}, "no target layer is chosen")
            return {"CANCELLED"}
        settings.layers.remove(settings.layer_index)
        settings.layer_index = max(0, settings.layer_index - 1)
        return {"FINISHED"}


class PROCMOD_OT_new_mask(bpy.types.Operator):
    """A white image in the camera frame's shape to paint the silhouette target into (black: hit)"""

    bl_idname = "procmod.new_mask"
    bl_label = "New mask"
    bl_options = {"REGISTER", "UNDO"}

    def execute(self, context):
        context.scene.procmod.mask = scene.new_mask(context)
        return {"FINISHED"}


class PROCMOD_OT_open_report(bpy.types.Operator):
    """Open the last run's report in the web browser (orbitable 3D view)"""

    bl_idname = "procmod.open_report"
    bl_label = "Open report"

    def execute(self, context):
        report = context.window_manager.procmod_status.report
        if not report or not Path(report).exists():
            self.report({"ERROR"}, "no report yet: run Control or Learn first")
            return {"CANCELLED"}
        bpy.ops.wm.url_open(url=Path(report).resolve().as_uri())
        return {"FINISHED"}


# ---- panel ---------------------------------------------------------------------------------------------

class PROCMOD_UL_layers(bpy.types.UIList):
    def draw_item(self, context, layout, data, item, icon, active_data, active_propname, index):
        row = layout.row(align=True)
        row.prop(item, "object", text="", emboss=False, icon="MESH_DATA")
        row.prop(item, "w_fill", text="in")
        row.prop(item, "w_avoid", text="out")


class PROCMOD_PT_panel(bpy.types.Panel):
    bl_label = "procmod"
    bl_idname = "PROCMOD_PT_panel"
    bl_space_type = "VIEW_3D"
    bl_region_type = "UI"
    bl_category = "procmod"

    def draw(self, context):
        settings = context.scene.procmod
        status = context.window_manager.procmod_status
        layout = self.layout
        col = layout.column()
        col.prop(settings, "model")
        if settings.model == "PROGRAM":
            col.prop(settings, "program")
        row = col.row(align=True)
        row.prop(settings, "seed")
        row.prop(settings, "count")
        col.operator("procmod.sample", icon="MESH_CUBE")

        box = layout.box()
        box.label(text="Control", icon="TRACKING")
        box.prop(settings, "target_kind", expand=True)
        if settings.target_kind == "VOLUME":
            box.template_list("PROCMOD_UL_layers", "", settings, "layers", settings, "layer_index", rows=2)
            row = box.row(align=True)
            row.operator("procmod.add_layers", text="Fill").role = "FILL"
            row.operator("procmod.add_layers", text="Avoid").role = "AVOID"
            row.operator("procmod.remove_layer", text="", icon="REMOVE")
            row = box.row(align=True)
            row.prop(settings, "voxel_size")
            row.prop(settings, "w_self")
        else:
            box.prop(settings, "camera")
            row = box.row(align=True)
            row.prop(settings, "mask")
            row.operator("procmod.new_mask", text="", icon="ADD")
            row = box.row(align=True)
            row.prop(settings, "hit")
            row.prop(settings, "avoid")
        row = box.row(align=True)
        row.prop(settings, "engine", text="")
        row.prop(settings, "population")
        box.prop(settings, "budget")
        box.prop(settings, "output_dir")
        box.operator("procmod.infer", icon="PLAY")

        box = layout.box()
        box.label(text="Learn", icon="OUTLINER_OB_GROUP_INSTANCE")
        box.prop(settings, "learn_particles")
        box.operator("procmod.learn", icon="EXPERIMENTAL")

        if status.running:
            layout.progress(factor=status.fraction, type="BAR", text=status.message or "running")
            layout.operator("procmod.stop", icon="CANCEL")
        elif status.message:
            layout.label(text=status.message)
        if status.report:
            layout.operator("procmod.open_report", icon="URL")


CLASSES = (PROCMOD_PG_layer, PROCMOD_PG_settings, PROCMOD_PG_status, PROCMOD_AP_preferences, PROCMOD_OT_sample,
           PROCMOD_OT_infer, PROCMOD_OT_learn, PROCMOD_OT_stop, PROCMOD_OT_add_layers, PROCMOD_OT_remove_layer,
           PROCMOD_OT_new_mask, PROCMOD_OT_open_report, PROCMOD_UL_layers, PROCMOD_PT_panel)


_exit_hook = []  # the atexit hook, once added


def register() -> None:
    for cls in CLASSES:
        bpy.utils.register_class(cls)
    bpy.types.Scene.procmod = PointerProperty(type=PROCMOD_PG_settings)
    bpy.types.WindowManager.procmod_status = PointerProperty(type=PROCMOD_PG_status)
    # Blender as a Python module (the bpy wheel: no binary) never exits while an operator
    # class is still registered: a script that registered the add-on and did not unregister
    # it hung at its end. Blender itself unregisters add-ons when it quits.
    if not bpy.app.binary_path and not _exit_hook:
        _exit_hook.append(atexit.register(_unregister_at_exit))


def _unregister_at_exit() -> None:
    if hasattr(bpy.types.Scene, "procmod"):
        unregister()


def unregister() -> None:
    # once only: a script that enabled the zip with addon_utils has it unregistered both by
    # the exit hook above and by Blender's add-on shutdown (a traceback at every exit)
    if not hasattr(bpy.types.WindowManager, "procmod_status"):
        return
    runner = Runner.active
    if runner is not None:
        runner.job.kill()
        Runner.active = None
    del bpy.types.WindowManager.procmod_status
    del bpy.types.Scene.procmod
    for cls in reversed(CLASSES):
        bpy.utils.unregister_class(cls)
