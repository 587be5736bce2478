"""A trained guide (networks + metadata), its file format, and the proposers that use it.

Files: ``NAME.pt`` holds the networks' torch state dict (tensors only, loaded with
``weights_only=True``); ``NAME.json`` (``procmod-guide/1``) says which model the guide is
for, its feature settings, mixture size and sites, and how it was trained; ``NAME.npz``
holds the same weights as plain arrays (``numpy.load`` without pickles), its digest in
the metadata (``numpy_weights``), so that running a guide needs no torch: importing torch
takes seconds, longer than a 10-particle guided run. A guide without it (or whose
``.npz`` does not match its digest) is read from the ``.pt``, which must match its own
digest (``torch_weights``) where the metadata records one.
"""

from __future__ import annotations

import io
import json
import math
import os
import re
from pathlib import Path

import numpy as np

from ..core.distributions import Normal, TruncatedNormal
from ..core.errors import argument, cut_text, plain_value, shown_value, whole_number
from ..core.io import check_format, fingerprint, load_tensors, read_json, save_tensors, write_bytes_atomic, write_text_atomic
from ..core.limits import check_memory
from ..core.choicemap import format_address
from ..core.runtime import rule_name
from .fast import guided_draw, pack_site, site_outputs
from .features import (HEADING, SOURCES, FeatureExtractor, FeatureSettings, GuideError, Pyramid, check_same_size,
                       covered_pixels, heading_of, partial_pyramid, with_defaults)
from .network import base_params, encode_value, head_kind, initial_bias, n_outputs, propose

FORMAT = "procmod-guide/1"
MAX_MIXTURE = 64  # Gaussian components per continuous choice (the papers use 4)
MAX_FEATURES = 100_000  # inputs of one site network (the built-in models have under 200)
MAX_CATEGORIES = 100_000


def check_mixture(mixture, where: str = "mixture") -> int:
    """``mixture`` if it is an integer in [1, MAX_MIXTURE], else a GuideError naming ``where``."""
    components = whole_number(mixture)
    if components is None or not 1 <= components <= MAX_MIXTURE:
        raise GuideError(f"{argument(where)} must be a whole number of Gaussian components from 1 to {MAX_MIXTURE}, "
                         f"got {shown_value(mixture)}")
    return components


def _site_kind(kind, where: str) -> str:
    if kind in ("real", "interval", "bernoulli"):
        return kind
    match = re.fullmatch(r"categorical:(\d{1,7})", kind) if isinstance(kind, str) else None
    if match is None or not 2 <= int(match.group(1)) <= MAX_CATEGORIES:
        raise GuideError(f"{where}.kind must be real, interval, bernoulli or categorical:K (2 <= K <= "
                         f"{MAX_CATEGORIES}), got {shown_value(kind)}")
    return kind


