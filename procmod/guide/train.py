"""Training a guide: maximise the log-likelihood of SMC traces under the guided model
(seed 004 eq. 1-2).

Each trace is replayed once with a :class:`RecordingProposer`, which records, for every
choice, its site, features, the prior's parameters and the value. Training then never
runs the model again: each Adam step takes a minibatch of traces (one by default, as the
papers) and sums the log-proposal of all their choices, batched per site.

Defaults follow seed 003 section 5.2: Adam with step size 0.01 and both decay rates 0.75,
minibatches of one trace, 20000 steps, with one addition: the step size is annealed from
0.01 to zero by a half cosine over the run (``schedule="cosine"``). With a constant step
and minibatches of one trace, the last iterate is a noisy point of the optimisation path;
annealing lets it settle (lower held-out negative log-likelihood and higher similarity
at 10 particles; ``bench/ngpm.py`` trains both, README has the figures).
``schedule="constant"`` is the papers' setting exactly. The job writes a checkpoint every
``checkpoint_every`` steps (``OUT.ckpt.pt`` + ``OUT.ckpt.json``) and resumes from it when
rerun with the same settings; the minibatch of step t depends only on (seed, t), so a
resumed run ends with the same guide as an uninterrupted one, and with the same loss curve:
the checkpoint keeps the smoothed loss the curve reports (an exponential average over
about 100 steps) as well as the weights and Adam's state.
"""

from __future__ import annotations

import hashlib
import json
import math
import numbers
import os
import time
from pathlib import Path

import numpy as np
import torch

from ..core import Model, start
from ..core.errors import argument, shown_value, whole_number
from ..core.runtime import finish
from ..core.serialize import stored_calls
from ..core.io import load_tensors, save_tensors, write_text_atomic
from .features import FeatureExtractor, FeatureSettings, FeatureSettingsError, GuideError
from .guide import (Guide, RecordingProposer, check_mixture, guide_paths, merge_labels, new_guide_for,
                    output_size, target_kind, target_mask_for)
from .nets import log_q_torch
from .traces import load_traces

MAX_BATCH = 100_000  # traces a step: far beyond any useful minibatch, small enough to hold
# Adam steps: 500x the papers' 20,000 (days of training); a mistyped count beyond it
# would run for ever with no word
MAX_ITERATIONS = 10_000_000
ADAM_BETAS = (0.75, 0.75)  # seed 003 5.2: "alpha = beta = 0.75"
SCHEDULES = ("cosine", "constant")
# how an error message names the local-only feature setting (the command line spells it
# --features local: procmod.cli.CLI_SPELLING)
LOCAL_FEATURES = "settings=FeatureSettings.condition('local')"


def step_size(lr: float, schedule: str, step: int, iterations: int) -> float:
    """The Adam step size at ``step`` (0-based) of ``iterations``."""
    if schedule == "cosine":
        return lr * 0.5 * (1.0 + math.cos(math.pi * step / iterations))
    return lr


def _target_mask(spec: str, model):
    from ..data import target_from_spec

    return target_mask_for(target_from_spec(spec), model)


def trace_rows(model, trace: dict, settings: FeatureSettings, masks: dict | None = None,
               labels: dict | None = None) -> list:
    """Replay one trace and return its per-choice training rows; ``labels`` (site key ->
    labels, :func:`~procmod.guide.guide.merge_labels`) gathers its categorical sites' labels."""
    d = trace["derivation"]
    if d.get("model") != model.name:
        raise GuideError(f"{_trace_name(trace)} is of model {d.get('model')!r}, not {model.name!r}")
    configured = model.configure(**d["params"])
    choices = stored_calls(d, "its derivation")[1]
    spec = trace["target"]
    if masks is not None and spec in masks:
        mask = masks[spec]
    else:
        mask = _target_mask(spec, configured) if settings.target else None
        if masks is not None:
            masks[spec] = mask
    extractor = FeatureExtractor(configured, settings, mask)
    recorder = RecordingProposer(choices, extractor)
    state = start(configured)
    state.proposer = recorder
    try:
        finish(state, np.random.default_rng(0))
    except FeatureSettingsError:  # the model's and the settings' matter: remaking the trace would not help
        raise
    except GuideError as exc:  # the recorder's: a choice the trace lacks, or holds a value it cannot take
        raise GuideError(f"{_trace_name(trace)}: {exc}{_RERUN}") from None
    if len(recorder.rows) != len(choices) or not math.isclose(state.log_prior, d["log_prior"], abs_tol=1e-6):
        raise GuideError(f"{_trace_name(trace)} does not replay under model {model.name!r}: it was made "
                         f"by another version of the model, or edited{_RERUN}")
    if labels is not None:
        for key, drawn in recorder.labels.items():
            merge_labels(labels, key, drawn)
    return recorder.rows


