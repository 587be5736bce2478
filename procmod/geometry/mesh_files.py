"""Reading one mesh file with trimesh, with the OBJ details trimesh's parser gets wrong.

Every place procmod reads a mesh file (volume and silhouette targets, part libraries,
asset meshes) goes through :func:`load_mesh_file`. For OBJ files it first rewrites what
trimesh 4 misreads, in memory (the file is left as it is):

* **Relative indices.** ``f -4 -3 -2`` means "the vertices 4, 3 and 2 back from this
  line"; trimesh resolves them against the *whole file's* vertices, so in a file of two
  objects every face of the first pointed at the second's vertices and the first object
  vanished without a word. They are rewritten as absolute indices.
* **Whitespace.** A tab after the keyword (``v\\t1 2 3``) or an indented line is dropped
  by trimesh, silently losing those vertices or faces; lines are re-spaced.
* **Line continuations** (a ``\\`` at the end of a line) are joined first, so that the
  two rules above see whole statements.
"""

from __future__ import annotations

import io
import re
from pathlib import Path

_INDEXED = ("f", "l", "p")  # statements that index vertices (v/vt/vn per field)
_COUNTED = {"v": 0, "vt": 1, "vn": 2}


def normalised_obj(text: str) -> str | None:
    """``text`` (an OBJ file) with relative indices made absolute and each statement
    re-spaced; None when nothing needed changing (trimesh reads the file as it is)."""
    text = re.sub(r"\\\r?\n", " ", text)
    counts = [0, 0, 0]
    out, changed = [], False
    for line in text.splitlines():
        fields = line.split()
        if not fields or fields[0].startswith("#"):
            out.append(line)
            continue
        key = fields[0]
        if key in _COUNTED:
            counts[_COUNTED[key]] += 1
        elif key in _INDEXED:
            for i in range(1, len(fields)):
                refs = fields[i].split("/")
                for slot, ref in enumerate(refs[:3]):
                    if ref.startswith("-"):
                        try:
                            refs[slot] = str(counts[slot] + 1 + int(ref))
                        except ValueError:  # not a number: trimesh decides what it makes of it
                            continue
                fields[i] = "/".join(refs)
        statement = " ".join(fields)
        changed = changed or statement != line
        out.append(statement)
    return "\n".join(out) + "\n" if changed else None


def load_mesh_file(path: str | Path, **options):
    """``trimesh.load(path, **options)``, an OBJ file read through :func:`normalised_obj`
    (materials and other files it names are still found beside it)."""
    import trimesh

    path = Path(path)
    if path.suffix.lower() == ".obj":
        # latin-1 maps every byte to one character and back: names in other encodings survive
        fixed = normalised_obj(path.read_bytes().decode("latin-1"))
        if fixed is not None:
            resolver = trimesh.resolvers.FilePathResolver(str(path))
            return trimesh.load(io.BytesIO(fixed.encode("latin-1")), file_type="obj", resolver=resolver, **options)
    return trimesh.load(path, **options)


__all__ = ["load_mesh_file", "normalised_obj"]
