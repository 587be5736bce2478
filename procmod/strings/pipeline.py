"""The whole seed-001 pipeline as folders: a collection (``augment``), a trained model
(``train``), samples and instantiated meshes.

A collection folder holds ``shapes.json`` (``procmod-shapes/1``: the input shapes first,
then the variants, mesh files copied beside it), ``graphs/`` (one ``procmod-graph/1`` per
shape), ``strings.txt`` (strings of every shape, one a line), ``growth.json`` (the settings
it was grown with and one row per sampling round) and ``contact_sheet.png``. A collection
grown twice with the same seed and a round limit (``--rounds``, no ``--seconds``) is the
same file for file, byte for byte, except the rounds' ``"seconds"`` in growth.json (wall
time since the growth began: the one timing field). ``procmod strings augment`` writes it
into a fresh folder that then replaces ``--out`` whole (:mod:`procmod.core.runfolder`).

A model folder holds ``model.json`` (``procmod-string-model/1``: grammar, settings,
training history), ``collection.json`` (the training shapes, for transplanting),
``vae.json`` + ``vae.pt`` and ``tagger.json`` + ``tagger.pt`` (torch state dicts, loaded
with ``weights_only=True``). Training checkpoints after every epoch, and a run started
again on the same folder resumes where the last one stopped.
"""

from __future__ import annotations

import contextlib
import json
import os
import shutil
from dataclasses import asdict
from pathlib import Path

import networkx as nx
import numpy as np

from ..core.errors import InvalidArgumentError, ProcmodError, argument, check_real, checked_count, spelled
from ..core.io import read_json, read_versioned_json, write_text_atomic
from ..core.paths import is_dir_quietly, output_path, reading_an_outputs_own_files
from ..core.runfolder import COLLECTION, STRINGS_MODEL, RunFolder
from .categories import CategoryParams, EdgeCategories, part_clearances
from .codec import decode, parse, strings_of
from .instantiate import InstantiateResult, instantiate_graph
from .contacts import ENCLOSED_ADVICE, enclosing_parts, loose_parts, only_enclosed, shape_graph
from .grammar import Grammar
from .shapes import (ShapeSet, ShapesFormatError, check_copies, first_poses, graph_to_dict, read_shapes,
                     shapes_to_dict, write_shapes)
from .tagger import TaggerConfig, TaggerModel, tagging_accuracy, tagging_examples, train_tagger
from .torch_utils import ModelFileError, OtherTrainingError, reading_model_file, training_device
from .vae import StringModel, VAEConfig, check_vae_resumable, train_vae

MODEL_FORMAT = "procmod-string-model/1"
# how an error message says to train a model folder (the command line: procmod strings train)
TRAIN_MODEL = "train_model(COLLECTION, out=MODEL)"


class InstantiationError(ProcmodError):
    """A string that could not be built from the model's parts."""


def write_collection(shape_set: ShapeSet, shapes, out: str | os.PathLike, rounds=None, strings_per_shape: int = 8,
                     seed: int = 0, sheet: bool = True, settings: dict | None = None) -> list[str]:
    """Write a collection folder (see the module docstring); returns the strings written.
    ``settings`` (how the collection was grown: seed, sampling constants, duplicate rule)
    go into ``growth.json`` beside the rounds."""
    from .render import write_sheet

    out = Path(out)
    if out.exists() and not out.is_dir():
        raise InvalidArgumentError(f"{argument('out')} {out} exists and is not a folder")
    (out / "graphs").mkdir(parents=True, exist_ok=True)
    write_shapes(shape_set, out / "shapes.json", shapes, COLLECTION.patterns)
    rng = np.random.default_rng([seed, 1])
    strings = []
    for i, shape in enumerate(shapes):
        g = shape_graph(shape_set, shape)
        write_text_atomic(out / "graphs" / f"shape_{i:04d}.json", json.dumps(graph_to_dict(g)) + "\n")
        strings += strings_of(g, strings_per_shape, rng)
    write_text_atomic(out / "strings.txt", "\n".join(strings) + "\n")
    # the inputs come first: train keeps every one of them in training (collection_inputs)
    growth = {"inputs": len(shape_set.shapes), "rounds": rounds or []}
    if settings is not None:
        growth = {"settings": settings, **growth}
    write_text_atomic(out / "growth.json", json.dumps(growth, indent=1) + "\n")
    if sheet:
        write_sheet(shape_set, shapes[:36], out / "contact_sheet.png", size=140, labels=[str(i) for i in range(36)])
    return strings


