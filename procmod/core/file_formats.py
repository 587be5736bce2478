"""Files of other 3D tools that procmod does not read, and what to export instead.

procmod reads meshes through trimesh (OBJ, STL, PLY, OFF, glTF / GLB, COLLADA) and part
hierarchies from glTF / GLB and URDF. The tools' own scene formats (FBX, Maya, Blender,
3ds Max, USD, Alembic, ...) have no maintained reader that installs with pip alone, so a
file in one is refused, and the message says how to get a file procmod reads: every such
tool exports glTF or OBJ, and Blender imports most of them (FBX, USD, Alembic, 3DS) and
exports glTF 2.0.
"""

from __future__ import annotations

import os
from pathlib import Path

# suffix -> what the file is, as its user would name it
OTHER_TOOL_FORMATS = {
    ".fbx": "an Autodesk FBX file",
    ".ma": "a Maya scene",
    ".mb": "a Maya scene",
    ".blend": "a Blender file",
    ".max": "a 3ds Max scene",
    ".3ds": "a 3DS file",
    ".c4d": "a Cinema 4D scene",
    ".hip": "a Houdini scene",
    ".hipnc": "a Houdini scene",
    ".usd": "a USD file",
    ".usda": "a USD file",
    ".usdc": "a USD file",
    ".usdz": "a USD file",
    ".abc": "an Alembic file",
    ".skp": "a SketchUp model",
    ".3mf": "a 3MF file",
    ".x3d": "an X3D file",
    ".wrl": "a VRML file",
    ".step": "a CAD (STEP) file",
    ".stp": "a CAD (STEP) file",
    ".iges": "a CAD (IGES) file",
    ".igs": "a CAD (IGES) file",
}

# what the user's tool does with each: Blender imports these itself
_BLENDER_IMPORTS = {".fbx", ".3ds", ".usd", ".usda", ".usdc", ".usdz", ".abc", ".x3d", ".wrl", ".3mf"}

# mesh files procmod reads as one mesh, which hold no parts' placements
_FLAT_MESHES = {".obj": "an OBJ", ".stl": "an STL", ".ply": "a PLY", ".off": "an OFF"}


def conversion_hint(path: str | os.PathLike, hierarchy: bool = False) -> str:
    """A sentence for an error message about a file procmod does not read, saying what it
    is and what to export instead; ``""`` for a suffix no 3D tool is known to write.

    ``hierarchy``: the file was given where parts and their placements are read (``learn``,
    ``strings``), so the advice is glTF (an OBJ or STL keeps no part hierarchy).
    """
    suffix = Path(path).suffix.lower()
    what = OTHER_TOOL_FORMATS.get(suffix)
    wanted = "glTF 2.0 (.glb)" if hierarchy else "glTF 2.0 (.glb) or OBJ"
    if what is None:
        if hierarchy and suffix in _FLAT_MESHES:
            return (f"{_FLAT_MESHES[suffix]} file keeps no part hierarchy; export the parts as glTF 2.0 "
                    "(.glb), which keeps each part's transform")
        if hierarchy and suffix == ".dae":
            return "parts and their placements are read from glTF and URDF; export the scene as glTF 2.0 (.glb)"
        return ""
    if suffix in _BLENDER_IMPORTS:
        how = f"export it from its tool as {wanted}, or import it into Blender (File > Import) and export it from there"
    elif suffix == ".blend":
        how = f"in Blender, File > Export > {wanted}"
    else:
        how = f"export it from its tool as {wanted}"
    return f"{what} is not read by procmod; {how}"


__all__ = ["OTHER_TOOL_FORMATS", "conversion_hint"]
