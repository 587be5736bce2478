"""Files of other 3D tools that procmod does not read, and what to export instead.

procmod reads meshes through trimesh (OBJ, STL, PLY, OFF, glTF / GLB, COLLADA) and part
hierarchies from glTF / GLB and URDF. The tools' own scene formats (FBX, Maya, Blender,
3ds Max, USD, Alembic, ...) have no maintained reader that installs with pip alone, so a
file in one is refused, and the message says how to get a file procmod reads: from the
tool itself where it exports glTF or OBJ, else through Blender, which imports FBX, USD,
Alembic and COLLADA and exports glTF 2.0 (Maya and 3ds Max export glTF only through
plug-ins, so their route is FBX, then Blender; SketchUp's is COLLADA).
"""

from __future__ import annotations

import os
from pathlib import Path

# suffix -> (what the file is, as its user would name it; how to get a file procmod reads)
#   "blender": Blender imports it (File > Import) and exports glTF;
#   "native": its tool exports glTF (and OBJ) itself;
#   "via_fbx": its tool exports FBX, which Blender converts (Maya and 3ds Max export glTF
#     only through plug-ins);
#   "via_dae": its tool exports COLLADA, a mesh procmod reads, which Blender converts;
#   "mesh_tool": a CAD or exchange format: a conversion in a tool that reads it;
#   "xacro": a URDF with macros, which ROS's xacro expands.
OTHER_TOOL_FORMATS = {
    ".fbx": ("an Autodesk FBX file", "blender"),
    ".ma": ("a Maya scene", "via_fbx"),
    ".mb": ("a Maya scene", "via_fbx"),
    ".max": ("a 3ds Max scene", "via_fbx"),
    ".blend": ("a Blender file", "native"),
    ".c4d": ("a Cinema 4D scene", "native"),
    ".hip": ("a Houdini scene", "native"),
    ".hipnc": ("a Houdini scene", "native"),
    ".usd": ("a USD file", "blender"),
    ".usda": ("a USD file", "blender"),
    ".usdc": ("a USD file", "blender"),
    ".usdz": ("a USD file", "blender"),
    ".abc": ("an Alembic file", "blender"),
    ".skp": ("a SketchUp model", "via_dae"),
    ".3ds": ("a 3DS file", "mesh_tool"),
    ".x3d": ("an X3D file", "mesh_tool"),
    ".wrl": ("a VRML file", "mesh_tool"),
    ".step": ("a CAD (STEP) file", "mesh_tool"),
    ".stp": ("a CAD (STEP) file", "mesh_tool"),
    ".iges": ("a CAD (IGES) file", "mesh_tool"),
    ".igs": ("a CAD (IGES) file", "mesh_tool"),
    ".3mf": ("a 3MF file (a slicer's or Fusion 360's)", "mesh_tool"),
    ".3dm": ("a Rhino model", "native"),
    ".xacro": ("a xacro file (a URDF written with macros)", "xacro"),
}

XACRO_COMMAND = "ROS: xacro robot.urdf.xacro > robot.urdf"

# mesh files procmod reads as one mesh, which hold no parts' placements
_FLAT_MESHES = {".obj": "an OBJ", ".stl": "an STL", ".ply": "a PLY", ".off": "an OFF"}


def conversion_hint(path: str | os.PathLike, hierarchy: bool = False) -> str:
    """A sentence for an error message about a file procmod does not read, saying what it
    is and what to export instead; ``""`` for a suffix no 3D tool is known to write.

    ``hierarchy``: the file was given where parts and their placements are read (``learn``,
    ``strings``), so the advice is glTF (an OBJ or STL keeps no part hierarchy).
    """
    suffix = Path(path).suffix.lower()
    if suffix not in OTHER_TOOL_FORMATS:
        if hierarchy and suffix in _FLAT_MESHES:
            return (f"{_FLAT_MESHES[suffix]} file keeps no part hierarchy; export the parts as glTF 2.0 "
                    "(.glb), which keeps each part's transform")
        if hierarchy and suffix == ".dae":
            return ("parts and their placements are read from glTF and URDF; import the COLLADA file into Blender "
                    "(File > Import) and export glTF 2.0 (.glb)")
        return ""
    what, route = OTHER_TOOL_FORMATS[suffix]
    wanted = "glTF 2.0 (.glb)" if hierarchy else "glTF 2.0 (.glb) or OBJ"
    how = {
        "blender": f"export {wanted} from its tool, or import it into Blender (File > Import) and export {wanted} "
                   "from there",
        "native": f"export it from its tool as {wanted} (in Blender: File > Export)",
        "via_fbx": ("export it as FBX, import that into Blender (File > Import > FBX) and export glTF 2.0 (.glb)"
                    + ("" if hierarchy else ", or export a single mesh as OBJ")),
        "via_dae": ("export it as COLLADA (.dae), import that into Blender and export glTF 2.0 (.glb)" if hierarchy
                    else "export it from its tool as COLLADA (.dae) or OBJ"),
        "mesh_tool": f"convert it to {wanted} in a 3D tool that reads it",
        "xacro": f"expand its macros into a URDF first ({XACRO_COMMAND}) and give the .urdf",
    }[route]
    return f"{what} is not read by procmod; {how}"


__all__ = ["OTHER_TOOL_FORMATS", "XACRO_COMMAND", "conversion_hint"]