def read_collection(path: str | os.PathLike) -> ShapeSet:
    """The shapes of a collection folder (or of a shapes file given directly)."""
    path = Path(path)
    if path.is_dir():
        path = path / "shapes.json"
    if not path.is_file():
        raise ShapesFormatError(f"{path} " + ("is not a regular file (a folder, a device or a pipe)" if path.exists()
                                              else "does not exist") +
                                "; give a collection folder made by 'procmod strings augment' or a procmod-shapes/1 "
                                "file")
    from .assets import rigid_shape_set
    return rigid_shape_set(read_shapes(path))


def collection_inputs(path: str | os.PathLike, count: int) -> int:
    """How many of a collection's ``count`` shapes are its input shapes (they come first):
    ``growth.json``'s ``inputs`` (the collection folder's, or the one beside its
    ``shapes.json`` given directly); for a collection grown before it was recorded, its
    first round's shapes less the new ones; every shape of a shapes file of the user's."""
    path = Path(path)
    growth = path / "growth.json" if path.is_dir() else path.with_name("growth.json")
    try:
        data = json.loads(growth.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        data = None
    if not isinstance(data, dict):
        return count
    inputs = data.get("inputs")
    rounds = data.get("rounds")
    if inputs is None and isinstance(rounds, list) and rounds and isinstance(rounds[0], dict):
        inputs = rounds[0].get("shapes", 0) - rounds[0].get("new", 0)
    if isinstance(inputs, int) and not isinstance(inputs, bool) and 0 < inputs <= count:
        return inputs
    return count


def split_shapes(n: int, held_out: float, seed: int, inputs: int = 2) -> tuple[list[int], list[int]]:
    """Indices of training and held-out shapes: the first ``inputs`` (a collection's input
    shapes, :func:`collection_inputs`) always train, and ``held_out`` of the rest (the
    variants augment grew) are held out. Two inputs had been assumed: a collection grown
    from six held the sixth out, and a part type only it used could never be sampled (h69)."""
    rng = np.random.default_rng([seed, 2])
    first = min(n, inputs)
    rest = [int(i) for i in rng.permutation(np.arange(first, n))] if n > first else []
    k = int(round(held_out * len(rest)))
    return sorted(list(range(first)) + rest[k:]), sorted(rest[:k])


def train_model(collection: str | os.PathLike, out: str | os.PathLike, vae_config: VAEConfig = VAEConfig(),
                tagger_config: TaggerConfig = TaggerConfig(), strings_per_shape: int = 8, held_out: float = 0.2,
                seed: int = 0, progress=None, stop_after: int | None = None,
                tagger_strings_per_shape: int = 16, device: str | None = None, overwrite: bool = False) -> dict:
    """Train the VAE and the edge-category tagger on a collection, into a model folder.

    ``out``: an interrupted training there resumes; a non-empty folder that is not an
    earlier model folder is refused unless ``overwrite`` (then replaced whole; see
    :class:`procmod.core.runfolder.RunFolder`).

    ``device``: where both train (``"cpu"``, ``"cuda"``; see
    :func:`~procmod.strings.torch_utils.training_device`); the saved model loads on any machine.

    ``held_out`` of the variants (never the inputs) are kept out of both trainings and
    used for the tagger's held-out accuracy. Returns the model's ``model.json`` content.
    """
    training_device(device)  # a device this machine lacks fails before anything is written
    # numpy's numbers as Python's: they are recorded in model.json, and seed torch
    strings_per_shape = checked_count("strings_per_shape", strings_per_shape)
    tagger_strings_per_shape = checked_count("tagger_strings_per_shape", tagger_strings_per_shape)
    seed = checked_count("seed", seed, least=0, most=2 ** 63 - 1)
    if stop_after is not None:
        stop_after = checked_count("stop_after", stop_after)
    held_out = check_real(argument("held_out"), held_out, "a fraction in [0, 1)", lambda v: 0 <= v < 1)
    vae_config.check()
    tagger_config.check()
    shape_set = read_collection(collection)
    out = output_path(out)  # '..' resolved: no stray folders made on the way to it
    folder = RunFolder(out, STRINGS_MODEL, overwrite, inputs=[collection])
    # a part's file copied where the model's own files go would be replaced by one: refused before the folder is made
    check_copies(shape_set, out / "collection.json", STRINGS_MODEL.patterns)
    # what the collection's shapes can refuse (a loose part) is found before the folder is made
    graphs = [shape_graph(shape_set, s) for s in shape_set.shapes]
    for i, g in enumerate(graphs):
        pieces = sorted(nx.connected_components(g), key=len, reverse=True)
        if len(pieces) > 1:
            enclosed = enclosing_parts(shape_set, shape_set.shapes[i], pieces)
            fix = ENCLOSED_ADVICE if only_enclosed(pieces, enclosed) else "move the parts to touch"
            raise InvalidArgumentError(f"{loose_parts(g, pieces, i, None, shape_set.letters, None, enclosed)} in "
                                       f"{collection}; a string encodes one connected shape: {fix}")
    grammar = Grammar.from_graphs(graphs)
    train_idx, test_idx = split_shapes(len(graphs), held_out, seed, collection_inputs(collection, len(graphs)))
    strings = vae_training_strings(graphs, train_idx, strings_per_shape, seed)
    fresh = not is_dir_quietly(out) or not any(out.iterdir())
    train_shapes = [shape_set.shapes[i] for i in train_idx]
    folder.prepare_in_place(keep=not (overwrite and _other_training(out, strings, grammar, vae_config, shape_set,
                                                                    train_shapes)))
    if (out / "collection.json").is_file():  # a resume: what it holds is read by every later command
        try:
            with reading_an_outputs_own_files():
                kept = read_shapes(out / "collection.json")
        except ProcmodError as exc:  # bad JSON, a part mesh missing or damaged (it marks the folder: kept)
            raise ModelFileError(f"{exc}; restore it, or pass {argument('overwrite=True')} to train the model again "
                                 "from the start") from None
        if not _same_collection(kept, shape_set, train_shapes):  # its training went on, on other shapes
            before, _ = split_shapes(len(graphs), held_out, seed)  # the split before every input trained
            if _same_collection(kept, shape_set, [shape_set.shapes[i] for i in before]):
                raise OtherTrainingError(
                    f"{out} holds a model of this collection trained before procmod kept every input shape in "
                    f"training (two were assumed: {len(shape_set.shapes) - len(before) - len(test_idx)} more train "
                    f"now); pass {argument('overwrite=True')} to train it afresh, or give a new {argument('out')}")
            raise OtherTrainingError(f"{out} holds a model of another collection (its collection.json is not these "
                                     f"shapes, {argument('held_out')} and {argument('seed')}'s training part); use a "
                                     f"new {argument('out')}, or pass {argument('overwrite=True')} to train afresh "
                                     "there")
    else:
        try:
            write_shapes(shape_set, out / "collection.json", train_shapes, STRINGS_MODEL.patterns)
        except BaseException:
            if fresh:  # what it had copied (a mesh file) made the folder a stranger's to the retry
                shutil.rmtree(out, ignore_errors=True)
            raise
    report = progress or (lambda stage, row: None)
    # the trainings' messages name their folder: here it is this function's out
    names = {"folder": argument("out")}
    with spelled(names), _with_overwrite_advice():
        vae = train_vae(strings, grammar, out, vae_config, seed, progress=lambda row: report("vae", row),
                        stop_after=stop_after, device=device)
    if len(vae_history(out)) < vae_config.epochs:
        return {}
    cats_path = out / "categories.json"
    categories = read_categories(cats_path) if cats_path.is_file() else None
    upgrade = categories is not None and categories.clearance is None
    categories, examples, trng = tagger_training_set(shape_set, graphs, train_idx, tagger_strings_per_shape, seed,
                                                     categories)
    if upgrade or not cats_path.is_file():
        write_text_atomic(cats_path, json.dumps(categories.to_json()) + "\n")
    held = tagging_examples(shape_set, [shape_set.shapes[i] for i in test_idx], [graphs[i] for i in test_idx],
                            categories, 4, trng, every_symmetry=True)
    with spelled(names), _with_overwrite_advice():
        try:
            tagger = train_tagger(examples, vae.vocab, categories, out, tagger_config, seed,
                                  progress=lambda row: report("tagger", row), device=device)
        except OtherTrainingError:
            if not overwrite:
                raise
            # the VAE is this training's (checked above): only the tagger starts afresh
            for name in ("tagger.json", "tagger.pt"):
                (out / name).unlink(missing_ok=True)
            tagger = train_tagger(examples, vae.vocab, categories, out, tagger_config, seed,
                                  progress=lambda row: report("tagger", row), device=device)
    meta = {"format": MODEL_FORMAT, "grammar": grammar.to_json(), "seed": seed,
            "strings_per_shape": strings_per_shape, "tagger_strings_per_shape": tagger_strings_per_shape,
            "train_shapes": len(train_idx), "held_out_shapes": len(test_idx),
            "training_strings": len(strings), "categories": len(categories) - 1,
            # per character, structured decoding (stars, rings) and each character alone
            "tagger_held_out_accuracy":
                tagging_accuracy(tagger, held, predicted=_held_out_labels(tagger, held, shape_set, report))
                if held else None,
            "tagger_held_out_accuracy_per_character_argmax":
                tagging_accuracy(tagger, held, structured=False) if held else None,
            "vae": asdict(vae_config), "tagger": asdict(tagger_config),
            "start_pose": _start_poses(shape_set)}
    write_text_atomic(out / "model.json", json.dumps(meta, indent=1) + "\n")
    write_text_atomic(out / "strings.txt", "\n".join(strings) + "\n")
    return meta


def _other_training(out: Path, strings: list, grammar, config: VAEConfig, shape_set: ShapeSet,
                    train_shapes: list) -> bool:
    """Whether ``out`` holds a model this training would not resume: another collection
    (or another training part of it), a VAE checkpoint of another configuration,
    vocabulary, tiling rules, training strings or more epochs than asked, or a damaged
    collection or checkpoint. ``--overwrite`` then starts the folder afresh (it had been
    refused, as without it)."""
    if not is_dir_quietly(out):
        return False
    try:
        with reading_an_outputs_own_files():  # its meshes are the folder's own, not inputs
            if (out / "collection.json").is_file() and \
                    not _same_collection(read_shapes(out / "collection.json"), shape_set, train_shapes):
                return True
        check_vae_resumable(out, strings, grammar, config)
    except ProcmodError:  # another training (OtherTrainingError), or damaged: replaced whole
        return True
    return False


def _same_collection(kept: ShapeSet, shape_set: ShapeSet, train_shapes: list) -> bool:
    """Whether a model folder's collection (``kept``) is ``train_shapes`` of ``shape_set``:
    the same shapes (parts, transforms), part geometry and contact tolerance. A folder that
    had no checkpoint yet kept another collection's file through ``--overwrite``, and the
    model trained on these shapes could not be used with it."""
    def geometry(library: dict) -> dict:
        return {name: (p.kind, p.size, p.vertices, p.faces) for name, p in library.items()}

    return (shapes_to_dict(kept)["shapes"] == shapes_to_dict(shape_set, train_shapes)["shapes"]
            and geometry(kept.library) == geometry(shape_set.library) and kept.tolerance == shape_set.tolerance)


@contextlib.contextmanager
def _with_overwrite_advice():
    """A checkpoint of another training, refused: say how to replace it."""
    try:
        yield
    except OtherTrainingError as exc:
        raise OtherTrainingError(f"{exc}, or pass {argument('overwrite=True')} to train afresh there") from None


def _rebuilt() -> str:
    """What to do with a damaged model file that training writes again from the
    collection when it is missing."""
    return (f"delete it (training writes it again from the collection) or pass {argument('overwrite=True')} to "
            "train the model again from the start")


def read_categories(path: Path) -> EdgeCategories:
    """The edge categories of a model folder's ``categories.json``; a file that does not
    read, or holds content of the wrong shape, is one :class:`ModelFileError` line naming it."""
    try:
        data = read_json(path, ModelFileError, "edge categories file")
    except ModelFileError as exc:
        raise ModelFileError(f"{exc}; {_rebuilt()}") from None
    with reading_model_file(str(path), advice=f"; {_rebuilt()}"):
        return EdgeCategories.from_json(data)


def _held_out_labels(tagger: TaggerModel, held: list, shape_set: ShapeSet, report) -> list:
    """Structured decoding of the held-out strings, reported as stage ``"held-out"``
    (``{"done": strings, "total": strings}``): it takes minutes on a large collection."""
    texts = [text for text, _ in held]
    labels: list = []
    for k in range(0, len(texts), 16):
        labels += tagger.labels(texts[k:k + 16], shape_set)
        report("held-out", {"done": len(labels), "total": len(texts)})
    return labels


def vae_training_strings(graphs: list, train_idx: list[int], strings_per_shape: int, seed: int) -> list[str]:
    """The VAE's training strings as :func:`train_model` draws them: up to
    ``strings_per_shape`` distinct strings of each training graph."""
    rng = np.random.default_rng([seed, 3])
    return [s for i in train_idx for s in strings_of(graphs[i], strings_per_shape, rng)]


def tagger_training_set(shape_set: ShapeSet, graphs: list, train_idx: list[int], strings_per_shape: int, seed: int,
                        categories: EdgeCategories | None = None):
    """The tagger's training data as :func:`train_model` makes it: edge categories fitted on
    the training shapes (unless given), ``strings_per_shape`` strings of each with every
    symmetric target sequence. Returns ``(categories, examples, rng)``; the generator has
    drawn the strings and goes on to draw the held-out ones."""
    train_shapes = [shape_set.shapes[i] for i in train_idx]
    train_graphs = [graphs[i] for i in train_idx]
    if categories is None:
        categories = EdgeCategories.fit(shape_set, train_shapes, train_graphs, CategoryParams())
    elif categories.clearance is None:  # fitted before clearances were kept: add them
        categories.clearance = part_clearances(shape_set, train_shapes, train_graphs)
    rng = np.random.default_rng([seed, 4])
    examples = tagging_examples(shape_set, train_shapes, train_graphs, categories, strings_per_shape, rng,
                                every_symmetry=True)
    return categories, examples, rng


def vae_history(folder) -> list:
    try:
        return json.loads((Path(folder) / "vae.json").read_text()).get("train", {}).get("history", [])
    except (OSError, json.JSONDecodeError):
        return []


def _start_poses(shape_set: ShapeSet) -> dict:
    """Per type, the pose of its first instance in the inputs: the first part of an
    instantiation is placed like that."""
    return {t: m.tolist() for t, m in first_poses(shape_set).items()}


def _pose(value) -> np.ndarray:
    """A 4x4 matrix of finite numbers from a model file."""
    pose = np.asarray(value, dtype=np.float64)
    if pose.shape != (4, 4) or not np.isfinite(pose).all():
        raise ValueError(f"a start pose must be a 4x4 matrix of finite numbers, got {value!r:.60}")
    return pose


class TrainedModel:
    """A model folder, loaded: VAE, tagger, categories, grammar and the training shapes."""

    def __init__(self, folder: str | os.PathLike):
        folder = Path(folder)
        if not (folder / "model.json").is_file():
            raise ModelFileError(f"{folder} is not a trained string model (no model.json); make one with "
                                 f"{argument(TRAIN_MODEL)} (an interrupted training resumes when run again)")
        self.folder = folder
        self.meta = read_versioned_json(folder / "model.json", MODEL_FORMAT, ModelFileError, "string model file")
        self.vae = StringModel.load(folder)
        self.tagger = TaggerModel.load(folder)
        self.categories = self.tagger.categories
        with reading_model_file(str(folder / "model.json")):
            self.grammar = Grammar.from_json(self.meta["grammar"])
            self.vae.grammar = self.grammar  # one grammar per model folder: model.json's
            self.start_pose = {t: _pose(m) for t, m in self.meta["start_pose"].items()}
        self.shape_set = read_shapes(folder / "collection.json")
        self._check_collection_fits()
        try:  # a BOM and CRLF line ends from an editor are read through
            self.training_strings = (folder / "strings.txt").read_text(encoding="utf-8-sig").split()
        except (OSError, UnicodeDecodeError) as exc:
            raise ModelFileError(f"{folder / 'strings.txt'} cannot be read ({exc}); train the model again") from None
        self._strings_file = folder / "strings.txt"

    def _check_collection_fits(self) -> None:
        """Refuse a ``collection.json`` without the part types the VAE and the tagger were
        trained on (copied from another model, a part renamed or removed by hand): it had
        been a KeyError traceback when a shape was built."""
        known = set(self.shape_set.letters.values())
        trained = {c for c in self.vae.vocab.chars if c.isalpha()}
        trained |= {letter for name in self.categories.names if name is not None for letter in name[:2]}
        missing = sorted(trained - known)
        if missing:
            raise ModelFileError(f"{self.folder / 'collection.json'} lacks part types the model was trained on "
                                 f"({', '.join(missing[:8])}{', ...' if len(missing) > 8 else ''}; it holds "
                                 f"{', '.join(sorted(known)[:8])}{', ...' if len(known) > 8 else ''}): it is not the "
                                 "collection this model was trained on; restore that one, or train the model again "
                                 "on this one")

    def check_training_strings(self) -> list[str]:
        """The training strings, each checked to be a string (what sampling encodes and
        compares with); a bad one is a ModelFileError naming the file and its line."""
        for line, text in enumerate(self.training_strings, 1):
            try:
                parse(text)
            except ProcmodError as exc:
                raise ModelFileError(f"{self._strings_file}, string {line}: {exc}; restore the file (training "
                                     "the model again writes it)") from None
        return self.training_strings

    def check_string(self, text: str):
        """The graph of ``text``; raises if it is not a string or breaks the grammar.
        Whitespace around it is not part of it (as :func:`~procmod.strings.codec.decode` reads)."""
        g = decode(text)
        problems = self.grammar.violations(g)
        if problems:
            raise InstantiationError(f"{text!r} breaks the tiling grammar: {'; '.join(problems)}")
        return g

    def instantiate(self, text: str, rng: np.random.Generator, votes: int = 8, attempts: int = 8,
                    budget: int = 1000, soft_vote: bool = True) -> InstantiateResult:
        """Build a shape for a string: the tagger's vote over ``votes`` strings of its graph
        (categories ranked; ``soft_vote=False``: the paper's majority vote, see
        :meth:`TaggerModel.vote`), then the transplanting search from a random edge,
        ``budget`` placements an attempt; another attempt (another start edge and order)
        only when the budget ran out, not when the search proved that no placement realises
        the graph. Short searches restarted beat one long one at the same total: a search
        that goes wrong early rarely recovers (novel prior samples of the bench's three
        models, 30 each: 55 of 90 built at 1000 x 8 against 52 at 4000 x 2, in the same
        time; 40000 x 1 built 1 more of 10 castle failures, docs/strings.md)."""
        votes, attempts, budget = (checked_count(name, value) for name, value in
                                   (("votes", votes), ("attempts", attempts), ("budget", budget)))
        g = self.check_string(text)
        cats = self.tagger.vote(g, votes, rng, self.shape_set, ranked=True, soft=soft_vote)
        result = InstantiateResult(None, False, reason="no attempt")
        for _ in range(attempts):
            result = instantiate_graph(g, cats, self.categories, self.shape_set, rng, self.start_pose, budget=budget)
            if result.success or "budget" not in result.reason:
                return result
        return result