_RERUN = "; delete it and rerun the traces job (procmod guide traces makes it again)"


def _trace_name(trace) -> str:
    index = trace.get("index") if isinstance(trace, dict) else None
    return f"trace_{index:05d}.json" if isinstance(index, int) and not isinstance(index, bool) and index >= 0 \
        else "a trace"


def _checked_rows(model, trace, settings: FeatureSettings, masks: dict, labels: dict | None = None) -> list:
    """:func:`trace_rows`, a damaged or edited trace named with what to do."""
    from ..core.errors import ProcmodError

    advice = _RERUN
    try:
        if not isinstance(trace.get("derivation"), dict):
            raise ValueError("its 'derivation' is not a JSON object")
        return trace_rows(model, trace, settings, masks, labels)
    except GuideError:
        raise
    except ProcmodError as exc:
        raise GuideError(f"{_trace_name(trace)}: {exc}{advice}") from None
    except (KeyError, TypeError, ValueError, AttributeError, OverflowError, IndexError) as exc:
        problem = f"it lacks {exc}" if isinstance(exc, KeyError) else str(exc)
        raise GuideError(f"{_trace_name(trace)} is damaged ({problem[:160]}){advice}") from None


def traces_digest(traces: list) -> str:
    """A digest of the traces' contents: a checkpoint resumes only on the traces it began with."""
    digest = hashlib.sha256()
    for trace in traces:
        digest.update(json.dumps(trace, sort_keys=True, default=str).encode("utf-8"))
    return digest.hexdigest()


def _resumable(saved, fingerprint: dict, iterations: int) -> bool:
    """Whether a checkpoint's metadata is this run's and whole (an edited or damaged one,
    or another run's, is not resumed: training starts over)."""
    if not isinstance(saved, dict) or saved.get("fingerprint") != fingerprint:
        return False
    step, curve, running = saved.get("step"), saved.get("curve"), saved.get("running")
    if isinstance(step, bool) or not isinstance(step, int) or not 0 < step < iterations:
        return False
    if not isinstance(curve, list) or not all(
            isinstance(c, list) and len(c) == 2 and isinstance(c[0], int) and isinstance(c[1], (int, float))
            for c in curve):
        return False
    return running is None or (isinstance(running, (int, float)) and not isinstance(running, bool)
                               and math.isfinite(running))


class SiteData:
    """All training rows of one site, ordered by trace, as tensors."""

    def __init__(self, kind: str, rows: list, trace_ids: list, n_traces: int):
        self.kind = kind
        order = np.argsort(np.asarray(trace_ids), kind="stable")
        ids = np.asarray(trace_ids)[order]
        self.x = torch.as_tensor(np.array([rows[i][0] for i in order]).reshape(len(order), -1), dtype=torch.float64)
        width = max(len(rows[i][1]) for i in order)
        self.base = torch.as_tensor(np.array([rows[i][1] for i in order], dtype=np.float64).reshape(len(order), width))
        self.value = torch.as_tensor(np.array([rows[i][2] for i in order], dtype=np.float64))
        self.starts = np.searchsorted(ids, np.arange(n_traces), side="left")
        self.ends = np.searchsorted(ids, np.arange(n_traces), side="right")

    def batch(self, traces: np.ndarray):
        if len(traces) == 1:
            a, b = self.starts[traces[0]], self.ends[traces[0]]
            if a == b:
                return None
            return self.x[a:b], self.base[a:b], self.value[a:b]
        idx = np.concatenate([np.arange(self.starts[t], self.ends[t]) for t in traces])
        if len(idx) == 0:
            return None
        idx = torch.as_tensor(idx)
        return self.x[idx], self.base[idx], self.value[idx]


