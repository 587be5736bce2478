"""A sequence VAE over shape-graph strings (seed 001, section 5).

Characters are tokens (letters, ``(``, ``)``, ring-label digits and ``%``), plus three
specials: padding, start and end. The encoder is a recurrent network (GRU or LSTM,
``layers`` deep) whose last hidden state gives the mean and log-variance of a diagonal
Gaussian over a ``latent``-dimensional z; the decoder is a recurrent network started from
a linear map of z that also sees z at every step, trained with teacher forcing. Loss =
cross-entropy + beta * KL, beta rising linearly from 0 to ``kl_weight`` over the first
``kl_warmup`` epochs (so the decoder learns to use z before the KL term pulls it to the
prior).

Decoding checks what it writes against the tiling grammar. With ``constrained=True`` each
step masks (logit -inf) the tokens that cannot continue a valid string, as the grammar
automaton (:class:`~procmod.strings.automaton.Constraint`) says: the SMILES syntax
(balanced brackets, ring labels after a letter, no self-loops or duplicate edges), node
type pairs that never touch in the inputs, and neighbour multisets that no rule can still
complete. Every decoded string is then checked in full (:meth:`Grammar.is_valid`);
``constrained=False`` decodes freely, as the paper does, and only checks afterwards.
Thread count, training device and checkpoint writing are in :mod:`.torch_utils`.
"""

from __future__ import annotations

import json
import math
import os
import time
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path

import numpy as np
import torch
from torch import nn

from ..core.errors import InvalidArgumentError, argument, plain_fields, shown_value, whole_number
from ..core.io import fingerprint, load_tensors, read_versioned_json, write_text_atomic
from .automaton import Constraint, _Prefix
from .codec import StringSyntaxError, parse
from .grammar import Grammar
from .torch_utils import (ModelFileError, OtherTrainingError, check_finite_weights, config_from_json, load_weights,
                          reading_model_file, save_weights, torch_threads, training_device, training_state)

PAD, SOS, EOS = 0, 1, 2
NODE_BUDGET = 1.25  # constrained decoding stops adding letters at 1.25 x the largest training graph (nodes)
WRAP_FRACTION = 0.8  # constrained decoding wraps up from 0.8 x the largest training graph (nodes)
WRAP_BIAS = 0.5  # logit bonus per node past that, for tokens that close a ring, a branch or the string
SPECIALS = ("<pad>", "<s>", "</s>")


@dataclass
class VAEConfig:
    """Sizes and training constants of the string VAE (see docs/strings.md)."""

    cell: str = "gru"  # "gru" or "lstm"
    embed: int = 32
    hidden: int = 128
    layers: int = 1
    latent: int = 24
    kl_weight: float = 0.1  # final beta
    kl_warmup: int = 10  # epochs of linear beta warm-up
    epochs: int = 40
    batch: int = 64
    lr: float = 2e-3
    max_len: int = 320  # longest decoded string; training raises it to 1.5x its longest string
    word_dropout: float = 0.3  # decoder inputs replaced by padding (Bowman et al.'s trick)

    def check(self) -> None:
        if self.cell not in ("gru", "lstm"):
            raise InvalidArgumentError(f"cell must be 'gru' or 'lstm', got {self.cell!r}")
        check_sizes(self, CONFIG_LIMITS)
        for name, fits, wanted in (("kl_weight", 0 <= self.kl_weight < math.inf, "a finite number >= 0"),
                                   ("kl_warmup", 0 <= self.kl_warmup, "a whole number >= 0"),
                                   ("lr", 0 < self.lr < math.inf, "a finite number > 0"),
                                   ("word_dropout", 0 <= self.word_dropout < 1, "in [0, 1)")):
            if not fits:  # written so that NaN fails (NaN compares false)
                raise InvalidArgumentError(f"{argument(name)} must be {wanted}, got {getattr(self, name)}")


# Largest sizes a string VAE or tagger may have: far beyond what these small nets need
# (defaults 32-128), small enough that a hand-edited model file cannot allocate terabytes.
CONFIG_LIMITS = {"embed": 4096, "hidden": 4096, "layers": 16, "latent": 4096, "epochs": 1_000_000,
                 "batch": 1_000_000, "max_len": 100_000}


