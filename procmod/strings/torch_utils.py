"""Torch utilities of the string models: thread count, training device, checkpoints."""

from __future__ import annotations

import contextlib
import dataclasses
from pathlib import Path

import torch

from ..core.errors import InvalidArgumentError, ProcmodError, argument, cut_text
from ..core.io import save_tensors

# how an error message names training on the CPU (the command line: --device cpu)
CPU_DEVICE = "device='cpu'"
TORCH_THREADS = 1  # these nets are small: one thread is much faster than two on a busy 2-core machine


class torch_threads:
    """Run torch with ``n`` intra-op threads inside a ``with`` block (restored after)."""

    def __init__(self, n: int = TORCH_THREADS):
        self.n = n

    def __enter__(self):
        self.old = torch.get_num_threads()
        torch.set_num_threads(self.n)

    def __exit__(self, *exc):
        torch.set_num_threads(self.old)
        return False


class ModelFileError(ProcmodError):
    """A trained model folder or checkpoint that cannot be read."""


class OtherTrainingError(ModelFileError):
    """A folder's checkpoint is of another training (configuration, data, or more epochs
    than asked): not to be resumed. Raised before the training writes anything, so a caller
    that may replace the folder (``strings train --overwrite``) can start afresh."""


# what a damaged or hand-edited model file raises while it is turned into nets (a missing
# key, a field of the wrong type, weights of another size)
MALFORMED = (KeyError, TypeError, ValueError, AttributeError, IndexError, RuntimeError)


@contextlib.contextmanager
def reading_model_file(where: str, advice: str = "; train it again with 'procmod strings train'"):
    """Turn what a malformed model file raises inside the block into one ModelFileError
    line naming ``where`` (ProcmodErrors pass through)."""
    try:
        yield
    except ProcmodError:
        raise
    except MALFORMED as exc:
        text = str(exc).splitlines()[0] if str(exc) else ""
        raise ModelFileError(f"{where} is malformed ({type(exc).__name__}: {text[:160]}){advice}") from None


def load_weights(net, weights, weights_path, meta_path, advice: str = "; train it again with 'procmod strings train'"):
    """``net.load_state_dict(weights)``; weights of another network (another model's
    file copied over, another configuration) are one ModelFileError naming the weights'
    file, not the metadata that described the network."""
    try:
        net.load_state_dict(weights)
    except (RuntimeError, KeyError, TypeError, ValueError) as exc:
        text = str(exc).strip().splitlines()
        detail = text[1].strip() if len(text) > 1 else (text[0] if text else type(exc).__name__)
        raise ModelFileError(f"{weights_path} holds weights of another network than {Path(meta_path).name} "
                             f"describes ({cut_text(detail, 160)}): it belongs to another model or was replaced"
                             f"{advice}") from None


def config_from_json(cls, data, where: str):
    """A config dataclass (``cls``, with a ``check()`` of its values) from a model file's
    JSON object: only its own settings, each of its default's type (an int where a float
    is wanted too), then checked, so that a hand-edited size cannot allocate terabytes."""
    if not isinstance(data, dict):
        raise ModelFileError(f"{where} must be an object of settings, got {type(data).__name__}")
    defaults = {f.name: getattr(cls(), f.name) for f in dataclasses.fields(cls)}
    for key, value in data.items():
        if key not in defaults:
            raise ModelFileError(f"{where} has a setting {key!r} that procmod does not know; it was not written "
                                 "by this version of 'procmod strings train'")
        want = type(defaults[key])
        fits = (isinstance(value, want) and (want is bool or not isinstance(value, bool))) or (
            want is float and isinstance(value, int) and not isinstance(value, bool))
        if not fits:
            kind = {"int": "a whole number", "float": "a number", "str": "a string", "bool": "true or false"}.get(
                want.__name__, want.__name__)
            raise ModelFileError(f"{where}.{key} must be {kind}, got {value!r:.40}")
    config = cls(**data)
    try:
        config.check()
    except InvalidArgumentError as exc:
        raise ModelFileError(f"{where}: {exc}") from None
    return config


