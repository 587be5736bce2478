"""Sets of files some of which were exported in other units of length.

A tool exports in its own units (Maya: centimetres; Blender, glTF: metres; CAD: millimetres
or inches), and a set gathered from several tools mixes them. Parts read at 100x the size of
the others are learned as variation (``procmod learn``) or as other part types
(``procmod strings``), so both say so in one line (:func:`mixed_sizes_note`).
"""

from __future__ import annotations

import math

import numpy as np

MIXED_SIZES = 10.0
"""Items whose sizes differ by more than this factor get a note (:func:`mixed_sizes_note`)."""

# ratios of one unit of length to another over MIXED_SIZES, as a size note names them
UNIT_FACTORS = ((100.0, "centimetres among metres"), (1000.0, "millimetres among metres"),
                (25.4, "millimetres among inches"), (39.37, "inches among metres"),
                (30.48, "centimetres among feet"), (12.0, "inches among feet"), (304.8, "millimetres among feet"))


def mixed_sizes_note(sizes, labels: list, what: str, consequence: str) -> str | None:
    """One line when the largest of ``sizes`` (one per item, e.g. its bounding-box
    diagonal) is over :data:`MIXED_SIZES` times the smallest: likely some exported in other
    units. When the sizes fall into two groups that far apart, the line names the larger
    group (by ``labels``) and, where their ratio is a units factor (100: centimetres and
    metres, ...), the units and the scale that makes them match; ``what`` names the items
    ("examples"), ``consequence`` ends the line (what the command makes of mixed sizes).
    None otherwise."""
    sizes = np.asarray(sizes, dtype=np.float64)
    if len(sizes) < 2:
        return None
    small, large = int(np.argmin(sizes)), int(np.argmax(sizes))
    if not sizes[small] > 0 or sizes[large] / sizes[small] <= MIXED_SIZES:
        return None
    logs = np.log(sizes)
    order = np.argsort(logs)
    gaps = np.diff(logs[order])
    cut = int(np.argmax(gaps))
    if np.exp(gaps[cut]) > MIXED_SIZES:  # two groups: some items in other units
        big = sorted(order[cut + 1:].tolist())
        ratio = float(np.exp(np.median(logs[order[cut + 1:]]) - np.median(logs[order[:cut + 1]])))
        # the nearest units factor, within the items' own spread of sizes (a quarter)
        factor, units = min(UNIT_FACTORS, key=lambda fu: abs(math.log(ratio / fu[0])))
        if abs(math.log(ratio / factor)) > math.log(1.25):
            factor, units = ratio, None
        named = ", ".join(labels[i] for i in big[:4]) + (f" and {len(big) - 4} more" if len(big) > 4 else "")
        return (f"{named} ({len(big)} of {len(sizes)} {what}) {'is' if len(big) == 1 else 'are'} about "
                f"{factor:.0f}x the size of the others"
                + (f" ({units}?)" if units else "")
                + f": scale {'it' if len(big) == 1 else 'them'} by {1 / factor:.4g} (or the others by "
                f"{factor:.4g}) to match; {consequence}")
    return (f"the {what} differ in size up to {sizes[large] / sizes[small]:.0f}x ({labels[large]} is "
            f"{sizes[large]:.3g} across, {labels[small]} {sizes[small]:.3g}): if some were exported in other "
            f"units, scale them to match; {consequence}")


__all__ = ["MIXED_SIZES", "UNIT_FACTORS", "mixed_sizes_note"]