def weight_shapes(n_in: int, n_out: int) -> list[tuple]:
    """Shapes of a site network's (W1, b1, W2, b2): n_in -> tanh(max(n_in // 2, 1)) ->
    n_out, or a constant vector (empty W1, b1, W2) when it has no inputs
    (:meth:`~procmod.guide.nets.SiteNet.numpy_weights`)."""
    if n_in == 0:
        return [(0, 0), (0,), (n_out, 0), (n_out,)]
    hidden = max(n_in // 2, 1)
    return [(hidden, n_in), (hidden,), (n_out, hidden), (n_out,)]


def check_metadata(data, source: str) -> dict:
    """The fields of a ``procmod-guide/1`` metadata object, each checked, or a GuideError
    in one line naming the file and the field. The networks' total size is checked
    against the machine's memory before any is built."""
    check_format(data, FORMAT, source, GuideError)
    if not isinstance(data.get("model"), str):
        raise GuideError(f"{source}: model must be a model name, got {shown_value(data.get('model'))}")
    features = data.get("features")
    if (not isinstance(features, dict) or not {"local", "target", "partial"} <= set(features) <= set(SOURCES)
            or not all(isinstance(v, bool) for v in features.values())):
        raise GuideError(f"{source}: features must be {{\"local\": bool, \"target\": bool, \"partial\": bool}} "
                         f"(and optionally \"progress\": bool), got {shown_value(features)}")
    mixture = check_mixture(data.get("mixture"), f"{source}: mixture")
    sites = data.get("sites")
    if not isinstance(sites, dict):
        raise GuideError(f"{source}: sites must be an object (site -> kind, n_in, n_out)")
    weights = 0
    for key, spec in sites.items():
        where = f"{source}: sites[{shown_value(key)}]"
        if not isinstance(spec, dict) or ":" not in key:
            raise GuideError(f"{where} must be an object {{kind, n_in, n_out}} under a 'rule:choice' name")
        kind = _site_kind(spec.get("kind"), where)
        n_in = spec.get("n_in")
        if isinstance(n_in, bool) or not isinstance(n_in, int) or not 0 <= n_in <= MAX_FEATURES:
            raise GuideError(f"{where}.n_in must be a whole number of features from 0 to {MAX_FEATURES}, "
                             f"got {shown_value(n_in)}")
        n_out = n_outputs(kind, mixture)
        if spec.get("n_out") != n_out:
            raise GuideError(f"{where}.n_out must be {n_out} for a {kind} site with mixture {mixture}, "
                             f"got {shown_value(spec.get('n_out'))}")
        labels = spec.get("labels")
        if labels is not None and not kind.startswith("categorical"):
            raise GuideError(f"{where} draws a {kind} choice, which has no labels; remove its \"labels\" (a "
                             "categorical site's labels are the ones it was trained on)")
        if labels is not None and not (
                isinstance(labels, list) and len(labels) == n_out
                and all(isinstance(v, (str, int, bool)) or (isinstance(v, float) and math.isfinite(v)) for v in labels)
                and len(set(label_codes(labels))) == n_out):
            raise GuideError(f"{where}.labels must be a categorical site's {n_out} distinct labels (strings, numbers "
                             f"or bools), got {shown_value(labels)}")
        weights += sum(math.prod(shape) for shape in weight_shapes(n_in, n_out))
    check_memory(f"{source}: the guide's networks", 8.0 * weights * 3, "the metadata is not a guide procmod wrote")
    if data.get("info") is not None and not isinstance(data.get("info"), dict):
        raise GuideError(f"{source}: info must be an object")
    return data


def site_key(rule_name: str, choice: str) -> str:
    """The name of a random-choice site: ``rule:choice``."""
    return f"{rule_name}:{choice}"


class Guide:
    """Networks for every site of one model, with the settings they were trained under.

    Parameters
    ----------
    model_name : str
        The model the guide was trained for.
    settings : FeatureSettings
    mixture : int
        Gaussian components per continuous choice (1 = no mixture).
    sites : dict
        ``site key -> {"kind": ..., "n_in": ..., "n_out": ...}``.
    seed : int
        Seeds the networks' initial weights.
    info : dict
        Free-form training record (traces, iterations, loss) saved in the metadata.
    """

    def __init__(self, model_name: str, settings: FeatureSettings, mixture: int, sites: dict,
                 seed: int = 0, info: dict | None = None):
        check_mixture(mixture)
        self.model_name = model_name
        self.settings = settings
        self.mixture = mixture
        self.sites = dict(sites)
        self.info = dict(info or {})
        self.source = None  # the name or path Guide.load read it by
        self._seed = seed
        self._nets = None  # torch modules, built on first use (training, saving)
        self._numpy = None

    @property
    def nets(self):
        """The site networks (``torch.nn.ModuleDict``), built on first use: a guide read for
        inference only (:meth:`load` with a matching ``.npz``) never imports torch."""
        if self._nets is None:
            import torch

            from .nets import SiteNet

            generator = torch.Generator().manual_seed(self._seed)
            nets = torch.nn.ModuleDict({
                key: SiteNet(spec["n_in"], spec["n_out"], initial_bias(spec["kind"], self.mixture), generator)
                for key, spec in sorted(self.sites.items())})
            if self._numpy is not None:  # read from the .npz only: the networks take its weights
                for key, net in nets.items():
                    net.set_numpy_weights(self._numpy[key])
            self._nets = nets
        return self._nets

    # ---- files ---------------------------------------------------------------------

    def metadata(self) -> dict:
        return {"format": FORMAT, "model": self.model_name, "features": self.settings.to_json(),
                "mixture": self.mixture, "sites": self.sites, "info": self.info}

    def save(self, path: str | os.PathLike) -> tuple[Path, Path]:
        """Write ``STEM.pt``, ``STEM.npz`` and ``STEM.json`` (each atomically, the metadata
        last); returns the ``.pt`` and ``.json`` paths. A bare shipped guide's name is a
        file in the current folder here (:func:`guide_paths`)."""
        weights, meta = guide_paths(path, for_writing=True)
        weights.parent.mkdir(parents=True, exist_ok=True)
        save_tensors(self.nets.state_dict(), weights)
        self.invalidate()
        buffer = io.BytesIO()
        np.savez(buffer, **{f"{key}|{i}": a for key, arrays in sorted(self.numpy_weights().items())
                            for i, a in enumerate(arrays)})
        arrays = buffer.getvalue()
        write_bytes_atomic(weights.with_suffix(".npz"), arrays)
        data = self.metadata()
        data["numpy_weights"] = {"sha256_16": fingerprint(arrays)}  # of STEM.npz
        data["torch_weights"] = {"sha256_16": fingerprint(weights.read_bytes())}  # of STEM.pt
        write_text_atomic(meta, json.dumps(data, indent=1) + "\n")
        return weights, meta

    @classmethod
    def load(cls, path: str | os.PathLike) -> "Guide":
        """Read a guide saved by :meth:`save` (``STEM``, ``STEM.pt`` or ``STEM.json``)."""
        if not isinstance(path, (str, os.PathLike)):
            raise GuideError(f"a guide is given by its name or path, got {type(path).__name__} {path!r:.40}")
        weights, meta = guide_paths(path)
        if Path(path).is_dir() and not meta.is_file():  # it would be read as the guide FOLDER.json
            raise GuideError(f"{shown_value(str(path))} is a folder, not a guide: give the guide's NAME.json (with "
                             "its .npz or .pt beside it, as 'procmod guide train' wrote them), or a shipped guide's "
                             f"name ({', '.join(pretrained_guides()) or 'none'})")

        def check_file(p: Path) -> None:
            if p.exists() and not p.is_file():
                raise GuideError(f"guide file {p} is not a regular file (a folder, a device or a pipe); a guide is "
                                 "a .json with its .npz (or .pt), written by 'procmod guide train'")
            if not p.is_file():
                shipped = ", ".join(pretrained_guides()) or "none"
                raise GuideError(f"guide file {p} does not exist (a guide is a .json with its .npz or .pt, "
                                 f"written by 'procmod guide train', or a shipped guide: {shipped})")

        check_file(meta)
        metadata = read_json(meta, GuideError, "guide metadata")  # an empty or broken .json: said first
        npz = weights.with_suffix(".npz")
        if not weights.exists() and not npz.exists():  # (a matching .npz alone runs the guide; the .pt: to train on)
            raise GuideError(f"guide {meta} has no weights beside it: neither {npz.name} nor {weights.name} is there; "
                             "a guide is its .json with the .npz (or .pt) that 'procmod guide train' wrote: keep them "
                             "together")
        if weights.exists():
            check_file(weights)
        data = check_metadata(metadata, str(meta))
        settings = FeatureSettings(**data["features"])
        guide = cls(data["model"], settings, data["mixture"], data["sites"], 0, data.get("info"))
        guide.source = str(path)  # as the user named it: a run's settings record it
        guide._numpy = _numpy_weights(data, weights.with_suffix(".npz"))
        if guide._numpy is not None:
            return guide
        if not weights.exists():
            raise GuideError(f"{npz} is not the weights written with {meta.name} (another guide's, or changed since), "
                             f"and there is no {weights.name} to read instead; keep the files that 'procmod guide "
                             "train' wrote together")
        check_file(weights)  # the .npz does not match this .json: only the .pt can say
        recorded = data.get("torch_weights")  # (guides saved before it was recorded: unchecked)
        if isinstance(recorded, dict) and recorded.get("sha256_16") != fingerprint(weights.read_bytes()):
            raise GuideError(f"{weights} is not the weights written with {meta.name} (another guide's, or changed "
                             "since); keep the files that 'procmod guide train' wrote together")
        state = load_tensors(weights, GuideError, "guide's weights", "; use a guide written by 'procmod guide train'")
        try:  # no matching .npz: the .pt (torch)
            guide.nets.load_state_dict(state)
        except (RuntimeError, KeyError, TypeError, AttributeError) as exc:
            first = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
            raise GuideError(f"{weights}: the weights do not match {weights.with_suffix('.json').name} "
                             f"({cut_text(first, 160)}); keep the files that 'procmod guide train' wrote "
                             "together") from None
        if not all(bool(p.isfinite().all()) for p in guide.nets.parameters()):
            raise GuideError(f"{weights}: the weights are not all finite numbers (a training that diverged); "
                             "train the guide again with a smaller learning rate")
        return guide

    # ---- use -----------------------------------------------------------------------

    def check_model(self, model) -> None:
        """Raise a :class:`GuideError` unless the guide was trained for ``model``."""
        if model.name != self.model_name:
            from ..models import MODELS
            if getattr(model.new_output(), "dimension", 2) != 2:  # the advice below cannot be followed
                raise GuideError(f"this guide was trained for model {self.model_name!r}, not {model.name!r}; and "
                                 "guides exist for 2D models only (a guide reads windows of a target picture and of "
                                 f"the partial drawing, seed 004): run {model.name!r} without --guide")
            advice = (f"train one with 'procmod guide train {model.name} ...'" if model.name in MODELS else
                      "train one for it with 'procmod guide traces FILE.py:NAME' then 'procmod guide train "
                      "FILE.py:NAME' (README, \"Neural guides\"), or run it without --guide")
            raise GuideError(f"this guide was trained for model {self.model_name!r}, not {model.name!r}; {advice}")

    def numpy_weights(self) -> dict:
        """Per-site numpy weights for fast one-choice-at-a-time inference (cached)."""
        if self._numpy is None:
            self._numpy = {key: net.numpy_weights() for key, net in self.nets.items()}
        return self._numpy

    def invalidate(self) -> None:
        """Forget cached numpy weights (after training changed the networks)."""
        self.nets  # a guide read from its .npz holds its weights only there: build the nets first
        self._numpy = None

    def proposer(self, model, target) -> "GuidedProposer":
        """A proposer for derivations of ``model`` (already configured by the target) under
        ``target``, whose mask (if it has one) the networks look at."""
        self.check_model(model)
        return GuidedProposer(self, FeatureExtractor(model, self.settings, target_mask_for(target, model)))


def _numpy_weights(data: dict, path: Path) -> dict | None:
    """The per-site ``(W1, b1, W2, b2)`` of a guide's ``.npz``, or None when the metadata
    names none, the file is missing or not the one the metadata's digest names, or its
    arrays do not have the sites' shapes (the caller then reads the ``.pt``)."""
    named = data.get("numpy_weights")
    if not isinstance(named, dict) or not path.is_file():
        return None
    count = sum(math.prod(shape) for s in data["sites"].values() for shape in weight_shapes(s["n_in"], s["n_out"]))
    if path.stat().st_size > 16 * count + (1 << 20):  # not these networks' weights (and not read)
        return None
    raw = path.read_bytes()
    if fingerprint(raw) != named.get("sha256_16"):
        return None
    try:
        with np.load(io.BytesIO(raw), allow_pickle=False) as arrays:
            stored = {name: arrays[name] for name in arrays.files}
    except (ValueError, OSError, EOFError, KeyError):
        return None
    out = {}
    for key, spec in data["sites"].items():
        parts = [stored.get(f"{key}|{i}") for i in range(4)]
        if any(p is None or p.dtype != np.float64 for p in parts):
            return None
        if [p.shape for p in parts] != weight_shapes(spec["n_in"], spec["n_out"]) or not all(np.isfinite(p).all() for p in parts):
            return None
        out[key] = tuple(np.ascontiguousarray(p) for p in parts)
    return out


PRETRAINED = Path(__file__).resolve().parent / "pretrained"
DRAW_BLOCK = 256  # random numbers a proposer draws from the run's generator at a time (at most)
FIRST_DRAWS = 32  # ... and in its first block from a generator (see GuidedProposer._draws)


def pretrained_guides() -> list[str]:
    """Names of the guides shipped with procmod (usable wherever a guide path is)."""
    return sorted(p.stem for p in PRETRAINED.glob("*.json"))


def target_mask_for(target, model) -> np.ndarray | None:
    """The target's mask at the resolution ``model`` draws at (None for image-free targets)."""
    if target is None or not target.has_mask:
        return None
    canvas = model.new_output()
    return target.mask(canvas.width, canvas.height)


def shadowing_note(path: str | os.PathLike) -> str | None:
    """A note when ``path``, a shipped guide's bare name, reads a guide of the current
    folder instead (one trained with ``--out`` that name, as the README's recipe to
    retrain a shipped guide does): the same command gave another result in another folder."""
    if str(path).startswith(("./", ".\\")):  # the folder's guide, said so (pathlib drops the "./")
        return None
    path = Path(path)
    if len(path.parts) != 1 or path.name not in pretrained_guides():
        return None
    weights, meta = guide_paths(path)
    if meta.parent == PRETRAINED:
        return None
    return (f"--guide {path.name} reads {meta.name} of this folder, a guide trained here, not the shipped guide of "
            f"that name (give ./{path.name} to say so; rename it to use the shipped one here)")


def target_kind(target) -> str:
    """What a guide records of the targets it was trained on, and compares with a run's:
    ``picture`` (a target image), ``circuit``, or the target's class name."""
    from ..targets.circuit import Circuit
    from ..targets.shape import ShapeMatch

    if isinstance(target, ShapeMatch):
        return "picture"
    if isinstance(target, Circuit):
        return "circuit"
    return type(target).__name__


def output_size(output) -> list | None:
    """``[width, height]`` of a raster output (a guide's features are windows of it), else None."""
    width, height = getattr(output, "width", None), getattr(output, "height", None)
    return [width, height] if isinstance(width, int) and isinstance(height, int) else None


def fit_note(guide: "Guide", output, target, model=None) -> str | None:
    """A note when a run's drawing size or kind of target is not what ``guide`` was
    trained on (its ``info["trained_on"]``; guides trained before it was recorded: None),
    or when the code of ``model``, a model file of the user's, is not what the guide's
    traces were made with (a categorical's labels reordered steered the choices to the
    wrong labels without a word: worse than no guide, h70). The networks read windows of
    the target and of the drawing by pixel, and learned what choices the training targets
    favour: the run is still correct (its weights are prior over proposal), but the guide
    may steer it worse than the prior would."""
    said = []
    if model is not None and _model_file_changed(guide.info.get("trace_job"), model):
        said.append("its model's files changed after its traces were made (a choice renamed, or whose meaning "
                    "changed, is steered as the guide learned it)")
    sized = False
    trained = guide.info.get("trained_on")
    if not isinstance(trained, dict):
        trained = {}
    sizes, size = trained.get("canvases"), output_size(output)
    sizes = [s for s in sizes if isinstance(s, list) and len(s) == 2] if isinstance(sizes, list) else []
    if sizes and size is not None and size not in sizes:
        shown = ", ".join(f"{w}x{h}" for w, h in sizes[:3]) + (", ..." if len(sizes) > 3 else "")
        said.append(f"it was trained on {shown}-pixel drawings and this run draws at {size[0]}x{size[1]} (its "
                     "windows now cover other distances)")
        sized = True
    kinds, kind = trained.get("targets"), target_kind(target)
    if isinstance(kinds, list) and kinds and kind not in kinds:
        said.append(f"it was trained on {' and '.join(map(str, kinds[:3]))} targets and this run's is a {kind}")
    if not said:
        return None
    return (f"guide {guide.source or guide.model_name}: {'; '.join(said)}: it may steer worse than no guide; train "
            "one on traces of this kind (procmod guide traces, then procmod guide train"
            + (" at this run's parameter values: guide traces takes --param, none for the defaults)" if sized
               else ")"))


def _model_file_changed(job, model) -> bool:
    """Whether a guide's traces (``job``: its ``info["trace_job"]``) were made from a model
    file of the user's whose code ``model`` no longer has. The job's digest covers the
    model file and its rules' files: it is taken again both with the job's file (rules in
    a module beside it) and without it (the file copied elsewhere, the rules in it); a file
    gone since cannot be compared. Built-in models are not compared (not the user's to edit)."""
    from .traces import model_code_digests, model_file_path

    if not isinstance(job, dict) or not isinstance(job.get("model_code"), str) or not job.get("model_file"):
        return False
    spec = str(job["model_file"])
    if not model_file_path(spec).is_file():
        return job["model_code"] not in model_code_digests(model)
    return job["model_code"] not in (*model_code_digests(model), *model_code_digests(model, spec))


def guide_paths(path: str | os.PathLike, for_writing: bool = False) -> tuple[Path, Path]:
    """(weights .pt, metadata .json) for a guide path given with or without a suffix, or,
    to read, the name of a shipped guide (e.g. ``vines-scribbles``). A path to write
    (``for_writing``) is always the path as given: a bare shipped name writes into the
    current folder, never over the guides shipped inside the package."""
    path = Path(path)
    if path.name in ("", ".", ".."):  # '', '.', '/', '..': a folder, no file name to add .pt to
        raise GuideError(f"{shown_value(str(path))} is not a guide's name or path: give NAME, NAME.pt or NAME.json "
                         "(the pair 'procmod guide train' writes), or a shipped guide's name")
    if not for_writing and path.name in pretrained_guides() \
            and not path.with_name(path.name + ".json").exists() and len(path.parts) == 1:
        path = PRETRAINED / path.name
    stem = path.with_suffix("") if path.suffix.lower() in (".pt", ".json", ".npz") else path
    return stem.with_name(stem.name + ".pt"), stem.with_name(stem.name + ".json")


class GuidedProposer:
    """Proposes each fresh choice from the guide's network for its site.

    Installed as ``derivation.proposer``; the runtime adds each proposal's log-density to
    ``derivation.log_proposal`` so engines can weight by prior / proposal.
    """

    def __init__(self, guide: Guide, extractor: FeatureExtractor):
        self.guide = guide
        self.extractor = extractor
        self.mixture = guide.mixture
        settings = extractor.settings
        self._use_local, self._use_target, self._use_partial = settings.local, settings.target, settings.partial
        self._target_flat = extractor.target_pyramid.flat if settings.target else np.zeros(1)
        self._layout = extractor.target_pyramid.layout if settings.target else np.zeros((4, 3), dtype=np.int64)
        # every particle's first partial-output pyramid, made before the engine's clock starts
        # (its layout is the target's own object: _inputs then skips the size comparison)
        self._empty_partial = (Pyramid(flat=np.zeros_like(self._target_flat), layout=self._layout)
                               if settings.target else None)
        self._no_local = np.zeros(0)
        # progress features (features.py): the pending calls, and the target's covered fraction
        self._n_progress = n_progress = extractor.n_progress()
        self._coverage_of = (None, 0.0)  # (partial-output pyramid, its covered fraction)
        weights = guide.numpy_weights()
        self._sites = {}
        local = {}  # rule -> its local-state layout, shared by the rule's sites
        raws = {}  # rule -> the array its sites' raw local values are written into (see _inputs)
        for key, spec in guide.sites.items():
            rule_name, choice = key.split(":", 1)
            n_in = extractor.size(rule_name)
            if n_in != spec["n_in"]:
                raise GuideError(f"site {key} of the guide expects {spec['n_in']} features but the model "
                                 f"gives {n_in}; the model's arguments changed since the guide was trained")
            if rule_name not in local:
                local[rule_name] = self._local_layout(extractor, rule_name) if settings.local else (
                    self._no_local, self._no_local, self._no_local, np.zeros(0, dtype=np.bool_), 0, False)
            arg_idx, lows, spans, angular, prefix, heading = local[rule_name]
            if n_progress:  # the progress values follow the local state in the raw values
                lows, spans, angular = (np.concatenate(pair) for pair in zip((lows, spans, angular),
                                                                             extractor.progress_ranges))
            params = pack_site(lows, spans, angular, weights[key], self._use_target, self._use_partial)
            raw = raws.setdefault(rule_name, np.zeros(len(lows)))
            # [kind, packed ranges + network (fast.pack_site), argument indices, prefix length
            #  (None: gather by index), distribution class last checked against the kind
            #  (None: not yet), whether the heading follows the arguments, the rule's raw values,
            #  how many arguments the features read (a call with fewer takes the rule's defaults),
            #  a categorical's labels as trained (label_codes; None: not recorded)]
            needed = int(max(arg_idx)) + 1 if len(arg_idx) else 0
            labels = spec.get("labels")
            self._sites[(rule_name, choice)] = [spec["kind"], params, arg_idx, prefix, None, heading, raw, needed,
                                                None if labels is None else label_codes(labels)]
        self._by_rule = {}  # (rule function, choice) -> its site (or None): the hot path's lookup
        self._bases = {}  # shared discrete distributions -> their base parameters
        # (site, categorical) -> (its base parameters in the order the site's network learned,
        # the index in the categorical's labels of each of the network's outputs, or None
        # where the orders agree); see propose
        self._categories = {}
        self._relabelled = set()  # sites whose labels are not the ones they were trained on (see relabelled_note)
        self._raw_of = (None, None)  # (call arguments, the raw-values array they were written into)
        self._draws_of = None  # see _draws
        self._uniforms = self._normals = ()
        self._next_draw = 0
        self._load_kernels()

    def _load_kernels(self) -> None:
        """Call each kernel the sites will use once, with the argument types they will
        pass: numba loads a kernel's machine code at its first call (~10 ms each), and the
        proposer is made before an engine starts its clock (see :mod:`procmod.core.kernels`)."""
        for kind, params, *_ in self._sites.values():  # after the first proposer, ~2 us a site
            raw = np.zeros(int(params[0]))  # the site's local values, all at their ranges' centres
            inputs = (raw, params, self._target_flat, self._target_flat, self._layout, 0.0, 0.0)
            if kind == "interval":
                site_outputs(*inputs)
            else:
                code = {"real": 0, "bernoulli": 1}.get(kind, 2)
                base = self._no_local if kind == "real" else np.zeros(n_outputs(kind, self.mixture))
                guided_draw(code, self.mixture, 0.0, 1.0, base, 0.5, 0.0, *inputs)
        if self._use_partial or self._n_progress == 2:
            Pyramid.empty(1, 1).updated(np.zeros(1, dtype=np.uint8))
        if self._n_progress == 2:
            covered_pixels(self._target_flat, self._target_flat, 0)

    @staticmethod
    def _local_layout(extractor, rule_name: str) -> tuple:
        """(argument indices, lows, spans, angular, prefix, heading) of a rule's local state."""
        idx, lows, spans, angular = extractor.ranges(rule_name)
        heading = len(idx) > 0 and idx[-1] == HEADING
        arg_idx = idx[:-1] if heading else idx
        # the common case, the first n arguments, takes a slice of the call's tuple
        prefix = len(arg_idx) if np.array_equal(arg_idx, np.arange(len(arg_idx))) else None
        return arg_idx, lows, spans, angular, prefix, heading

    def _inputs(self, state, site, args: tuple) -> tuple:
        """The kernel arguments after the draw's own (features' sources + packed network)
        of a choice made now."""
        prefix, heading, n_progress = site[3], site[5], self._n_progress
        if not prefix and prefix is not None and not heading and not n_progress:
            raw = self._no_local
        elif args is self._raw_of[0] and site[6] is self._raw_of[1]:
            raw = site[6]  # another choice of the same call: its arguments are there already
        else:
            # written into the rule's one array (the kernel reads it during the call only):
            # a new array a call cost ~4-6% of a guided run (in-run A/Bs, same results)
            raw = site[6]
            if prefix is None:
                for j, i in enumerate(site[2]):
                    raw[j] = args[i]
            else:
                raw[:prefix] = args[:prefix]
            # holding ``args`` keeps its identity from being reused by a later call's tuple
            self._raw_of = (args, raw)
        pyramid = None
        if self._use_partial or n_progress == 2:
            pyramid = partial_pyramid(state, self._empty_partial)
            if self._use_target and pyramid.layout is not self._layout:
                # the kernels read both pyramids by the target's layout: sizes must agree
                check_same_size(self._layout, pyramid.layout)
                self._layout = pyramid.layout  # same sizes: later calls skip the comparison
        if heading:  # the heading may turn between two choices of one call
            raw[len(raw) - 1 - n_progress] = heading_of(state)
        if n_progress:  # so may the pending calls and the coverage (an emit between choices)
            self._fill_progress(state, raw, pyramid)
        if self._use_target or self._use_partial:
            px, py = self.extractor.pixel_position(state)
        else:
            px = py = 0.0
        if self._use_partial:
            partial, layout = pyramid.flat, pyramid.layout
        else:
            partial, layout = self._target_flat, self._layout
        return raw, site[1], self._target_flat, partial, layout, px, py

    def _fill_progress(self, state, raw: np.ndarray, pyramid) -> None:
        """Write the progress values (:meth:`FeatureExtractor.progress_values`) into the
        end of ``raw``; the coverage is worked out once per partial-output ``pyramid``."""
        n = self._n_progress
        raw[len(raw) - n] = len(state.pending)
        if n == 2:
            if pyramid is not self._coverage_of[0]:  # sizes were checked in _inputs
                self._coverage_of = (pyramid, self.extractor.coverage(pyramid))
            raw[-1] = self._coverage_of[1]

    def outputs(self, state, site, args: tuple) -> np.ndarray:
        """The site network's outputs for a choice made now (the fused fast path)."""
        return site_outputs(*self._inputs(state, site, args))

    def propose(self, ctx, name, dist, rng):
        key = (ctx.rule, name)
        site = self._by_rule.get(key, False)
        if site is False:  # first time this rule function makes this choice
            if len(self._by_rule) > 4096:  # a model that builds its rules afresh: don't grow forever
                self._by_rule.clear()
            site = self._by_rule[key] = self._sites.get((rule_name(ctx.rule), name))
        if site is None:  # never seen in training: the prior
            value = dist.sample(rng)
            return value, dist.log_prob(value)
        kind = site[0]
        args = ctx.args
        if len(args) < site[7]:  # a call that leaves arguments to the rule's defaults
            args = with_defaults(ctx.rule, args)
        if type(dist) is not site[4]:
            if head_kind(dist) != kind:
                now = head_kind(dist)
                if now.startswith("categorical") and kind.startswith("categorical"):  # a category added or removed
                    raise GuideError(f"site {site_key(rule_name(ctx.rule), name)} draws a Categorical of "
                                     f"{now.split(':')[1]} categories now, of {kind.split(':')[1]} when the guide was "
                                     "trained; retrain the guide")
                article = "an" if kind[0] in "aeiou" else "a"
                raise GuideError(f"site {site_key(rule_name(ctx.rule), name)} draws a {type(dist).__name__} now but the "
                                 f"guide learned {article} {kind} proposal for it; retrain the guide")
            # the class settles the kind, except a categorical's size and a truncated normal's
            # bounds (finite: interval; half-open: real): those are checked every time
            if not kind.startswith("categorical") and type(dist) is not TruncatedNormal:
                site[4] = type(dist)
        if kind == "real" and type(dist) is TruncatedNormal:  # one-sided: the mixture cut to its support
            out = self.outputs(ctx.derivation, site, args)
            return propose(kind, self.mixture, out, base_params(kind, dist), dist, rng)
        if kind == "real":
            mu0, s0 = (dist.mu, dist.sigma) if type(dist) is Normal else base_params(kind, dist)
            u, z = self._draws(rng)
            return guided_draw(0, self.mixture, mu0, s0, self._no_local, u, z,
                               *self._inputs(ctx.derivation, site, args))
        if kind == "interval":
            out = self.outputs(ctx.derivation, site, args)
            return propose(kind, self.mixture, out, base_params(kind, dist), dist, rng)
        if kind == "bernoulli":
            base = self._bases.get(dist)
            if base is None:
                if len(self._bases) > 4096:  # a model that builds its coins afresh: don't grow forever
                    self._bases.clear()
                base = self._bases[dist] = np.array(base_params(kind, dist), dtype=np.float64)
            u = self._draws(rng)[0]
            value, lq = guided_draw(1, 0, 0.0, 0.0, base, u, 0.0, *self._inputs(ctx.derivation, site, args))
            return value == 1.0, lq
        known = self._categories.get((key, dist))  # by site too: one categorical may serve two sites (h86)
        if known is None:
            if len(self._categories) > 4096:  # a model that builds its categoricals afresh: don't grow forever
                self._categories.clear()
            known = self._categories[(key, dist)] = self._category_order(ctx, name, site, dist)
        base, order = known
        u = self._draws(rng)[0]
        index, lq = guided_draw(2, 0, 0.0, 0.0, base, u, 0.0, *self._inputs(ctx.derivation, site, args))
        return dist.labels[int(index) if order is None else order[int(index)]], lq

    def _category_order(self, ctx, name, site, dist) -> tuple:
        """``(base parameters, order)`` of a categorical at ``site``: a network's k-th output
        is the k-th label it was trained on, so where the model lists the same labels in
        another order now, its base parameters are put in the trained order and ``order[k]``
        is the index of that label now (a reordering had steered every choice to the wrong
        label, worse than no guide, h70). Other labels than the trained ones (renamed) are
        proposed by position, and noted (:meth:`relabelled_note`)."""
        base = np.array(base_params(site[0], dist), dtype=np.float64)
        trained = site[8]
        if trained is None:
            return base, None
        now = label_codes(dist.labels)
        if now == trained:
            return base, None
        position = {code: i for i, code in enumerate(now)}
        if set(position) != set(trained):
            self._relabelled.add(site_key(rule_name(ctx.rule), name))
            return base, None
        order = [position[code] for code in trained]
        return np.ascontiguousarray(base[order]), order

    def unmatched_note(self) -> str | None:
        """A note when the guide proposed none of the choices the model made: none of its
        sites is a choice of the model's rules (a rule renamed since it was trained), so
        every choice came from the prior and the run was unguided in all but name; None
        otherwise (or before any choice)."""
        if not self._by_rule or any(site is not None for site in self._by_rule.values()):
            return None
        made = sorted({site_key(rule_name(rule), name) for rule, name in self._by_rule})
        known = sorted(self.guide.sites)
        return (f"the guide proposed none of this run's choices: its sites ({', '.join(known[:4])}"
                f"{', ...' if len(known) > 4 else ''}) are none of the model's ({', '.join(made[:4])}"
                f"{', ...' if len(made) > 4 else ''}), so every choice came from the prior; retrain the guide "
                "on this model")

    def relabelled_note(self) -> str | None:
        """A note when a categorical the guide proposed has other labels than the ones its
        site was trained on (renamed, not reordered): proposed by position, which may no
        longer be what it learned; None otherwise."""
        if not self._relabelled:
            return None
        sites = sorted(self._relabelled)
        return (f"the guide's site{'s' if len(sites) > 1 else ''} {', '.join(sites[:3])}"
                f"{', ...' if len(sites) > 3 else ''} draw{'' if len(sites) > 1 else 's'} among other labels than "
                "it was trained on, and proposed them by position: if a label's meaning moved, retrain the guide")

    def _draws(self, rng) -> tuple[float, float]:
        """A uniform and a standard normal from ``rng``, drawn in blocks: two generator
        calls per choice cost about as much as the network. Deterministic given the
        generator's seed, like single draws. A generator's first block is
        :data:`FIRST_DRAWS`, and each next one twice the last, up to :data:`DRAW_BLOCK`:
        a guided 1-particle run makes a few dozen choices."""
        i = self._next_draw
        if i == len(self._uniforms) or rng is not self._draws_of:
            size = min(2 * i, DRAW_BLOCK) if rng is self._draws_of else FIRST_DRAWS
            self._uniforms = rng.random(size).tolist()
            self._normals = rng.standard_normal(size).tolist()
            self._draws_of = rng
            i = 0
        self._next_draw = i + 1
        return self._uniforms[i], self._normals[i]


def merge_labels(labels: dict, key: str, drawn) -> None:
    """Record in ``labels`` (site key -> labels) that a choice of site ``key`` drew among
    ``drawn`` (None: among labels that varied already): a site whose labels differ between
    its choices (labels made from the rule's arguments) records None, as no one order of
    them is what its network learned."""
    if drawn is None:
        labels[key] = None
    elif key not in labels:
        labels[key] = tuple(drawn)
    elif labels[key] is not None and label_codes(labels[key]) != label_codes(drawn):
        labels[key] = None


def plain_labels(labels) -> list:
    """A categorical's labels as plain Python values, as its JSON holds them (a Categorical
    keeps numpy's ints and floats as given: json could not write them, h86)."""
    return plain_value(list(labels))


def label_codes(labels) -> tuple:
    """Labels as JSON text, to compare them as the guide's metadata keeps them (1, 1.0 and
    True are one label to Python's ==, three to a categorical's JSON)."""
    return tuple(json.dumps(label) for label in plain_labels(labels))


class RecordingProposer:
    """Replays a trace's choices (log q = 0) and records what training needs per choice:
    site, features, the prior's base parameters and the encoded value."""

    def __init__(self, choices: dict, extractor: FeatureExtractor):
        self.choices = choices
        self.extractor = extractor
        self.rows = []  # (site key, kind, features, base, value)
        self.labels = {}  # categorical site key -> its labels (None: they varied between choices)

    def propose(self, ctx, name, dist, rng):
        key = (ctx.address, name)
        if key not in self.choices:
            raise GuideError(f"it has no value for choice {cut_text(name, 60)!r} at {format_address(ctx.address)}: it "
                             "was made by another version of the model, or edited")
        value = self.choices[key]
        try:
            takes = dist.log_prob(value) > -math.inf  # NaN: False
        except (TypeError, ValueError, OverflowError):  # another type (a string for a Normal)
            takes = False
        if not takes:  # replayed, it reached the geometry, and was blamed on the rule's arithmetic
            raise GuideError(f"its choice {cut_text(name, 60)!r} at {format_address(ctx.address)} is "
                             f"{shown_value(value)}, which its {type(dist).__name__} cannot draw (not a number, "
                             "outside its range, or another type): the trace was edited")
        kind = head_kind(dist)
        rule = rule_name(ctx.rule)
        if kind.startswith("categorical"):
            merge_labels(self.labels, site_key(rule, name), dist.labels)
        self.rows.append((site_key(rule, name), kind,
                          self.extractor.features(ctx.derivation, rule, with_defaults(ctx.rule, ctx.args)),
                          base_params(kind, dist), encode_value(kind, dist, value)))
        return value, 0.0


def new_guide_for(model, settings: FeatureSettings, mixture: int, site_kinds: dict, seed: int,
                  site_labels: dict | None = None) -> Guide:
    """A fresh guide with one network per site in ``site_kinds`` (key -> kind);
    ``site_labels`` (key -> labels) records the labels a categorical site was trained on,
    in the order its network's outputs follow (see :meth:`GuidedProposer.propose`)."""
    extractor = FeatureExtractor(model, settings, np.zeros((1, 1)) if settings.target else None)
    sites = {}
    for key, kind in site_kinds.items():
        rule_name = key.split(":", 1)[0]
        sites[key] = {"kind": kind, "n_in": extractor.size(rule_name), "n_out": n_outputs(kind, mixture)}
        labels = (site_labels or {}).get(key)
        if labels is not None and kind.startswith("categorical"):
            sites[key]["labels"] = plain_labels(labels)
    return Guide(model.name, settings, mixture, sites, seed)
