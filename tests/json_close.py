"""Compare JSON documents that a script regenerates with the stored copies.

Generators round what they write to 12 significant digits, but a value that lies on a
rounding boundary can still come out one unit of the 12th digit apart on another CPU
(its libm or BLAS kernel changes a double's last bits). So numbers are compared with a
relative tolerance of 1e-9: far above that cross-machine noise (~1e-15 relative, times
the few dozen operations behind a value), far below any change to a generator (which
moves values by 1e-3 or more).
"""

import math

REL = 1e-9
ABS = 1e-12


def differences(made, stored, where="$") -> list:
    """Paths (JSON-path-like) where ``made`` and ``stored`` differ beyond the tolerance."""
    if isinstance(made, bool) or isinstance(stored, bool):
        return [] if made is stored else [where]
    if isinstance(made, (int, float)) and isinstance(stored, (int, float)):
        return [] if math.isclose(made, stored, rel_tol=REL, abs_tol=ABS) else [where]
    if isinstance(made, dict) and isinstance(stored, dict):
        if made.keys() != stored.keys():
            return [f"{where} (keys {sorted(made)} vs {sorted(stored)})"]
        return [d for k in made for d in differences(made[k], stored[k], f"{where}.{k}")]
    if isinstance(made, list) and isinstance(stored, list):
        if len(made) != len(stored):
            return [f"{where} (length {len(made)} vs {len(stored)})"]
        return [d for i, (a, b) in enumerate(zip(made, stored)) for d in differences(a, b, f"{where}[{i}]")]
    return [] if made == stored else [where]


def assert_json_close(made, stored) -> None:
    diff = differences(made, stored)
    assert not diff, f"{len(diff)} differences, first: {diff[:5]}"
