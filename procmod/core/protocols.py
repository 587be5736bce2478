"""The contracts between procmod's parts: outputs, targets and proposers.

Engines, targets, renderers and guides meet through three kinds of objects, declared here
as :class:`typing.Protocol` classes:

* an :class:`Output` is what a derivation's emits are drawn into (a raster canvas, a
  voxel scene, silhouette rasters); every derivation owns one;
* a :class:`Target` is what engines control a model toward: it places the model, makes
  the output it scores and scores it;
* a :class:`Proposer` draws a derivation's fresh choices instead of the prior (a neural
  guide's proposal).

**Capabilities are declared, not discovered.** What an object can do beyond the required
methods is a class attribute (``supports_removal``, ``dimension``, ``exact_removal``,
...), and code that needs a capability reads the attribute rather than probing with
``hasattr``. A capability that promises more methods comes with a sub-protocol naming
them (:class:`RemovableOutput`, :class:`PartCachingOutput`, :class:`MaskedTarget`,
:class:`OverlayTarget`).

A class of your own either subclasses the protocol, inheriting the defaults given here
(``class MyTarget(procmod.core.Target): ...``), or declares every capability itself.
procmod's own outputs and targets declare theirs without subclassing: a protocol's
metaclass makes ``isinstance`` checks against a class a Python-level call, and the raster
canvas and voxel scene sit on every engine's hot path. :func:`check_declared` refuses,
in one line, an object that declares too little (engines call it once per run).

This module imports nothing of procmod at run time (the annotations are for readers and
type checkers).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, Protocol

if TYPE_CHECKING:
    import numpy as np
    from PIL import Image

    from .distributions import Distribution
    from .model import Model
    from .runtime import Context


class Output(Protocol):
    """What a derivation's emits are drawn into, incrementally (seed 002's "accumulator").

    Capabilities
    ------------
    dimension : int
        ``2``: a 2D raster canvas, i.e. a :class:`procmod.geometry.Canvas` (renderers and
        image targets read its ``viewport``, ``pixels``, ``gain``, ``width`` ...);
        ``3``: 3D parts (boxes, cylinders, meshes: volume and silhouette targets, shaded
        previews, mesh export). Any other value (a test's running sum) is neither. No
        default: every output says what it draws.
    supports_removal : bool
        ``remove(geometry)`` undoes ``add(geometry)`` exactly (see
        :class:`RemovableOutput`), so an offspring's output can be derived from its
        parent's by :func:`procmod.core.runtime.replay_reusing`. Default False.
    supports_part_cache : bool
        ``use_part_cache()`` makes later ``add`` calls look equal parts up instead of
        drawing them again (see :class:`PartCachingOutput`; engines that replay whole
        derivations turn it on). Default False.
    """

    dimension: int
    supports_removal: bool = False
    supports_part_cache: bool = False

    def add(self, geometry) -> int:
        """Draw one emitted primitive or part; returns how much became newly covered
        (pixels, voxels)."""
        ...

    def copy(self) -> "Output":
        """An independent copy, cheap: arrays that copies never write (a target's gains,
        scratch buffers) may be shared."""
        ...


class RemovableOutput(Output, Protocol):
    """An output with ``supports_removal = True``."""

    saturated: bool  # True once a count overflowed: from then on remove refuses (InvalidArgumentError)

    def remove(self, geometry) -> int:
        """Take out geometry added earlier, exactly as if it had never been added (a
        bounding ``extent`` may stay as it was)."""
        ...


class PartCachingOutput(Output, Protocol):
    """An output with ``supports_part_cache = True``."""

    def use_part_cache(self) -> None:
        """Look parts up by value in this process's cache from now on."""
        ...


class Target(Protocol):
    """What an engine controls a model toward (DESIGN.md "Targets").

    ``score`` is the figure a person reads (a similarity, a fitness); ``log_likelihood``
    is what probabilistic engines weight by. Both read an output made by ``new_output``
    and, on partial outputs, cost O(what the last emit changed).

    Capabilities
    ------------
    exact_removal : bool
        ``score`` and ``log_likelihood`` read only what the output's ``remove`` restores
        exactly, so the GA may score an offspring from its parent's output with parts
        taken out and added (Volume, Silhouette; not ProxyVolume, which reads the
        bounding box ``remove`` does not shrink). Default False.
    has_mask : bool
        ``mask(width, height)`` gives the boolean target image a neural guide looks at
        (see :class:`MaskedTarget`). Default False.
    has_overlay : bool
        ``overlay_image(output, index, width)`` draws a result over the target for reports
        (see :class:`OverlayTarget`). Default False.
    """

    name: str
    exact_removal: bool = False
    has_mask: bool = False
    has_overlay: bool = False

    def configure(self, model: "Model") -> "Model":
        """``model`` as this target wants it (e.g. placed at the target's start point)."""
        ...

    def new_output(self, model: "Model") -> Output:
        """An empty output of the configured ``model`` that keeps this target's running
        sums; refuses (InvalidArgumentError) a model the target cannot score."""
        ...

    def score(self, output) -> float:
        """The human-readable figure of ``output`` (higher is better)."""
        ...

    def log_likelihood(self, output) -> float:
        """``log p(target | output)`` up to a constant; ``-inf`` for an impossible output."""
        ...

    def display_mask(self, width: int) -> "np.ndarray | None":
        """The target picture to draw results over, ``width`` pixels wide, or None (the
        default: no picture)."""
        return None


class MaskedTarget(Target, Protocol):
    """A target with ``has_mask = True``."""

    def mask(self, width: int, height: int) -> "np.ndarray":
        """The boolean target image at a canvas size."""
        ...


class OverlayTarget(Target, Protocol):
    """A target with ``has_overlay = True``."""

    def overlay_image(self, output, index: int = 0, width: int = 256) -> "Image.Image":
        """A picture of ``output`` over view ``index`` of the target."""
        ...


class Proposer(Protocol):
    """Draws a derivation's fresh choices instead of the prior (a neural guide's proposal).

    Installed as ``derivation.proposer`` (:func:`procmod.infer.smc` does it for a guide),
    which gives the derivation a :class:`~procmod.core.runtime.GuidedPolicy`: the runtime
    calls :meth:`propose` for every fresh choice and adds the returned log-density to
    ``derivation.log_proposal``, so engines weight by prior / proposal. ``ctx.derivation`` is the derivation as built so far (its output, position,
    emit count); a proposer may keep per-derivation state in ``derivation.guide_cache``,
    which copies share, so it replaces the value rather than mutating it.
    """

    def propose(self, ctx: "Context", name: str, dist: "Distribution", rng) -> tuple[Any, float]:
        """``(value, log q(value))`` for the choice ``name`` of the call ``ctx``, whose prior
        is ``dist``; ``value`` must lie in ``dist``'s support."""
        ...


# The capabilities of each protocol, and what each promises when it is True.
_CAPABILITIES = {
    Output: ("dimension", "supports_removal", "supports_part_cache"),
    Target: ("exact_removal", "has_mask", "has_overlay"),
}
_PROMISES = {
    "supports_removal": ("remove", "saturated"),
    "supports_part_cache": ("use_part_cache",),
    "has_mask": ("mask",),
    "has_overlay": ("overlay_image",),
}
# The methods every object of a protocol defines itself: a subclass that leaves one out
# inherits the protocol's empty body, which returns None (a misnamed ``add`` dropped every
# emit without a word; a missing ``copy`` failed later in the user's own score).
_METHODS = {
    Output: ("add", "copy"),
    Target: ("configure", "new_output", "score", "log_likelihood"),
}
_MISSING = object()


def check_declared(obj, protocol, what: str) -> None:
    """Refuse ``obj`` unless it declares every capability of ``protocol`` (:class:`Output`
    or :class:`Target`) and has the members each capability it claims promises.

    Raises
    ------
    InvalidArgumentError
        Naming ``what`` (e.g. "the target"), the class and what it lacks.
    """
    from .errors import InvalidArgumentError

    name = type(obj).__name__
    missing = [c for c in _CAPABILITIES[protocol] if getattr(obj, c, _MISSING) is _MISSING]
    if missing:
        raise InvalidArgumentError(
            f"{what} ({name}) does not declare {', '.join(missing)}: subclass procmod.core.{protocol.__name__}, "
            "which gives the defaults, or set them as class attributes")
    for capability, members in _PROMISES.items():
        if capability in _CAPABILITIES[protocol] and getattr(obj, capability):
            lacking = [m for m in members if getattr(obj, m, _MISSING) is _MISSING]
            if lacking:
                raise InvalidArgumentError(f"{what} ({name}) declares {capability} but has no "
                                           f"{', '.join(lacking)}")
    # what the object resolves (a method set on the instance, a wrapper's __getattr__): the
    # protocol's own empty function only when nothing overrides it
    absent = [m for m in _METHODS[protocol] if not callable(getattr(obj, m, None))]
    if absent:  # (a class that does not subclass the protocol and leaves one out: h82, Output.copy)
        raise InvalidArgumentError(f"{what} ({name}) has no method {', '.join(absent)} that "
                                   f"procmod.core.{protocol.__name__} requires; define "
                                   f"{'it' if len(absent) == 1 else 'them'}")
    empty = [m for m in _METHODS[protocol]
             if getattr(getattr(obj, m, None), "__func__", None) is getattr(protocol, m)]
    if empty:
        raise InvalidArgumentError(f"{what} ({name}) does not define {', '.join(empty)} (it would inherit "
                                   f"procmod.core.{protocol.__name__}'s, which does nothing); define "
                                   f"{'it' if len(empty) == 1 else 'them'}")


__all__ = ["MaskedTarget", "Output", "OverlayTarget", "PartCachingOutput", "Proposer", "RemovableOutput",
           "Target", "check_declared"]