def check_sizes(config, limits: dict) -> None:
    """Each of ``limits``' fields of ``config`` a whole number from 1 to its limit; a
    numpy number in any field becomes the Python number (configs are saved as JSON)."""
    plain_fields(config)
    for name, largest in limits.items():
        value = getattr(config, name, None)
        if value is None:
            continue
        if whole_number(value) is None or not 1 <= value <= largest:
            raise InvalidArgumentError(f"{argument(name)} must be a whole number from 1 to {largest:,}, got "
                                       f"{shown_value(value)}")


class Vocab:
    """Token ids of the characters strings use."""

    def __init__(self, chars):
        self.chars = sorted(set(chars))
        self.itos = list(SPECIALS) + self.chars
        self.stoi = {c: i for i, c in enumerate(self.itos)}

    def __len__(self) -> int:
        return len(self.itos)

    def encode(self, text: str, any_ring_label: bool = False) -> list[int]:
        """Token ids of ``text``. With ``any_ring_label``, a ring-label character the
        vocabulary lacks (``%`` or ``0`` of a label from ``%10`` on, which strings need only
        when ten rings are open at once) is read as the ring digit ``1``: for a model that
        is given which characters pair up by other means (the tagger's string structure)."""
        try:
            if any_ring_label:
                ring = self.stoi.get("1")
                return [self.stoi[c] if c in self.stoi or ring is None or not (c.isdigit() or c == "%") else ring
                        for c in text]
            return [self.stoi[c] for c in text]
        except KeyError as exc:
            raise InvalidArgumentError(f"character {exc.args[0]!r} of {text!r} is not in the model's vocabulary "
                                       f"({''.join(self.chars)})") from None

    def decode(self, ids) -> str:
        return "".join(self.itos[i] for i in ids if i > EOS)


def _rnn(cell: str, input_size: int, hidden: int, layers: int):
    kind = nn.GRU if cell == "gru" else nn.LSTM
    return kind(input_size, hidden, num_layers=layers, batch_first=True)


