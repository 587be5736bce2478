"""Features a neural guide sees at each random choice (seed 003 section 5.1, seed 004 4.1).

Three sources, each optional (the ablation conditions of seed 004 Figure 5), and a fourth
off by default:

- **local state**: the scalar arguments of the rule call the choice occurs in, mapped to
  [-1, 1] with the ranges the model declares (``Model.arg_ranges``) and clipped; an
  argument declared as an angle (``"angle"``) becomes its cosine and sine instead, and a
  rule in ``Model.heading_rules`` adds the cosine and sine of the heading its ``ctx.at``
  reports (see :func:`local_ranges`);
- **target image**: 3x3 windows of the target mask around the current position
  (``ctx.at``) at four resolutions (36 features);
- **partial output**: the same windows on the image the derivation has drawn so far;
- **progress** (a design extension of the papers, off unless asked for): how many calls
  are still pending besides the current one, and, with a target image, the fraction of
  the target the derivation has drawn on (:meth:`FeatureExtractor.progress_values`),
  mapped to [-1, 1] like local state and placed after it. The windows only see a few
  pixels around the current position; a choice that ends the derivation (a vine's
  ``terminate``, or a ``branch1`` coin that spawns nothing when nothing else is pending)
  needs to know whether the rest of the target is still empty. README ("Neural guides")
  has what it gains and costs.

Each resolution level is the previous one convolved with a 3x3 kernel, then downsampled
by a 2x2 box filter. The papers learn the kernels jointly with each network; procmod fixes
them to a binomial blur ([1 2 1] x [1 2 1] / 16), shared by every site. That design change
is deliberate: the partial-output pyramid then depends only on the drawn pixels, so it is
computed once per emit (after an emit, the first choice that needs it rebuilds it in one
numba pass over the 50x50 raster, a few microseconds; every later choice until the next
emit, in this particle and in every copy of it made by resampling, reuses it), and a
training trace's features can be computed once and reused for every gradient step. The
networks keep their learned first layer, which mixes the window values freely.
"""

from __future__ import annotations

import inspect
import math
from dataclasses import dataclass

import numba
import numpy as np

from ..core import ProcmodError

LEVELS = 4
WINDOW = 3
FEATURES_PER_IMAGE = LEVELS * WINDOW * WINDOW  # 36 per channel


class GuideError(ProcmodError):
    """A guide that does not fit its model, target or settings."""


class FeatureSettingsError(GuideError):
    """Features the model cannot give (local state of a rule without argument ranges): a
    matter of the model and the settings, not of any one trace."""


CONDITIONS = {
    # seed 004 Figure 5's conditions: name -> (local state, target image, partial output)
    "constant": (False, False, False),
    "local": (True, False, False),
    "local+target": (True, True, False),
    "all": (True, True, True),
}
SOURCES = ("local", "target", "partial", "progress")


@dataclass(frozen=True)
class FeatureSettings:
    """Which feature sources a guide's networks see."""

    local: bool = True
    target: bool = True
    partial: bool = True
    progress: bool = False

    @classmethod
    def condition(cls, name: str) -> "FeatureSettings":
        """Settings by name: seed 004's conditions (constant, local, local+target, all) or
        any ``+``-joined set of local, target, partial and progress (e.g. ``local+partial``
        for a score without a target image, such as the circuit; ``all+progress``)."""
        if name in CONDITIONS:
            return cls(*CONDITIONS[name])
        parts = name.split("+")
        if parts[0] in CONDITIONS:  # a condition and more, e.g. all+progress
            # (a condition's flags are the first three sources: zip stops at them)
            parts = [n for n, on in zip(SOURCES, CONDITIONS[parts[0]]) if on] + parts[1:]
        if not name or any(p not in SOURCES for p in parts):
            raise GuideError(f"unknown feature condition {name!r}; choose one of {', '.join(CONDITIONS)}, "
                             f"or join {', '.join(SOURCES)} with '+'")
        return cls(*(source in parts for source in SOURCES))

    @property
    def name(self) -> str:
        flags = (self.local, self.target, self.partial)
        for name, condition in CONDITIONS.items():
            if condition == flags:
                if not self.progress:
                    return name
                return "progress" if name == "constant" else name + "+progress"
        return "+".join(n for n, on in zip(SOURCES, flags + (self.progress,)) if on)

    def to_json(self) -> dict:
        # "progress" only when on: guides of the papers' conditions keep their files as before
        flags = {"local": self.local, "target": self.target, "partial": self.partial}
        return {**flags, "progress": True} if self.progress else flags