def training_state(value, where: str) -> dict:
    """A checkpoint's training state from its model file (``{"epoch", "history", "data"}``:
    epochs done, one row per epoch, the training data's fingerprint or None), checked, so
    that an edited file is one line here rather than a traceback where training resumes."""
    if not isinstance(value, dict):
        raise ModelFileError(f"{where} must be an object with the epochs trained, got {value!r:.40}")
    epoch, history, data = value.get("epoch"), value.get("history"), value.get("data")
    if isinstance(epoch, bool) or not isinstance(epoch, int) or epoch < 0:
        raise ModelFileError(f"{where}.epoch must be a whole number of epochs >= 0, got {epoch!r:.40}")
    if not isinstance(history, list) or not all(isinstance(row, dict) for row in history):
        raise ModelFileError(f"{where}.history must be a list of one object per epoch, got {history!r:.40}")
    if data is not None and not isinstance(data, str):
        raise ModelFileError(f"{where}.data must be the training data's fingerprint (a string), got {data!r:.40}")
    unknown = sorted(set(value) - {"epoch", "history", "data"})
    if unknown:
        raise ModelFileError(f"{where} has a field {unknown[0]!r:.40} that procmod does not know; it was not written "
                             "by this version of 'procmod strings train'")
    return value


def check_finite_weights(net, where: str) -> None:
    """Refuse weights that are NaN or infinite (a run that diverged; a damaged file)."""
    for name, value in net.state_dict().items():
        if value.is_floating_point() and not bool(torch.isfinite(value).all()):
            raise ModelFileError(f"{where}: weight {name!r} holds NaN or infinity (training diverged, or the file "
                                 "is damaged); train the model again")


def training_device(name: str | None) -> torch.device:
    """The torch device to train on: ``None`` or ``"cpu"``, ``"cuda"``, ``"cuda:N"``.

    Training runs there; checkpoints are always written with CPU tensors and every trained
    model is handed back on the CPU, where sampling, decoding and instantiation run (their
    per-step work is small and branchy), so a model trained on a GPU loads anywhere.
    """
    if name is None or name == "cpu":
        return torch.device("cpu")
    option = argument("device")
    try:
        device = torch.device(name)
    except (RuntimeError, TypeError):
        raise InvalidArgumentError(f"{option} {name!r} is not a torch device; use cpu, cuda or cuda:N") from None
    if device.type != "cuda":
        raise InvalidArgumentError(f"{option} {name!r}: training runs on cpu or cuda only")
    if not torch.cuda.is_available():
        raise InvalidArgumentError(f"{option} {name!r}: torch sees no CUDA device here "
                                   f"(torch {torch.__version__}); train with {argument(CPU_DEVICE)}")
    if device.index is not None and device.index >= torch.cuda.device_count():
        raise InvalidArgumentError(f"{option} {name!r}: only {torch.cuda.device_count()} CUDA device(s) visible")
    return device


def cpu_state(module_or_optimizer) -> dict:
    """A state dict with every tensor on the CPU (checkpoints load on any machine)."""
    def to_cpu(x):
        if isinstance(x, torch.Tensor):
            return x.detach().cpu()
        if isinstance(x, dict):
            return {k: to_cpu(v) for k, v in x.items()}
        if isinstance(x, (list, tuple)):
            return type(x)(to_cpu(v) for v in x)
        return x
    return to_cpu(module_or_optimizer.state_dict())


def save_weights(path: Path, net, optimizer=None) -> None:
    """Write a net's (and optionally its optimizer's) CPU state dicts to ``path`` through a
    temporary file and a rename: a kill mid-write leaves the previous checkpoint whole."""
    payload = {"model": cpu_state(net)}
    if optimizer is not None:
        payload["optimizer"] = cpu_state(optimizer)
    save_tensors(payload, path)
