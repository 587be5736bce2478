"""Seed 000's evaluation measures (section 7, Table 2).

* ``s_struc(A, B)`` — the size of the largest rooted subtree two hierarchies have in
  common (same part at the root, children matched one-to-one by a maximum-weight
  assignment, recursively), divided by the larger of the two hierarchies' sizes (their
  self-similarities).
* ``s_vis(A, B)`` — in place of the paper's CNN descriptor: silhouettes from six
  orthographic views (the three axes and three diagonals, 32 x 32 pixels, one framing
  shared by the whole set), blurred (Gaussian, 1.5 px) so that distances grade with
  displacement, concatenated into a descriptor. As in the paper the distance is
  normalised by distances to the root part's descriptor: ``d(A, B) / (d(A, root_A) +
  d(B, root_B))``, which the triangle inequality keeps in [0, 1] when the roots agree
  (clipped otherwise), and ``s_vis = 1 - that``.
"""

from __future__ import annotations

import numpy as np
from scipy.optimize import linear_sum_assignment

from ..geometry.camera import Camera, Silhouettes
from .examples import ExampleNode


def hierarchy_from_dict(d: dict) -> ExampleNode:
    return ExampleNode(d["part"], np.asarray(d["transform"], dtype=np.float64),
                       [hierarchy_from_dict(c) for c in d["children"]])


def signature(node: ExampleNode) -> str:
    """A canonical string of the unordered part structure."""
    return node.part + "(" + ",".join(sorted(signature(c) for c in node.children)) + ")"


class StructureSimilarity:
    """Largest common rooted subtree, memoised on subtree signatures."""

    def __init__(self):
        self._memo = {}
        self._sig = {}

    def _signature(self, node):
        key = id(node)
        if key not in self._sig:
            self._sig[key] = (signature(node), node)
        return self._sig[key][0]

    def common(self, a: ExampleNode, b: ExampleNode) -> int:
        if a.part != b.part:
            return 0
        key = (self._signature(a), self._signature(b))
        if key in self._memo:
            return self._memo[key]
        value = 1
        if a.children and b.children:
            score = np.array([[self.common(x, y) for y in b.children] for x in a.children], dtype=float)
            if score.any():
                r, c = linear_sum_assignment(-score)
                value += int(score[r, c].sum())
        self._memo[key] = value
        return value

    def __call__(self, a: ExampleNode, b: ExampleNode) -> float:
        return self.common(a, b) / max(a.size(), b.size())


VIEW_DIRECTIONS = ((1, 0, 0), (0, 1, 0), (0, 0, 1), (1, 1, 1), (-1, 1, 1), (1, 1, -1))


def view_cameras(lo, hi, pixels: int = 32) -> list:
    lo, hi = np.asarray(lo, dtype=float), np.asarray(hi, dtype=float)
    centre = 0.5 * (lo + hi)
    radius = 0.5 * float(np.linalg.norm(hi - lo)) * 1.05
    cams = []
    for d in VIEW_DIRECTIONS:
        d = np.asarray(d, dtype=float)
        d /= np.linalg.norm(d)
        up = (0.0, 0.0, 1.0) if abs(d[1]) > 0.99 else (0.0, 1.0, 0.0)
        cams.append(Camera(tuple(centre + 4 * radius * d), tuple(centre), up, "orthographic", 2 * radius, pixels, pixels))
    return cams


def descriptor(parts, cameras, blur: float = 1.5) -> np.ndarray:
    from scipy.ndimage import gaussian_filter
    out = Silhouettes(cameras)
    for p in parts:
        out.add(p)
    return np.concatenate([gaussian_filter(out.image(i).astype(np.float64), blur).ravel()
                           for i in range(len(cameras))])


def parts_of(node: ExampleNode, library: dict) -> list:
    return [library[n.part].part(n.transform) for n in node.walk()]


class VisualSimilarity:
    """s_vis over one framing (the union bounds of ``reference`` hierarchies)."""

    def __init__(self, library: dict, reference: list, pixels: int = 32):
        from ..geometry.solid import scene_bounds
        lo, hi = scene_bounds([p for h in reference for p in parts_of(h, library)])
        self.library = library
        self.cameras = view_cameras(lo, hi, pixels)

    def features(self, node: ExampleNode) -> tuple[np.ndarray, float]:
        d = descriptor(parts_of(node, self.library), self.cameras)
        root = descriptor([self.library[node.part].part(node.transform)], self.cameras)
        return d, max(float(np.linalg.norm(d - root)), 1e-9)

    @staticmethod
    def similarity(fa, fb) -> float:
        (da, ra), (db, rb) = fa, fb
        dist = float(np.linalg.norm(da - db)) / (ra + rb)
        return 1.0 - min(dist, 1.0)


def pairwise_mean(items, sim) -> tuple[float, list]:
    values = [sim(items[i], items[j]) for i in range(len(items)) for j in range(i + 1, len(items))]
    return float(np.mean(values)), values


def table2(examples: list, samples: list, library: dict) -> dict:
    """Seed 000 Table 2 for hierarchies (ExampleNode lists) of examples and samples."""
    from scipy.stats import ttest_ind
    struc = StructureSimilarity()
    s_ex, v_ex = pairwise_mean(examples, struc)
    s_sa, v_sa = pairwise_mean(samples, struc)
    test = ttest_ind(v_ex, v_sa, equal_var=False)
    example_sigs = {signature(e) for e in examples}
    new = float(np.mean([signature(s) not in example_sigs for s in samples]))
    smax = float(np.mean([max(struc(s, e) for e in examples) for s in samples]))
    vis = VisualSimilarity(library, examples)
    fe = [vis.features(e) for e in examples]
    fs = [vis.features(s) for s in samples]
    vis_ex, w_ex = pairwise_mean(fe, vis.similarity)
    vis_sa, w_sa = pairwise_mean(fs, vis.similarity)
    vtest = ttest_ind(w_ex, w_sa, equal_var=False)
    vmax = float(np.mean([max(vis.similarity(f, g) for g in fe) for f in fs]))
    return {"s_struc_examples": s_ex, "s_struc_samples": s_sa, "s_struc_p_value": float(test.pvalue),
            "pct_new_structures": 100 * new, "s_max_struc": smax,
            "s_vis_examples": vis_ex, "s_vis_samples": vis_sa, "s_vis_p_value": float(vtest.pvalue),
            "s_max_vis": vmax, "n_samples": len(samples)}