def level_layout(height: int, width: int) -> np.ndarray:
    """Rows of (offset, height, width) of the four levels inside one flat array."""
    rows, offset, h, w = [], 0, height, width
    for _ in range(LEVELS):
        rows.append((offset, h, w))
        offset += h * w
        h, w = max(h // 2, 1), max(w // 2, 1)
    return np.array(rows, dtype=np.int64)


@numba.njit(cache=True)
def _blur_down_region(flat, src, dst, r0, r1, c0, c1):
    """Recompute rows r0..r1, columns c0..c1 of the level ``dst`` (offset, h, w) as the 2x2
    box downsampling of the level ``src`` convolved with the binomial 3x3 kernel (zero
    padded)."""
    so, h, w = src[0], src[1], src[2]
    do, dw = dst[0], dst[2]
    for i in range(r0, r1 + 1):
        for j in range(c0, c1 + 1):
            total = 0.0
            for a in range(2):
                for b in range(2):
                    r = 2 * i + a
                    c = 2 * j + b
                    for di in range(-1, 2):
                        rr = r + di
                        if rr < 0 or rr >= h:
                            continue
                        wi = 2.0 if di == 0 else 1.0
                        for dj in range(-1, 2):
                            cc = c + dj
                            if cc < 0 or cc >= w:
                                continue
                            wj = 2.0 if dj == 0 else 1.0
                            total += wi * wj * flat[so + rr * w + cc]
            flat[do + i * dw + j] = total / 64.0  # /16 for the kernel, /4 for the box


@numba.njit(cache=True)
def pyramid_update(pixels, old, new, layout):
    """``new`` = the pyramid of ``pixels`` (non-zero = 1), given ``old``, the pyramid of an
    earlier state of the same raster: only the region whose pixels changed is recomputed,
    level by level (``old`` and ``new`` are distinct arrays). Returns whether anything
    changed."""
    h, w = layout[0, 1], layout[0, 2]
    new[h * w:] = old[h * w:]
    rmin, rmax, cmin, cmax = h, -1, w, -1
    for i in range(h):
        row = i * w
        changed = 0
        for j in range(w):  # branch-free, so that it vectorises: most rows do not change
            v = 1.0 if pixels[row + j] != 0 else 0.0
            changed += v != old[row + j]
            new[row + j] = v
        if changed:
            rmin = min(rmin, i)
            rmax = i
            for j in range(w):
                if new[row + j] != old[row + j]:
                    cmin = min(cmin, j)
                    cmax = max(cmax, j)
    if rmax < 0:
        return False
    for k in range(1, layout.shape[0]):
        dh, dw = layout[k, 1], layout[k, 2]
        # a blurred pixel changes up to one pixel away; a coarse pixel covers 2x2 of them
        rmin, rmax = max((rmin - 1) // 2, 0), min((rmax + 1) // 2, dh - 1)
        cmin, cmax = max((cmin - 1) // 2, 0), min((cmax + 1) // 2, dw - 1)
        if rmin > rmax or cmin > cmax:
            break
        _blur_down_region(new, layout[k - 1], layout[k], rmin, rmax, cmin, cmax)
    return True


@numba.njit(cache=True)
def windows_flat(flat, layout, px, py, out, offset):
    """The 3x3 windows around pixel position (px, py) at every level, into out[offset:]
    (zero outside the image)."""
    scale = 1.0
    k = offset
    for level in range(layout.shape[0]):
        o, h, w = layout[level, 0], layout[level, 1], layout[level, 2]
        cx = int(math.floor(px / scale))
        cy = int(math.floor(py / scale))
        for di in range(-1, 2):
            r = cy + di
            for dj in range(-1, 2):
                c = cx + dj
                out[k] = flat[o + r * w + c] if (0 <= r < h and 0 <= c < w) else 0.0
                k += 1
        scale *= 2.0


class Pyramid:
    """The four resolution levels of one image (level 0 is the image itself), stored in
    one flat array (``flat``, laid out by ``layout``)."""

    __slots__ = ("flat", "layout")

    def __init__(self, image: np.ndarray | None = None, *, flat=None, layout=None):
        if image is not None:
            image = np.asarray(image)
            layout = level_layout(*image.shape)
            flat = np.zeros(int(layout[-1, 0] + layout[-1, 1] * layout[-1, 2]))
            pixels = np.ascontiguousarray((image != 0).ravel(), dtype=np.uint8)
            pyramid_update(pixels, flat.copy(), flat, layout)
        self.flat, self.layout = flat, layout

    @classmethod
    def empty(cls, height: int, width: int) -> "Pyramid":
        layout = level_layout(height, width)
        return cls(flat=np.zeros(int(layout[-1, 0] + layout[-1, 1] * layout[-1, 2])), layout=layout)

    def updated(self, pixels: np.ndarray) -> "Pyramid":
        """The pyramid of ``pixels`` (flat raster of the same size), computed incrementally
        from this one (which is left unchanged: copies of a particle share it)."""
        new = np.empty_like(self.flat)
        pyramid_update(pixels, self.flat, new, self.layout)
        return Pyramid(flat=new, layout=self.layout)

    @property
    def levels(self) -> tuple:
        """The levels as 2D arrays (views)."""
        return tuple(self.flat[o:o + h * w].reshape(h, w) for o, h, w in self.layout)

    def windows_into(self, px: float, py: float, out: np.ndarray, offset: int) -> None:
        windows_flat(self.flat, self.layout, px, py, out, offset)


ANGLE = "angle"  # an arg_ranges entry for a direction in radians
HEADING = -1  # the local-state entry of the heading a rule reports with ctx.at


_DEFAULTS: dict = {}  # rule function -> the defaults of its positional arguments after ctx


def with_defaults(rule, args: tuple) -> tuple:
    """A call's arguments completed with the rule's defaults for those it left out (``def
    stem(ctx, x, y, angle, width, depth=0)`` spawned with four): local features read
    arguments by position, and a missing one was an IndexError blamed on a trace file."""
    try:
        defaults = _DEFAULTS.get(rule, False)
    except TypeError:  # an unhashable callable (a dataclass instance with __call__): not cached
        defaults = False
    if defaults is False:
        try:
            parameters = list(inspect.signature(rule).parameters.values())[1:]  # after ctx
        except (TypeError, ValueError):  # a builtin or a callable without a signature
            parameters = []
        defaults = tuple(p.default for p in parameters
                         if p.kind in (p.POSITIONAL_ONLY, p.POSITIONAL_OR_KEYWORD))
        if len(_DEFAULTS) > 4096:  # a model that builds its rules afresh: don't grow forever
            _DEFAULTS.clear()
        try:
            _DEFAULTS[rule] = defaults
        except TypeError:
            pass
    if len(args) >= len(defaults):
        return args
    missing = defaults[len(args):]
    if any(d is inspect.Parameter.empty for d in missing):
        return args  # a call short of a required argument: the rule's own call says so
    return tuple(args) + missing


def local_ranges(model, rule_name: str) -> tuple | None:
    """(argument indices, lows, spans, angular) of the local-state features of a rule.

    One entry per scalar argument the model gives a range for, in order, then, for a rule
    in ``model.heading_rules``, one for the heading its ``ctx.at`` reports (index -1). An
    argument declared ``"angle"`` and the heading are fed as (cos, sin) rather than
    clipped to a range: a heading is periodic, and a vine that has turned twice round
    would otherwise sit at the clip while its direction keeps changing. (A design
    extension of the papers, which normalise every argument linearly; README has its
    effect.)
    """
    ranges = model.arg_ranges.get(rule_name)
    if ranges is None:
        return None
    for i, r in enumerate(ranges):
        if not (r is None or r == ANGLE or (isinstance(r, (tuple, list)) and len(r) == 2
                                           and all(isinstance(v, (int, float)) for v in r) and r[1] > r[0])):
            raise FeatureSettingsError(f"model {model.name!r}: arg_ranges[{rule_name!r}][{i}] is {r!r}; each entry must be "
                             f"(low, high) with low < high, None (not a feature) or {ANGLE!r}")
    idx = [i for i, r in enumerate(ranges) if r is not None]
    angular = [ranges[i] == ANGLE for i in idx]
    lows = [0.0 if a else ranges[i][0] for i, a in zip(idx, angular)]
    spans = [1.0 if a else ranges[i][1] - ranges[i][0] for i, a in zip(idx, angular)]
    if rule_name in model.heading_rules:
        idx.append(HEADING)
        angular.append(True)
        lows.append(0.0)
        spans.append(1.0)
    return (np.array(idx, dtype=np.int64), np.array(lows, dtype=np.float64),
            np.array(spans, dtype=np.float64), np.array(angular, dtype=np.bool_))


def heading_of(state) -> float:
    """The heading the last ``ctx.at`` reported (a position ``(x, y, heading)``), else 0."""
    position = state.position
    return float(position[2]) if position is not None and len(position) > 2 else 0.0


@numba.njit(cache=True)
def local_features(raw, lows, spans, angular, out):
    """Write a call's local-state features into ``out`` (from index 0); returns how many:
    ranged arguments mapped to [-1, 1] and clipped, angles as (cos, sin)."""
    k = 0
    for j in range(raw.shape[0]):
        if angular[j]:
            out[k] = math.cos(raw[j])
            out[k + 1] = math.sin(raw[j])
            k += 2
        else:
            v = 2.0 * (raw[j] - lows[j]) / spans[j] - 1.0
            out[k] = min(max(v, -1.0), 1.0)
            k += 1
    return k


# The progress features' ranges (mapped to [-1, 1] and clipped like local state): the
# calls pending besides the current one, 0 to this many (more reads as this many), and
# the covered fraction of the target, 0 to 1.
PENDING_SCALE = 4.0


# fastmath lets the sum vectorise; its terms are 0 or 1, so any order gives the same sum
@numba.njit(cache=True, fastmath=True)
def covered_pixels(partial, target, n):
    """Sum over the first ``n`` entries (a pyramid's level 0) of partial x target: the
    target pixels the partial output has drawn on."""
    total = 0.0
    for i in range(n):
        total += partial[i] * target[i]
    return total


def check_same_size(target_layout: np.ndarray, partial_layout: np.ndarray) -> None:
    """Refuse a partial output whose raster is not the target image's size (pyramid
    layouts, :func:`level_layout`): the coverage and the windows read both alike."""
    if not np.array_equal(target_layout, partial_layout):
        raise GuideError(f"the target image is {target_layout[0, 2]}x{target_layout[0, 1]} pixels but the model "
                         f"draws {partial_layout[0, 2]}x{partial_layout[0, 1]}; give the model the target's size")


class FeatureExtractor:
    """Builds the feature vector of a choice from the context, output and target.

    One extractor serves every particle of a run: per-particle state (the partial-output
    pyramid) is cached on the derivation and shared by its copies.
    """

    def __init__(self, model, settings: FeatureSettings, target_mask: np.ndarray | None):
        self.model = model
        self.settings = settings
        if settings.target and target_mask is None:
            raise GuideError("this guide looks at a target image, but the target has none: run without --guide, "
                             "with one whose features leave the target out (the shipped vines-circuit for vines), "
                             "or train one with --features local, local+partial or constant")
        self.target_pyramid = Pyramid(target_mask.astype(np.float64)) if settings.target else None
        if self.target_pyramid is not None:
            level0 = self.target_pyramid.layout[0]
            self.target_pixels = int(level0[1] * level0[2])
            self.target_total = max(float(self.target_pyramid.flat[:self.target_pixels].sum()), 1.0)
        n_progress = self.n_progress()
        # (lows, spans, angular) of the progress values, for local_features
        self.progress_ranges = (np.zeros(n_progress), np.array([PENDING_SCALE, 1.0][:n_progress]),
                                np.zeros(n_progress, dtype=np.bool_))
        self._local = {}
        self._frame = None  # (xmin, ymin, x scale, y scale, centre) of the output raster

    def n_local(self, rule_name: str) -> int:
        """Number of local-state features of a rule's choices (0 without local features)."""
        if not self.settings.local:
            return 0
        idx, _, _, angular = self.ranges(rule_name)
        return len(idx) + int(angular.sum())

    def n_progress(self) -> int:
        """Number of progress features: the pending calls, then, with a target image, its
        covered fraction (0 without progress features)."""
        return (1 + int(self.settings.target)) if self.settings.progress else 0

    def progress_values(self, state) -> list:
        """The raw progress values of a choice made now (before mapping to [-1, 1])."""
        values = [float(len(state.pending))]
        if self.settings.target:
            partial = partial_pyramid(state)
            check_same_size(self.target_pyramid.layout, partial.layout)
            values.append(self.coverage(partial))
        return values

    def coverage(self, partial: Pyramid) -> float:
        """The fraction of the target's pixels a partial output (of the target's size,
        :func:`check_same_size`) has drawn on."""
        return covered_pixels(partial.flat, self.target_pyramid.flat, self.target_pixels) / self.target_total

    def size(self, rule_name: str) -> int:
        """Length of the feature vector of a rule's choices."""
        n = self.n_local(rule_name) + self.n_progress()
        if self.settings.target:
            n += FEATURES_PER_IMAGE
        if self.settings.partial:
            n += FEATURES_PER_IMAGE
        return n

    def ranges(self, rule_name: str):
        """(argument indices, lows, spans, angular) of a rule's local-state features."""
        ranges = self._local.get(rule_name)
        if ranges is None:
            ranges = local_ranges(self.model, rule_name)
            if ranges is None:
                declared = sorted(self.model.arg_ranges)
                if declared:  # ranges for other rules: this one was likely renamed since the guide was trained
                    raise FeatureSettingsError(f"model {self.model.name!r} declares argument ranges for rule"
                                     f"{'s' if len(declared) > 1 else ''} {', '.join(map(repr, declared[:4]))} but "
                                     f"not {rule_name!r}, whose choices the guide proposes: if the rule was renamed, "
                                     "retrain the guide on the model as it is; else give the Model "
                                     f"arg_ranges={{{rule_name!r}: ((low, high), ...)}}")
                raise FeatureSettingsError(f"model {self.model.name!r} declares no argument ranges for rule "
                                 f"{rule_name!r}; give the Model arg_ranges={{{rule_name!r}: ((low, high), ...)}} "
                                 "or train the guide without local state (--features target+partial)")
            self._local[rule_name] = ranges
        return ranges

    def local_values(self, rule_name: str, args: tuple, heading: float = 0.0) -> np.ndarray:
        """A call's scalar arguments mapped to [-1, 1] by the declared ranges (clipped),
        angles and the reported ``heading`` as (cos, sin)."""
        idx, lows, spans, angular = self.ranges(rule_name)
        if len(idx) and idx.max() >= len(args):  # the model's matter, not a trace's: say so once
            raise FeatureSettingsError(f"model {self.model.name!r} declares {int(idx.max()) + 1} argument ranges for "
                                       f"rule {rule_name!r}, which is called with {len(args)} arguments; give "
                                       "arg_ranges one entry per argument (None for one that is no feature)")
        values = np.array([float(heading) if i == HEADING else float(args[i]) for i in idx])
        out = np.empty(len(idx) + int(angular.sum()))
        local_features(values, lows, spans, angular, out)  # the kernel inference uses
        return out

    def features(self, state, rule_name: str, args: tuple) -> np.ndarray:
        """The feature vector for a choice made now by a call of ``rule_name(args)``."""
        settings = self.settings
        out = np.empty(self.size(rule_name))
        k = 0
        if settings.local:
            local = self.local_values(rule_name, args, heading_of(state))
            k = len(local)
            out[:k] = local
        if settings.progress:
            k += local_features(np.array(self.progress_values(state)), *self.progress_ranges, out[k:])
        if settings.target or settings.partial:
            px, py = self.pixel_position(state)
            if settings.target:
                self.target_pyramid.windows_into(px, py, out, k)
                k += FEATURES_PER_IMAGE
            if settings.partial:
                partial_pyramid(state).windows_into(px, py, out, k)
        return out

    def pixel_position(self, state) -> tuple[float, float]:
        """The current position (``ctx.at``) in the output raster's pixel coordinates
        (the centre of the raster before any position is reported). Every particle of a
        run draws on the same raster frame, so it is worked out once."""
        frame = self._frame
        if frame is None:
            canvas = state.output
            vp = canvas.viewport
            frame = self._frame = (vp.xmin, vp.ymin, canvas.width / (vp.xmax - vp.xmin),
                                   canvas.height / (vp.ymax - vp.ymin),
                                   (0.5 * (vp.xmin + vp.xmax), 0.5 * (vp.ymin + vp.ymax)))
        position = state.position
        if position is None:
            position = frame[4]
        return (position[0] - frame[0]) * frame[2], (position[1] - frame[1]) * frame[3]


def partial_pyramid(state, empty: Pyramid | None = None) -> Pyramid:
    """The pyramid of what ``state`` has drawn, updated only after a new emit and only
    where the emit changed pixels. ``empty``, an empty pyramid made beforehand (the
    target's size, shared by every particle of a run), starts a derivation's first pyramid
    when its raster has that size."""
    cached = state.guide_cache
    if cached is not None and cached[0] == state.n_emits:
        return cached[1]
    canvas = state.output
    if cached is not None:
        previous = cached[1]
    elif empty is not None and empty.layout[0, 1] == canvas.height and empty.layout[0, 2] == canvas.width:
        previous = empty  # never changed: updated() writes a new array
    else:
        previous = Pyramid.empty(canvas.height, canvas.width)
    pyramid = previous.updated(canvas.pixels)
    state.guide_cache = (state.n_emits, pyramid)
    return pyramid