def trained_on(model, traces: list) -> dict:
    """What a guide records of its traces' drawings and targets (``info["trained_on"]``):
    the drawing sizes (``[width, height]`` each) and the kinds of target
    (:func:`~procmod.guide.guide.target_kind`), so that a run on others is noted
    (:func:`~procmod.guide.guide.fit_note`)."""
    from ..core.errors import ProcmodError
    from ..data import target_from_spec

    sizes, kinds, seen = [], [], set()
    for trace in traces:
        params = trace["derivation"]["params"]
        key = (json.dumps(params, sort_keys=True, default=str), trace["target"])
        if key in seen:  # a job's traces share their params and a few dozen targets
            continue
        seen.add(key)
        size = output_size(model.configure(**params).new_output())
        if size is not None and size not in sizes:
            sizes.append(size)
        try:
            kind = target_kind(target_from_spec(trace["target"]))
        except ProcmodError:  # a picture moved since: a guide with local features only trains without it
            continue
        if kind not in kinds:
            kinds.append(kind)
    return {"canvases": sorted(sizes), "targets": sorted(kinds)}


def build_dataset(model, traces: list, settings: FeatureSettings,
                  labels: dict | None = None) -> tuple[dict, dict, int]:
    """Per-site training data; returns (site -> SiteData, site -> kind, number of choices).
    ``labels`` gathers the categorical sites' labels (:func:`trace_rows`)."""
    per_site, kinds = {}, {}
    masks = {}
    n_choices = 0
    for t, trace in enumerate(traces):
        for key, kind, features, base, value in _checked_rows(model, trace, settings, masks, labels):
            if kinds.setdefault(key, kind) != kind:
                raise GuideError(f"site {key} draws both {kinds[key]} and {kind} choices; a guide needs one "
                                 "distribution family per site, and tells sites apart by rule and choice name, so "
                                 "rules that share a name (closures of one factory, lambdas) share their sites: "
                                 "give the rules distinct names (or set each one's __name__) or the choices "
                                 "different names")
            rows, ids = per_site.setdefault(key, ([], []))
            rows.append((features, base, value))
            ids.append(t)
            n_choices += 1
    if not kinds:  # the optimiser would be handed no parameters (a traceback)
        raise GuideError(f"the {len(traces)} trace{'s' if len(traces) != 1 else ''} hold no random choices (model "
                         f"{model.name!r} made none in them): there is nothing for a guide to propose; a model "
                         "without ctx.sample needs no guide")
    data = {key: SiteData(kinds[key], rows, ids, len(traces)) for key, (rows, ids) in per_site.items()}
    return data, kinds, n_choices


def _nll(guide: Guide, data: dict, traces: np.ndarray) -> torch.Tensor:
    total = torch.zeros((), dtype=torch.float64)
    for key, site in data.items():
        batch = site.batch(traces)
        if batch is None:
            continue
        x, base, value = batch
        out = guide.nets[key](x)
        total = total - log_q_torch(site.kind, guide.mixture, out, base, value).sum()
    return total / len(traces)


def _refuse_foreign_checkpoint(ckpt: Path, ckpt_meta: Path) -> None:
    """Refuse to train where ``OUT.ckpt.pt`` / ``OUT.ckpt.json`` exist and are not a training
    checkpoint of procmod's: they are written during training and deleted at its end, and
    a user's own PyTorch checkpoint of that name had been deleted without a word (h135). A
    weights file alone is procmod's when it holds what :func:`train_guide` saves in it (a run
    killed between writing it and its metadata leaves one)."""
    for path in (ckpt_meta, ckpt):
        if not path.exists():
            continue
        if path == ckpt_meta:
            try:
                saved = json.loads(path.read_text(encoding="utf-8"))
            except (OSError, ValueError, RecursionError):
                saved = None
            ours = isinstance(saved, dict) and isinstance(saved.get("fingerprint"), dict) and "step" in saved
        elif ckpt_meta.exists():
            continue  # its metadata is ours (checked above): a damaged one is started over
        else:
            try:
                state = load_tensors(path, GuideError, "training checkpoint")
            except GuideError:
                state = None
            ours = isinstance(state, dict) and {"nets", "optimiser", "step"} <= set(state)
        if not ours:
            raise GuideError(f"{path} is not a procmod training checkpoint, and training writes its checkpoint "
                             "there (and deletes it at the end): move that file, or give another output name")


