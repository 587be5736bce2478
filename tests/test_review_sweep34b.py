"""Review h183 of sweep 34's OBJ export (one object per part, named after its tag)."""

import numpy as np
import pytest

from procmod.geometry.mesh_export import export_mesh
from procmod.geometry.solid import Box
from procmod.targets.files import read_mesh


def _at(x):
    m = np.eye(4)
    m[0, 3] = x
    return tuple(m.ravel())


@pytest.mark.parametrize("tag", ["wing\nv 9 9 9", "wing\r\nf 1 2 3", "wing\\", "a\u2028b", "\x85"])
def test_an_obj_object_name_stays_on_its_line(tmp_path, tag):
    """A part name is the rest of its ``o`` line: one with a line break (a part name in an
    examples file) had written its remainder as a line of its own (a stray vertex, every later
    face on the wrong vertices), and one ending in a backslash continued the line into the
    object's first vertex (procmod's own mesh reader refused the file). Both boxes read whole."""
    path = tmp_path / "parts.obj"
    export_mesh([Box((1, 1, 1), _at(0), tag), Box((1, 1, 1), _at(3), "next")], path, lambda tag: (200, 100, 50))
    vertices, faces = read_mesh(path, orient=False)
    assert (len(vertices), len(faces)) == (16, 24)
    assert np.allclose([vertices.min(0), vertices.max(0)], [[-0.5, -0.5, -0.5], [3.5, 0.5, 0.5]])
    names = [line[2:] for line in path.read_text(encoding="utf-8").split("\n") if line.startswith("o ")]
    assert len(names) == 2 and names[1] == "next" and all(name.strip() and "\r" not in name for name in names)