class StringVAE(nn.Module):
    """Recurrent encoder -> Gaussian latent -> recurrent decoder conditioned on z."""

    def __init__(self, vocab_size: int, config: VAEConfig):
        super().__init__()
        self.config = config
        c = config
        self.embedding = nn.Embedding(vocab_size, c.embed, padding_idx=PAD)
        self.encoder = _rnn(c.cell, c.embed, c.hidden, c.layers)
        self.to_mu = nn.Linear(c.hidden * c.layers, c.latent)
        self.to_logvar = nn.Linear(c.hidden * c.layers, c.latent)
        self.from_z = nn.Linear(c.latent, c.hidden * c.layers)
        self.decoder = _rnn(c.cell, c.embed + c.latent, c.hidden, c.layers)
        self.out = nn.Linear(c.hidden, vocab_size)

    def encode(self, tokens: torch.Tensor, lengths: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """Mean and log-variance ``(B, latent)`` of q(z | string)."""
        packed = nn.utils.rnn.pack_padded_sequence(self.embedding(tokens), lengths.cpu(), batch_first=True,
                                                   enforce_sorted=False)
        _, h = self.encoder(packed)
        if isinstance(h, tuple):
            h = h[0]
        h = h.transpose(0, 1).reshape(tokens.shape[0], -1)
        return self.to_mu(h), self.to_logvar(h)

    def initial_state(self, z: torch.Tensor):
        c = self.config
        h = torch.tanh(self.from_z(z)).reshape(z.shape[0], c.layers, c.hidden).transpose(0, 1).contiguous()
        return (h, torch.zeros_like(h)) if c.cell == "lstm" else h

    def decode_logits(self, z: torch.Tensor, inputs: torch.Tensor) -> torch.Tensor:
        """Teacher-forced logits ``(B, T, vocab)`` for decoder inputs ``(B, T)``."""
        e = self.embedding(inputs)
        zz = z[:, None, :].expand(-1, inputs.shape[1], -1)
        out, _ = self.decoder(torch.cat([e, zz], dim=2), self.initial_state(z))
        return self.out(out)

    def step(self, z, token, state):
        e = self.embedding(token)[:, None, :]
        out, state = self.decoder(torch.cat([e, z[:, None, :]], dim=2), state)
        return self.out(out[:, 0]), state


def _batch(vocab: Vocab, strings: list[str]):
    ids = [vocab.encode(s) for s in strings]
    t = max(len(x) for x in ids) + 1
    enc = torch.full((len(ids), t - 1), PAD, dtype=torch.long)
    dec_in = torch.full((len(ids), t), PAD, dtype=torch.long)
    dec_out = torch.full((len(ids), t), PAD, dtype=torch.long)
    for k, x in enumerate(ids):
        enc[k, :len(x)] = torch.tensor(x)
        dec_in[k, 0] = SOS
        dec_in[k, 1:len(x) + 1] = torch.tensor(x)
        dec_out[k, :len(x)] = torch.tensor(x)
        dec_out[k, len(x)] = EOS
    lengths = torch.tensor([len(x) for x in ids])
    return enc, lengths, dec_in, dec_out


# ---------------------------------------------------------------------------------------------


@dataclass
class TrainState:
    epoch: int = 0
    history: list = field(default_factory=list)  # rows: epoch, loss, recon, kl, beta, seconds, device
    data: str | None = None  # fingerprint of the training strings (None: saved before it was kept)


class StringModel:
    """A trained VAE with its vocabulary and grammar; decoding and latent sampling."""

    def __init__(self, net: StringVAE, vocab: Vocab, grammar: Grammar, max_nodes: int | None = None):
        self.net, self.vocab, self.max_nodes = net, vocab, max_nodes
        self.grammar = grammar
        # models store only the budget; the largest training graph is max_nodes / NODE_BUDGET
        self.wrap_nodes = None if max_nodes is None else max(1, int(round(WRAP_FRACTION * max_nodes / NODE_BUDGET)))

    @property
    def grammar(self) -> Grammar:
        """The tiling grammar decoding keeps to (setting it rebuilds the decoding masks)."""
        return self._grammar

    @grammar.setter
    def grammar(self, grammar: Grammar) -> None:
        self._grammar = grammar
        self.constraint = Constraint(self.vocab, grammar, self.max_nodes)

    @torch.no_grad()
    def encode(self, strings: list[str]) -> np.ndarray:
        """Posterior means of ``strings``, ``(n, latent)``."""
        with torch_threads():
            return self._encode(strings)

    def _encode(self, strings):
        self.net.eval()
        out = []
        for k in range(0, len(strings), 256):
            enc, lengths, _, _ = _batch(self.vocab, strings[k:k + 256])
            mu, _ = self.net.encode(enc, lengths)
            out.append(mu.numpy())
        return np.concatenate(out).astype(np.float64)

    @torch.no_grad()
    def decode(self, z: np.ndarray, constrained: bool = True, greedy: bool = False,
               rng: np.random.Generator | None = None, max_len: int | None = None,
               temperature: float = 1.0, wrap_bias: float = WRAP_BIAS, wrap: bool = True) -> list[str | None]:
        """Decode latent points; a string per point, or None when decoding ran past
        ``max_len`` or (constrained) reached a prefix no token can continue.

        Tokens are sampled (``rng`` required) at ``temperature``; ``greedy=True`` takes the
        argmax instead (which tends to loop on periodic strings). Constrained decoding also
        stops adding letters once a string has the model's ``max_nodes`` nodes (1.25 times
        the largest training graph), so it must close its rings and branches; and it *wraps
        up* from ``wrap_nodes`` nodes on (0.8 times the largest training graph): no new ring
        labels or branches, and the logits of tokens that close something (a ring label's
        second end, ``)``, the end) get ``wrap_bias`` times (nodes - ``wrap_nodes`` + 1)
        (``wrap=False``: no wrapping up, only the hard budget).
        """
        if not greedy and rng is None:
            raise InvalidArgumentError("sampled decoding needs a numpy Generator (rng)")
        with torch_threads():
            return self._decode(z, constrained, greedy, rng, max_len, temperature, wrap_bias if wrap else 0.0,
                                self.wrap_nodes if wrap else None)

    def _decode(self, z, constrained, greedy, rng, max_len, temperature, wrap_bias, wrap_nodes):
        self.net.eval()
        max_len = max_len or self.net.config.max_len
        zt = torch.as_tensor(np.asarray(z, dtype=np.float32))
        n = zt.shape[0]
        state = self.net.initial_state(zt)
        token = torch.full((n,), SOS, dtype=torch.long)
        prefixes = [_Prefix() for _ in range(n)]
        texts = [[] for _ in range(n)]
        alive = np.ones(n, dtype=bool)
        ok = np.ones(n, dtype=bool)
        for _ in range(max_len + 1):
            logits, state = self.net.step(zt, token, state)
            logits = logits.numpy().astype(np.float64)
            nxt = np.full(n, PAD, dtype=np.int64)
            for k in np.nonzero(alive)[0]:
                row = logits[k]
                if constrained:
                    pk = prefixes[k]
                    allowed = self.constraint.allowed(pk, wrap_nodes)
                    if not allowed:
                        alive[k], ok[k] = False, False
                        continue
                    ids = [EOS if c == "" else self.vocab.stoi[c] for c in allowed]
                    masked = np.full_like(row, -np.inf)
                    masked[ids] = row[ids]
                    row = masked
                    over = len(pk.types) - wrap_nodes + 1 if wrap_nodes is not None else 0
                    if over > 0 and wrap_bias:
                        for c, i in zip(allowed, ids):
                            if self.constraint.closes(pk, c):
                                row[i] += wrap_bias * over
                else:
                    row = row.copy()
                    row[[PAD, SOS]] = -np.inf
                if greedy:
                    t = int(np.argmax(row))
                else:
                    row = row / temperature
                    p = np.exp(row - row.max())
                    p /= p.sum()
                    t = int(rng.choice(len(p), p=p))
                nxt[k] = t
                if t == EOS:
                    alive[k] = False
                    continue
                c = self.vocab.itos[t]
                texts[k].append(c)
                if constrained:
                    self.constraint.advance(prefixes[k], c)
            if not alive.any():
                break
            token = torch.as_tensor(nxt)
        out = []
        for k in range(n):
            if alive[k] or not ok[k]:
                out.append(None)  # ran past max_len or dead-ended
                continue
            out.append("".join(texts[k]))
        return out

    def is_valid(self, text: str | None) -> bool:
        if not text:
            return False
        try:
            return self.grammar.is_valid(parse(text).graph)
        except StringSyntaxError:
            return False

    def save(self, folder: str | os.PathLike, state: TrainState | None = None, optimizer=None) -> None:
        folder = Path(folder)
        folder.mkdir(parents=True, exist_ok=True)
        meta = {"format": "procmod-string-vae/1", "config": asdict(self.net.config), "vocab": self.vocab.chars,
                "grammar": self.grammar.to_json(), "max_nodes": self.max_nodes,
                "train": asdict(state) if state is not None else None}
        save_weights(folder / "vae.pt", self.net, optimizer)
        write_text_atomic(folder / "vae.json", json.dumps(meta, indent=1) + "\n")

    @staticmethod
    def load(folder: str | os.PathLike, with_optimizer: bool = False):
        folder = Path(folder)
        advice = "; train one with 'procmod strings train'"
        meta = read_versioned_json(folder / "vae.json", "procmod-string-vae/1", ModelFileError,
                                   "string VAE metadata", advice)
        payload = load_tensors(folder / "vae.pt", ModelFileError, "string VAE's weights", advice)
        where = str(folder / "vae.json")
        config = config_from_json(VAEConfig, meta.get("config"), f"{where}: config")
        with reading_model_file(where):
            vocab = Vocab(_characters(meta["vocab"], f"{where}: vocab"))
            net = StringVAE(len(vocab), config)
            load_weights(net, payload["model"], folder / "vae.pt", where)
            check_finite_weights(net, str(folder / "vae.pt"))
            max_nodes = meta.get("max_nodes")
            if max_nodes is not None and (isinstance(max_nodes, bool) or not isinstance(max_nodes, int)
                                          or max_nodes < 1):
                raise ModelFileError(f"{where}: max_nodes must be a positive whole number, got {max_nodes!r:.40}")
            model = StringModel(net, vocab, Grammar.from_json(meta["grammar"]), max_nodes)
            state = TrainState(**training_state(meta["train"], f"{where}: train")) if meta.get("train") \
                else TrainState()
        if with_optimizer:
            return model, state, payload.get("optimizer")
        return model


def _characters(value, where: str) -> list:
    """A model file's vocabulary: a list of distinct one-character strings."""
    if (not isinstance(value, list) or not all(isinstance(c, str) and len(c) == 1 for c in value)
            or len(set(value)) != len(value)):
        raise ModelFileError(f"{where} must be a list of distinct characters, got {value!r:.60}")
    return value


def vocab_of(strings: list[str]) -> Vocab:
    """The vocabulary a model trained on ``strings`` uses: their characters, both brackets
    and the ring digits 1-9 (a sample may open a ring the training strings never needed)."""
    return Vocab({c for s in strings for c in s} | set("()") | set("123456789"))


def train_vae(strings: list[str], grammar: Grammar, folder: str | os.PathLike, config: VAEConfig = VAEConfig(),
              seed: int = 0, progress=None, stop_after: int | None = None, device: str | None = None) -> StringModel:
    """Train (or resume training) a string VAE (see :func:`_train_vae`); ``device``: see
    :func:`training_device` (the model comes back on the CPU)."""
    dev = training_device(device)
    with torch_threads():
        model = _train_vae(strings, grammar, folder, config, seed, progress, stop_after, dev)
    model.net.to("cpu")
    return model


def _with_room(config: VAEConfig, strings: list) -> VAEConfig:
    """``config`` with room to decode strings as long as the training ones: a fixed cap
    (320) made 18 of 20 decodings of a 400-character shape's own encodings come back invalid."""
    room = min(CONFIG_LIMITS["max_len"], math.ceil(1.5 * max(map(len, strings))))
    return replace(config, max_len=room) if config.max_len < room else config


def _check_same_training(folder: Path, model, state, config: VAEConfig, vocab, grammar, data: str) -> None:
    """Refuse (:class:`OtherTrainingError`) a checkpoint this training would not resume."""
    if {**asdict(model.net.config), "epochs": 0} != {**asdict(config), "epochs": 0} or \
            model.vocab.chars != vocab.chars:
        raise OtherTrainingError(f"{folder} holds a checkpoint of another configuration or data; use a new "
                                 f"{argument('folder')} or delete it")
    if model.grammar.rules != grammar.rules:
        raise OtherTrainingError(f"{folder} holds a checkpoint trained on other shapes (other tiling rules); use a "
                                 f"new {argument('folder')} or delete it")
    if state.data not in (None, data):
        raise OtherTrainingError(f"{folder} holds a VAE trained on other strings: another collection (or one grown "
                                 f"again), or other {argument('seed')} / {argument('strings_per_shape')} / "
                                 f"{argument('held_out')} than it was trained with; repeat those, or use a new "
                                 f"{argument('folder')}")
    if state.epoch > config.epochs:  # it would be kept as it is, recorded as trained for fewer
        raise OtherTrainingError(f"{folder} holds a VAE trained {state.epoch} epochs, more than the {config.epochs} "
                                 f"asked: ask for at least {state.epoch} to go on from it, or use a new "
                                 f"{argument('folder')}")


def check_vae_resumable(folder: str | os.PathLike, strings: list[str], grammar: Grammar,
                        config: VAEConfig = VAEConfig()) -> None:
    """Raise :class:`OtherTrainingError` when ``folder`` holds a VAE checkpoint that
    :func:`train_vae` with these arguments would refuse to resume (a damaged one raises
    its :class:`ModelFileError`); nothing when it would resume, or there is none."""
    folder = Path(folder)
    if not strings or not ((folder / "vae.json").is_file() and (folder / "vae.pt").is_file()):
        return
    model, state, _ = StringModel.load(folder, with_optimizer=True)
    _check_same_training(folder, model, state, _with_room(config, strings), vocab_of(strings), grammar,
                         fingerprint("\n".join(strings)))


def _train_vae(strings, grammar, folder, config, seed, progress, stop_after, device) -> StringModel:
    """Train (or resume training) a string VAE, checkpointing into ``folder`` every epoch.

    A folder that already holds a checkpoint of the same configuration resumes from its
    last finished epoch (on any device). ``stop_after`` ends after that many epochs of this
    call (tests use it to simulate a kill). Same strings, config, seed and device: same
    weights. The batches and the latent noise are drawn on the CPU, so the random stream
    is the same on every device.
    """
    config.check()
    folder = Path(folder)
    if not strings:
        raise InvalidArgumentError("no training strings")
    config = _with_room(config, strings)
    vocab = vocab_of(strings)
    data = fingerprint("\n".join(strings))
    resume = (folder / "vae.json").is_file() and (folder / "vae.pt").is_file()
    torch.manual_seed(seed)
    if resume:
        model, state, opt_state = StringModel.load(folder, with_optimizer=True)
        _check_same_training(folder, model, state, config, vocab, grammar, data)
        model.grammar = grammar  # a checkpoint saved before the ring-length rule learns it here
        adopt = state.data is None  # saved before the fingerprint was kept: keep it from now on
        state.data = data
    else:
        max_nodes = int(math.ceil(NODE_BUDGET * max(sum(c.isalpha() for c in s) for s in strings)))
        model, state, opt_state = StringModel(StringVAE(len(vocab), config), vocab, grammar,
                                              max_nodes), TrainState(data=data), None
    net = model.net.to(device)
    optimizer = torch.optim.Adam(net.parameters(), lr=config.lr)
    if opt_state is not None:
        optimizer.load_state_dict(opt_state)  # moves the moments to the parameters' device
    if resume and adopt:
        model.save(folder, state, optimizer)
    done_now = 0
    net.config = config  # more epochs than a checkpoint was trained for: train on
    while state.epoch < config.epochs:
        epoch = state.epoch
        # modulo 2**63: a seed past ~9e13 overflowed torch's seed (the same streams below it)
        gen = torch.Generator().manual_seed((seed * 100003 + epoch) % 2 ** 63)
        order = torch.randperm(len(strings), generator=gen).tolist()
        # Length buckets: sort within chunks of 8 batches, then shuffle the batches (less padding).
        chunk = 8 * config.batch
        batches = []
        for k in range(0, len(order), chunk):
            part = sorted(order[k:k + chunk], key=lambda i: len(strings[i]))
            batches += [part[j:j + config.batch] for j in range(0, len(part), config.batch)]
        batches = [batches[i] for i in torch.randperm(len(batches), generator=gen).tolist()]
        beta = config.kl_weight * min(1.0, (epoch + 1) / config.kl_warmup) if config.kl_warmup else config.kl_weight
        net.train()
        tot = rec_tot = kl_tot = 0.0
        t0 = time.perf_counter()
        for batch in batches:
            enc, lengths, dec_in, dec_out = _batch(model.vocab, [strings[i] for i in batch])
            eps = torch.randn((enc.shape[0], config.latent), generator=gen)
            if config.word_dropout > 0:
                drop = (torch.rand(dec_in.shape, generator=gen) < config.word_dropout) & (dec_in > EOS)
                dec_in = dec_in.masked_fill(drop, PAD)
            enc, dec_in, dec_out, eps = enc.to(device), dec_in.to(device), dec_out.to(device), eps.to(device)
            mu, logvar = net.encode(enc, lengths)
            z = mu + eps * torch.exp(0.5 * logvar)
            logits = net.decode_logits(z, dec_in)
            rec = nn.functional.cross_entropy(logits.reshape(-1, logits.shape[-1]), dec_out.reshape(-1),
                                              ignore_index=PAD, reduction="sum") / enc.shape[0]
            kl = -0.5 * torch.sum(1 + logvar - mu.pow(2) - logvar.exp()) / enc.shape[0]
            loss = rec + beta * kl
            optimizer.zero_grad()
            loss.backward()
            nn.utils.clip_grad_norm_(net.parameters(), 5.0)
            optimizer.step()
            n = enc.shape[0]
            tot, rec_tot, kl_tot = tot + loss.item() * n, rec_tot + rec.item() * n, kl_tot + kl.item() * n
        state.epoch += 1
        row = {"epoch": state.epoch, "loss": tot / len(order), "recon": rec_tot / len(order),
               "kl": kl_tot / len(order), "beta": beta, "seconds": round(time.perf_counter() - t0, 2),
               "device": str(device)}
        state.history.append(row)
        model.save(folder, state, optimizer)
        if progress is not None:
            progress(row)
        done_now += 1
        if stop_after is not None and done_now >= stop_after:
            break
    return model
