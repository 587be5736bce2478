"""String-based synthesis of structured shapes (seed 001).

Modules: :mod:`.codec` (graph <-> SMILES-topology strings), :mod:`.shapes` (shapes and
graph files), :mod:`.assets` (shapes from glTF / GLB / URDF files), :mod:`.contacts` (contact graphs), :mod:`.grammar` (tiling grammar),
:mod:`.automorphisms` (graph symmetries), :mod:`.sampling` (graph-based shape sampling),
:mod:`.vae` (sequence VAE), :mod:`.automaton` (the grammar automaton of constrained
decoding), :mod:`.torch_utils` (threads, devices, checkpoints), :mod:`.latent` (latent
sampling, search graphs), :mod:`.frames` (part frames, whole-shape symmetries),
:mod:`.categories` (edge categories), :mod:`.tagger` (strings -> edge categories, the
vote), :mod:`.decoding` (structured decoding of a string's categories),
:mod:`.instantiate` (graph -> 3D shape), :mod:`.pipeline` (collection and model folders),
:mod:`.render` (previews, GLB). See docs/strings.md.
"""

from ..core.lazy import lazy_getattr

# Imported on first use, so the command line's parser does not import the subsystem.
_LAZY = {**dict.fromkeys(("GraphError", "StringSyntaxError", "decode", "encode", "parse", "strings_of"), "codec"),
         **dict.fromkeys(("Shape", "ShapeSet", "ShapesFormatError", "read_graph", "read_shapes", "write_graph",
                          "write_shapes"), "shapes"),
         **dict.fromkeys(("read_shape_inputs", "shapes_from_assets"), "assets"),
         "shape_graph": "contacts", **dict.fromkeys(("Grammar", "validate_shape"), "grammar")}


__getattr__ = lazy_getattr(__name__, _LAZY, globals())


__all__ = ["GraphError", "StringSyntaxError", "decode", "encode", "parse", "strings_of", "Grammar", "Shape",
           "ShapeSet", "ShapesFormatError", "read_graph", "read_shape_inputs", "read_shapes", "shape_graph",
           "shapes_from_assets", "validate_shape",
           "write_graph", "write_shapes"]
