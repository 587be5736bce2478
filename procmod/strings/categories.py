"""Edge categories (seed 001, section 6): per pair of node types, the relative poses of
neighbours (one part's canonical frame seen from the other's, :mod:`.frames`) are
clustered by mean shift (scikit-learn); same-type pairs take the unordered pair of both
directions' clusters. Each category keeps example relative transforms, which the
instantiation transplants, and the labelling of a shape's edges is the ground truth the
tagger learns (:func:`shape_labelings`).
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, fields

import networkx as nx
import numpy as np

from .frames import (canonical_frame, estimate_world_symmetries, proper_placement, rigid_inverse, symmetric_copies,
                     world_symmetries)
from .automorphisms import type_automorphisms
from .contacts import part_points
from .shapes import Shape, ShapeSet


def _pose_feature(fa: np.ndarray, fb: np.ndarray, length: float, rot_weight: float) -> np.ndarray:
    rel = np.linalg.inv(fa) @ fb
    return np.concatenate([rel[:3, 3] / length, rot_weight * rel[:3, :3].reshape(9)])


@dataclass
class CategoryParams:
    bandwidth: float = 0.15  # mean-shift bandwidth in units of the median part diagonal
    rot_weight: float = 0.5  # weight of the rotation entries against normalised offsets
    examples_per_category: int = 24


class EdgeCategories:
    """Edge categories per type pair, fitted on shapes; the relative transforms that
    realise each category, for transplanting.

    ``names[k]`` = ``(A, B, key)`` for category ``k >= 1`` (``A <= B``); category 0 is the
    dummy of characters that stand for no edge. ``clearance[(A, B)]`` (``A <= B``): the
    smallest distance between the frame origins of two parts of those types that are *not*
    neighbours, over the fitted shapes (:func:`part_clearances`; None for categories saved
    before it was kept). ``symmetries``: the whole-shape turns and mirrors (4x4) a string
    cannot tell apart, estimated from the fitted shapes
    (:func:`~procmod.strings.frames.estimate_world_symmetries`; default, and for categories
    saved before they were kept: :func:`~procmod.strings.frames.world_symmetries`).
    """

    def __init__(self, names, centres, examples, length, params: CategoryParams,
                 clearance: dict | None = None, symmetries: list | None = None):
        self.names = [tuple(n) if n is not None else None for n in names]
        self.centres = centres  # (A, B) -> cluster centres (k, 12)
        self.examples = examples  # category -> list of 4x4 (A-part -> B-part relative transforms)
        self.length = length
        self.params = params
        self.clearance = clearance
        self.symmetries = [np.asarray(m, dtype=np.float64) for m in
                           (world_symmetries() if symmetries is None else symmetries)]
        self.groups: dict = {}  # part name -> symmetry rotations in frame terms (cache)
        self.index = {n: k for k, n in enumerate(self.names) if n is not None}
        self.by_pair: dict[tuple, list[int]] = {}
        for k, n in enumerate(self.names):
            if n is not None:
                self.by_pair.setdefault((n[0], n[1]), []).append(k)

    def __len__(self) -> int:
        return len(self.names)

    # -- fitting ------------------------------------------------------------------------------

    @staticmethod
    def fit(shape_set: ShapeSet, shapes, graphs, params: CategoryParams = CategoryParams(),
            symmetric: bool = True) -> "EdgeCategories":
        """Cluster the relative poses of neighbours in ``shapes`` (and, when ``symmetric``,
        in their copies moved by the whole-shape symmetries the shapes show:
        :func:`~procmod.strings.frames.estimate_world_symmetries`; without ``symmetric`` the
        categories keep the identity alone)."""
        from sklearn.cluster import MeanShift

        clearance = part_clearances(shape_set, shapes, graphs)  # turns and mirrors keep distances
        symmetries = estimate_world_symmetries(shape_set, shapes, graphs) if symmetric else [np.eye(4)]
        if symmetric:
            pairs = [(c, g) for s, g in zip(shapes, graphs)
                     for c in symmetric_copies(s, shape_set.library, symmetries) if c is not None]
            shapes, graphs = [c for c, _ in pairs], [g for _, g in pairs]

        lib = shape_set.library
        diag = [float(np.linalg.norm(np.subtract(*s.local_bounds()[::-1]))) for s in lib.values()]
        length = float(np.median(diag))
        groups: dict = {}
        per_pair: dict[tuple, list] = {}  # (A, B) -> rows (feature, shape, a, b) with a of type A
        for si, (shape, g) in enumerate(zip(shapes, graphs)):
            frames = [canonical_frame(lib, p, t, groups) for p, t in zip(shape.parts, shape.transforms)]
            for a, b in g.edges:
                ta, tb = g.nodes[a]["type"], g.nodes[b]["type"]
                for x, y in ((a, b), (b, a)) if ta == tb else (((a, b),) if ta < tb else ((b, a),)):
                    f = _pose_feature(frames[x], frames[y], length, params.rot_weight)
                    per_pair.setdefault((g.nodes[x]["type"], g.nodes[y]["type"]), []).append((f, si, x, y))
        centres = {}
        labels_of: dict[tuple, np.ndarray] = {}
        for pair, rows in sorted(per_pair.items()):
            feats = np.array([r[0] for r in rows])
            uniq, inverse = np.unique(np.round(feats, 4), axis=0, return_inverse=True)
            ms = MeanShift(bandwidth=params.bandwidth, bin_seeding=False).fit(uniq)
            centres[pair] = ms.cluster_centers_
            labels_of[pair] = ms.labels_[inverse.reshape(-1)]
        names: list = [None]
        examples: dict[int, list] = {}
        index: dict[tuple, int] = {}
        assignments = {}  # (shape, a, b) sorted pair -> category
        for pair, rows in sorted(per_pair.items()):
            labels = labels_of[pair]
            if pair[0] != pair[1]:
                keyed = [((int(l),), r) for l, r in zip(labels, rows)]
            else:
                both: dict[tuple, dict] = {}
                for l, r in zip(labels, rows):
                    both.setdefault((r[1], min(r[2], r[3]), max(r[2], r[3])), {})[(r[2], r[3])] = (int(l), r)
                keyed = []
                for (si, lo, hi), d in both.items():
                    (l1, r1), (l2, _) = d[(lo, hi)], d[(hi, lo)]
                    keyed.append(((min(l1, l2), max(l1, l2)), r1))
            for key, r in keyed:
                name = (pair[0], pair[1], "-".join(map(str, key)))
                if name not in index:
                    index[name] = len(names)
                    names.append(name)
                k = index[name]
                _, si, x, y = r
                assignments[(si, min(x, y), max(x, y))] = k
                ex = examples.setdefault(k, [])
                if len(ex) < 4 * params.examples_per_category:
                    shape = shapes[si]
                    fx = canonical_frame(lib, shape.parts[x], shape.transforms[x], groups)
                    fy = canonical_frame(lib, shape.parts[y], shape.transforms[y], groups)
                    # each part's transform in the other's canonical frame (A -> B, B -> A)
                    ax = shape.transforms[x].copy()
                    ax[:3, 3] = 0.0  # how the A part was turned (for symmetry_permutations)
                    ex.append(np.stack([rigid_inverse(fx) @ shape.transforms[y],
                                        rigid_inverse(fy) @ shape.transforms[x], ax]))
        for k, ex in examples.items():
            kept, keys = [], set()
            for m in ex:  # distinct examples, kept at full precision (frames of them must tie exactly)
                key = tuple(np.round(m, 5).reshape(-1).tolist())
                if key not in keys and len(kept) < params.examples_per_category:
                    keys.add(key)
                    kept.append(m)
            examples[k] = kept
        cats = EdgeCategories(names, centres, examples, length, params, clearance, symmetries)
        cats._fit_assignments = assignments
        return cats

    def edge_categories(self, shape_set: ShapeSet, shape: Shape, g: nx.Graph) -> dict:
        """Category of every edge of a shape: ``{(min, max): k}`` (nearest cluster centre)."""
        lib = shape_set.library
        frames = [canonical_frame(lib, p, t, self.groups) for p, t in zip(shape.parts, shape.transforms)]
        out = {}
        for a, b in g.edges:
            k = self.category_of_frames(frames[a], frames[b], g.nodes[a]["type"], g.nodes[b]["type"])
            if k is not None:
                out[(min(a, b), max(a, b))] = k
        return out

    def category_of_frames(self, fa: np.ndarray, fb: np.ndarray, ta: str, tb: str,
                           seen_only: bool = False) -> int | None:
        """Category of two neighbours of types ``ta``, ``tb`` with canonical frames ``fa``,
        ``fb`` (the nearest cluster centre of their relative pose), or None when their type
        pair has no categories; with ``seen_only`` also None when that centre is farther than
        one bandwidth (the pose is not one of the category's: :meth:`pose_seen`)."""
        if ta > tb:
            fa, fb, ta, tb = fb, fa, tb, ta
        forward = self._pose_distances(fa, fb, ta, tb)
        if forward is None:
            return None
        near = int(np.argmin(forward))
        if seen_only and forward[near] > self.params.bandwidth:
            return None
        key = (near,) if ta != tb else tuple(sorted((near, int(np.argmin(self._pose_distances(fb, fa, tb, ta))))))
        return self.index.get((ta, tb, "-".join(map(str, key))))

    def _pose_distances(self, fa: np.ndarray, fb: np.ndarray, ta: str, tb: str) -> np.ndarray | None:
        """Distances of ``b``'s pose in ``a``'s frame to the cluster centres of the type pair
        ``(ta, tb)``, ``ta <= tb`` (None: the pair has no categories)."""
        centres = self.centres.get((ta, tb))
        if centres is None:
            return None
        return np.linalg.norm(centres - _pose_feature(fa, fb, self.length, self.params.rot_weight), axis=1)

    def _category_of_pair(self, shape_set: ShapeSet, pa: str, ma: np.ndarray, pb: str, mb: np.ndarray):
        lib = shape_set.library
        fa, fb = canonical_frame(lib, pa, ma, self.groups), canonical_frame(lib, pb, mb, self.groups)
        return self.category_of_frames(fa, fb, shape_set.letters[pa], shape_set.letters[pb])

    def symmetry_permutations(self, shape_set: ShapeSet) -> list[dict]:
        """For each of :attr:`symmetries`, where it sends each category (turning an example
        edge of the category and classifying it again)."""
        if getattr(self, "_perms", None) is not None:
            return self._perms
        part_of = shape_set.part_of_letter
        perms = []
        for g in self.symmetries:
            perm = {0: 0}
            for k, name in enumerate(self.names):
                if name is None or not self.examples.get(k):
                    continue
                pa, pb = part_of[name[0]], part_of[name[1]]
                rel_ab, _, ma = self.examples[k][0]
                mb = canonical_frame(shape_set.library, pa, ma, self.groups) @ rel_ab
                ga = proper_placement(shape_set.library, pa, g @ ma)
                gb = proper_placement(shape_set.library, pb, g @ mb)
                perm[k] = None if ga is None or gb is None else self._category_of_pair(shape_set, pa, ga, pb, gb)
            perms.append(perm)
        self._perms = perms
        return perms

    def pose_seen(self, fa: np.ndarray, fb: np.ndarray, ta: str, tb: str) -> bool:
        """Is ``b``'s pose in ``a``'s frame within one bandwidth of a cluster for its type pair?"""
        if ta > tb:
            fa, fb, ta, tb = fb, fa, tb, ta
        dist = self._pose_distances(fa, fb, ta, tb)
        return dist is not None and float(dist.min()) <= self.params.bandwidth

    def allowed(self, ta: str, tb: str) -> list[int]:
        return self.by_pair.get((min(ta, tb), max(ta, tb)), [])

    def to_json(self) -> dict:
        out = {"names": [list(n) if n else None for n in self.names],
               "centres": {f"{a}|{b}": c.tolist() for (a, b), c in self.centres.items()},
               "examples": {str(k): [m.tolist() for m in v] for k, v in self.examples.items()},
               "length": self.length, "params": asdict(self.params)}
        if self.clearance is not None:
            out["clearance"] = {f"{a}|{b}": d for (a, b), d in sorted(self.clearance.items())}
        out["symmetries"] = [np.round(m, 12).tolist() for m in self.symmetries]
        return out

    @staticmethod
    def from_json(data) -> "EdgeCategories":
        """The inverse of :meth:`to_json`. Content of the wrong shape (a file cut short or
        edited by hand) is a ValueError saying what is wrong, never categories that fail later."""
        if not isinstance(data, dict):
            raise ValueError(f"edge categories must be a JSON object, got {type(data).__name__}")
        missing = [k for k in ("names", "centres", "examples", "length", "params") if k not in data]
        if missing:
            raise ValueError(f"edge categories lack {', '.join(repr(k) for k in missing)}")
        names = data["names"]
        if not isinstance(names, list) or not names or names[0] is not None or not all(
                isinstance(n, list) and len(n) == 3 and all(isinstance(x, str) for x in n) for n in names[1:]):
            raise ValueError(f"edge categories' names must be a list of null then [type, type, key] triples, got "
                             f"{names!r:.60}")
        pairs = {(a, b) for a, b, _ in names[1:]}
        centres = {_type_pair(k, "centres"): _finite(v, "centres", (None, 12))
                   for k, v in _object(data, "centres").items()}
        if not pairs <= set(centres):
            raise ValueError(f"edge categories have no centres for the type pair(s) "
                             f"{', '.join('|'.join(p) for p in sorted(pairs - set(centres)))}")
        examples = {}
        for k, v in _object(data, "examples").items():
            if not (k.isdigit() and 1 <= int(k) < len(names)) or not isinstance(v, list):
                raise ValueError(f"edge categories' examples must map a category number (1 to {len(names) - 1}) to "
                                 f"a list of examples, got {k!r:.20}: {v!r:.40}")
            # each a stack of B's pose in A's frame, A's in B's and (since symmetries) A's turn
            examples[int(k)] = [_finite(m, f"examples[{k}]", (None, 4, 4)) for m in v]
            if any(len(m) < 2 for m in examples[int(k)]):
                raise ValueError(f"edge categories' examples[{k}] must each stack at least two 4x4 poses")
        length = data["length"]
        if isinstance(length, bool) or not isinstance(length, (int, float)) or not (math.isfinite(length)
                                                                                     and length > 0):
            raise ValueError(f"edge categories' length must be a positive number, got {length!r:.40}")
        params = data["params"]
        known = {f.name for f in fields(CategoryParams)}
        if not isinstance(params, dict) or not set(params) <= known or not all(
                isinstance(v, (int, float)) and not isinstance(v, bool) for v in params.values()):
            raise ValueError(f"edge categories' params must be an object of numbers ({', '.join(sorted(known))}), "
                             f"got {params!r:.60}")
        clearance = data.get("clearance")  # absent in categories fitted before it was kept
        if clearance is not None:
            clearance = {_type_pair(k, "clearance"): _number(d, "clearance") for k, d in
                         _object(data, "clearance").items()}
        symmetries = data.get("symmetries")  # absent in categories fitted before they were estimated
        if symmetries is not None:
            if not isinstance(symmetries, list) or not symmetries:
                raise ValueError(f"edge categories' symmetries must be a list of 4x4 matrices, got {symmetries!r:.40}")
            symmetries = [_finite(m, "symmetries", (4, 4)) for m in symmetries]
        return EdgeCategories(names, centres, examples, float(length), CategoryParams(**params),
                              clearance, symmetries)


def _object(data: dict, key: str) -> dict:
    value = data[key]
    if not isinstance(value, dict):
        raise ValueError(f"edge categories' {key} must be a JSON object, got {value!r:.40}")
    return value


def _type_pair(key: str, where: str) -> tuple:
    pair = tuple(key.split("|"))
    if len(pair) != 2 or not all(pair):
        raise ValueError(f"edge categories' {where} must be keyed by type pairs 'A|B', got {key!r:.40}")
    return pair


def _number(value, where: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise ValueError(f"edge categories' {where} must hold finite numbers, got {value!r:.40}")
    return float(value)


def _finite(value, where: str, shape: tuple) -> np.ndarray:
    """``value`` as a float array of ``shape`` (None: any length), every entry finite."""
    try:
        array = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        array = None
    if array is None or array.ndim != len(shape) or any(w is not None and n != w for n, w in zip(array.shape, shape)) \
            or not np.isfinite(array).all():
        want = "x".join("n" if w is None else str(w) for w in shape)
        raise ValueError(f"edge categories' {where} must hold {want} arrays of finite numbers, got {value!r:.40}")
    return array


def part_clearances(shape_set: ShapeSet, shapes, graphs) -> dict[tuple[str, str], float]:
    """Per type pair ``(A, B)`` (letters, ``A <= B``), the smallest distance between the
    frame origins (vertex means) of two parts of those types that are not neighbours in
    their shape's graph, over ``shapes``. Structured decoding counts a labelling that puts
    two such parts closer as a fault: it places a part where the generator never put one
    (e.g. two columns on one spot after a wrong turn). Pairs never seen apart are absent."""
    lib = shape_set.library
    out: dict[tuple[str, str], float] = {}
    centre_of: dict = {}  # part name -> vertex mean in the part's own coordinates
    for shape, g in zip(shapes, graphs):
        n = len(shape.parts)
        if n < 2:
            continue
        for p in set(shape.parts):
            if p not in centre_of:
                centre_of[p] = part_points(lib, p, np.eye(4)).mean(0)
        centres = np.array([t[:3, :3] @ centre_of[p] + t[:3, 3] for p, t in zip(shape.parts, shape.transforms)])
        dist = np.linalg.norm(centres[:, None] - centres[None], axis=2)
        apart = ~np.eye(n, dtype=bool)
        for a, b in g.edges:
            apart[a, b] = apart[b, a] = False
        letters = np.array([shape_set.letters[p] for p in shape.parts])
        kinds = sorted(set(letters.tolist()))
        for i, a in enumerate(kinds):
            for b in kinds[i:]:
                pick = apart & np.outer(letters == a, letters == b)
                if pick.any():
                    d = float(dist[pick].min())
                    if d < out.get((a, b), np.inf):
                        out[(a, b)] = d
    return out


def shape_labelings(shape_set: ShapeSet, shape: Shape, g: nx.Graph, categories: "EdgeCategories",
                    automorphisms: int = 64) -> list[dict]:
    """Edge categories of each symmetric copy of a shape (``categories.symmetries``) that all its edges fall in, and
    of each of those relabelled by an automorphism of ``g`` (at most ``automorphisms`` of
    them, :func:`~procmod.strings.automorphisms.type_automorphisms`; 1: none): every labelling a
    string of ``g`` could be right to give, without duplicates."""
    out, seen = [], set()
    auts = type_automorphisms(g, automorphisms) if automorphisms > 1 else [{v: v for v in g.nodes}]
    for copy in symmetric_copies(shape, shape_set.library, categories.symmetries):
        if copy is None:
            continue
        cats = categories.edge_categories(shape_set, copy, g)
        if len(cats) != g.number_of_edges():
            continue
        for sigma in auts:
            # the part at a takes the place of sigma[a]: edge (a, b) gets sigma's image's category
            moved = {(a, b): cats[(min(sigma[a], sigma[b]), max(sigma[a], sigma[b]))] for a, b in cats}
            key = tuple(sorted(moved.items()))
            if key not in seen:
                seen.add(key)
                out.append(moved)
    return out
