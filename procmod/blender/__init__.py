"""procmod inside Blender: an add-on that samples, controls and learns procedural models.

Install (Blender 4.2 to 4.5 LTS): in procmod's environment run ::

    python -m procmod.blender.package --out procmod_blender.zip

then in Blender, Edit > Preferences > Add-ons > (the arrow at the top right) > Install from
Disk..., pick the zip and tick "procmod". The add-on runs its jobs with the Python that
made the zip (change it in the add-on's preferences). Its panel is in the 3D Viewport's
sidebar (N), tab "procmod"; the operators are ``bpy.ops.procmod.sample``, ``.infer``,
``.learn``, ``.stop``, ``.add_layers``, ``.remove_layer``, ``.new_mask`` and ``.open_report``.

Only the Blender side lives in Blender: :mod:`.addon` (settings, operators, panel) and
:mod:`.scene` (objects to and from procmod's files). procmod itself runs in a worker
process (:mod:`.worker`, started by :mod:`.jobs`), so Blender's UI stays live, a job can
be stopped, and procmod's dependencies (numba, torch, ...) need not be installed into
Blender's Python. This module imports no bpy until :func:`register`, so ``import procmod``
and the worker never need Blender.
"""

bl_info = {
    "name": "procmod",
    "author": "procmod",
    "version": (0, 1, 0),
    "blender": (4, 2, 0),
    "location": "3D Viewport > Sidebar > procmod",
    "description": "Sample, control toward targets and learn probabilistic procedural models",
    "category": "Add Mesh",
}


def register() -> None:
    """Register the add-on's classes (Blender calls this when the add-on is enabled)."""
    from . import addon
    addon.register()


def unregister() -> None:
    """Unregister them again."""
    from . import addon
    addon.unregister()
