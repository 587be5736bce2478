"""Targets: what engines control models toward.

Every target is a :class:`procmod.core.Target`: ``configure(model)`` (place the model,
e.g. at the target's start point), ``new_output(model)`` (an empty output that keeps the
target's running sums), ``score(output)`` (the human-readable figure),
``log_likelihood(output)`` (what probabilistic engines weight by), ``display_mask(width)``
and its declared capabilities (``exact_removal``, ``has_mask``, ``has_overlay``). Scores
of partial outputs are incremental: O(pixels changed by the last emit).
"""

from .circuit import Circuit, EdgeCanvas, edge_total
from .image import (TargetFileError, TargetImage, check_mask, load_target_image,
                    lowest_point_start, mask_from_image, out_of_bounds_penalty, place_model,
                    resample_mask)
from .shape import ShapeMatch, shape_weights, sobel_magnitude
from .files import load_silhouette_target, load_target_file, load_volume_target, read_mesh, voxelize_mesh_file
from .silhouette import Silhouette
from .volume import ProxyVolume, Volume

__all__ = [name for name in dir() if not name.startswith("_")]