def train_guide(model, traces_dir, out, settings: FeatureSettings | None = None, mixture: int = 4,
                iterations: int = 20000, batch: int = 1, lr: float = 0.01, schedule: str = "cosine",
                limit: int | None = None,
                seed: int = 0, checkpoint_every: int = 1000, progress=None, traces: list | None = None):
    """Train a guide for ``model`` on the traces in ``traces_dir``; save it to ``out``.

    Returns ``(guide, report)``; the report has the number of traces and choices, seconds,
    the loss curve (mean negative log-likelihood per trace, every 100 steps), and the paths
    written. ``traces`` (already loaded) skips reading the folder.
    """
    if isinstance(model, str):  # a model's name, or FILE.py:NAME, as the command line takes it
        from ..models import model_from_spec
        model = model_from_spec(model)
    if not isinstance(model, Model):
        raise GuideError(f"model must be a procmod Model or a model's name, got {type(model).__name__}")
    settings = FeatureSettings() if settings is None else settings
    if not isinstance(settings, FeatureSettings):
        raise GuideError(f"settings must be a FeatureSettings (e.g. FeatureSettings(partial=False)), got "
                         f"{type(settings).__name__} {settings!r:.40}")
    if not isinstance(out, (str, os.PathLike)):
        raise GuideError(f"out must be the guide's path (NAME, NAME.pt or NAME.json), got {type(out).__name__}")
    if traces is not None and (not isinstance(traces, list) or not traces
                               or not all(isinstance(t, dict) and "target" in t for t in traces)):
        raise GuideError("traces must be a non-empty list of traces as load_traces reads them (each a dict with "
                         "its target and choices); or leave it out to read traces_dir")
    for name, value in (("iterations", iterations), ("batch", batch), ("mixture", mixture),
                        ("checkpoint_every", checkpoint_every)):
        if whole_number(value) is None or value < 1:
            raise GuideError(f"{argument(name)} must be a positive integer, got {shown_value(value)}")
    check_mixture(mixture)
    if whole_number(seed) is None or not 0 <= seed < 2 ** 63:
        raise GuideError(f"seed must be an integer from 0 to 2**63-1, got {shown_value(seed)}")
    if limit is not None and (whole_number(limit) is None or limit < 1):
        raise GuideError(f"{argument('limit')} must be a positive integer (the first traces to train on)"
                         + (" or None" if argument("limit") == "limit" else "") + f", got {shown_value(limit)}")
    # numpy's integers as plain ones: they go into the guide's JSON and torch's seeding
    iterations, batch, mixture, checkpoint_every, seed = (int(v) for v in (iterations, batch, mixture,
                                                                           checkpoint_every, seed))
    limit = None if limit is None else int(limit)
    if iterations > MAX_ITERATIONS:
        raise GuideError(f"{argument('iterations')} must be at most {MAX_ITERATIONS:,} Adam steps (the papers train for 20,000), "
                         f"got {iterations:,}")
    if batch > MAX_BATCH:
        raise GuideError(f"{argument('batch')} must be at most {MAX_BATCH:,} traces a step, got {batch:,}")
    if isinstance(lr, bool) or not isinstance(lr, numbers.Real) or not (math.isfinite(lr) and lr > 0):
        raise GuideError(f"the learning rate ({argument('lr')}) must be a finite positive number, got {shown_value(lr)}")
    lr = float(lr)  # numpy's too: it is recorded in the guide's JSON
    if schedule not in SCHEDULES:
        raise GuideError(f"the step-size schedule ({argument('schedule')}) must be one of {', '.join(SCHEDULES)}, got {schedule!r}")
    weights_path, _ = guide_paths(out, for_writing=True)
    ckpt, ckpt_meta = weights_path.with_suffix(".ckpt.pt"), weights_path.with_suffix(".ckpt.json")
    _refuse_foreign_checkpoint(ckpt, ckpt_meta)
    job = None
    if traces is None:
        job, traces = load_traces(traces_dir, limit)
        if job.get("model") != model.name:
            raise GuideError(f"{traces_dir} holds traces of model {job.get('model')!r}, not {model.name!r}")
    elif limit is not None:
        traces = traces[:limit]
    if settings.target and any(t["target"] == "circuit" for t in traces):
        raise GuideError("circuit traces have no target image; train with "
                         f"{argument(LOCAL_FEATURES)} (or 'constant')")
    began = time.perf_counter()
    torch.set_num_threads(1)  # tiny networks: threads cost more than they give
    try:
        labels = {}
        data, kinds, n_choices = build_dataset(model, traces, settings, labels)
    except GuideError as exc:
        from .traces import model_code_digests
        if job is None or job.get("model_code") in (None, *model_code_digests(model, job.get("model_file"))):
            raise
        # the model was edited since the job: every trace may be stale, and the job refuses to
        # resume on the new code, so deleting the trace named and rerunning (the advice for a
        # damaged trace) led nowhere, one trace at a time
        raise GuideError(f"{traces_dir} holds traces of model {model.name!r} made before its code was edited, and "
                         f"they do not replay under it ({str(exc).replace(_RERUN, '')}): make them afresh with "
                         f"procmod guide traces and {argument('overwrite=True')}, or into a new folder") from None
    drawn = trained_on(model, traces)
    guide = new_guide_for(model, settings, mixture, kinds, seed, labels)
    optimiser = torch.optim.Adam(guide.nets.parameters(), lr=lr, betas=ADAM_BETAS)
    fingerprint = {"model": model.name, "features": settings.to_json(), "mixture": mixture, "batch": batch,
                   "lr": lr, "schedule": schedule, "seed": seed, "iterations": iterations, "traces": len(traces),
                   "sites": sorted(kinds), "traces_sha256": traces_digest(traces)}
    step, curve, running = 0, [], None
    if ckpt.exists() and ckpt_meta.exists():
        try:
            saved = json.loads(ckpt_meta.read_text())
        except (OSError, ValueError, RecursionError):
            saved = None
        state = None
        if _resumable(saved, fingerprint, iterations):
            try:
                state = load_tensors(ckpt, GuideError, "training checkpoint")
            except GuideError:
                state = None  # damaged: start over
        # the weights file holds its step too: a run killed between writing the weights
        # and the metadata left weights one checkpoint ahead of what the metadata says
        if isinstance(state, dict) and state.get("step") == saved["step"]:
            try:
                guide.nets.load_state_dict(state["nets"])
                optimiser.load_state_dict(state["optimiser"])
                step, curve = saved["step"], [list(c) for c in saved["curve"]]
                # the smoothed loss goes on from where it was (a checkpoint from before it
                # was kept restarts it: its curve then differs from an uninterrupted run's)
                running = saved.get("running")
            except (KeyError, RuntimeError, ValueError, TypeError):
                guide = new_guide_for(model, settings, mixture, kinds, seed, labels)  # a half-loaded state: start over
                optimiser = torch.optim.Adam(guide.nets.parameters(), lr=lr, betas=ADAM_BETAS)
    n = len(traces)
    while step < iterations:
        picked = np.random.default_rng([seed, step]).integers(n, size=batch)
        for group in optimiser.param_groups:
            group["lr"] = step_size(lr, schedule, step, iterations)
        optimiser.zero_grad()
        loss = _nll(guide, data, picked)
        loss.backward()
        optimiser.step()
        value = float(loss.detach())
        if not math.isfinite(value):  # diverged: a guide of NaN weights would be written otherwise
            raise GuideError(f"training diverged at step {step + 1} (the loss is {value}); use a smaller "
                             f"learning rate than {lr:g}")
        running = value if running is None else 0.99 * running + 0.01 * value
        step += 1
        if step % 100 == 0 or step == iterations:
            curve.append([step, running])
            if progress is not None:
                progress(step, running)
        if step % checkpoint_every == 0 and step < iterations:
            weights_path.parent.mkdir(parents=True, exist_ok=True)
            save_tensors({"nets": guide.nets.state_dict(), "optimiser": optimiser.state_dict(), "step": step}, ckpt)
            write_text_atomic(ckpt_meta, json.dumps({"fingerprint": fingerprint, "step": step, "curve": curve,
                                                     "running": running}))
    with torch.no_grad():
        final = float(_nll(guide, data, np.arange(n)))
    seconds = time.perf_counter() - began
    guide.invalidate()
    guide.info = {"traces": n, "choices": n_choices, "iterations": iterations, "batch": batch, "lr": lr,
                  "schedule": schedule, "adam_betas": list(ADAM_BETAS), "seed": seed, "final_nll": final, "seconds": seconds,
                  "trace_job": job, "trained_on": drawn, "curve": curve}
    weights, meta = guide.save(out)
    for p in (ckpt, ckpt_meta):
        if p.exists():
            p.unlink()
    report = dict(guide.info, weights=str(weights), metadata=str(meta))
    return guide, report
