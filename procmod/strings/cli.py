"""The ``procmod strings ...`` commands (registered into :mod:`procmod.cli`)."""

from __future__ import annotations

import argparse
import json
import math
import sys
from dataclasses import asdict
from pathlib import Path

import numpy as np

from ..core.errors import InvalidArgumentError, cut_text, printable, spelled


SHAPES_HELP = ("a procmod-shapes/1 JSON file, or asset files (.gltf, .glb, .urdf) and folders of them: one shape "
               "per file, one part per distinct mesh (docs/strings.md)")



# Sizes whose work and memory grow with them and that no use needs in the millions
# (defaults 8-16): 10^8 random subgraphs a round or strings a shape grew memory without end.
MAX_PARALLEL = 10_000
MAX_STRINGS_PER_SHAPE = 10_000
MAX_VOTES = 10_000
MAX_RANDOM_STRINGS = 1_000_000  # strings encode --random: ~100 MB of strings held to keep them distinct


PATH_POINTS = 8  # of a --mode path walk


def _at_most(value: int, flag: str, largest: int) -> None:
    if value > largest:
        raise InvalidArgumentError(f"{flag} must be at most {largest:,}, got {value:,}")

def register(sub, int_arg) -> None:
    """Add the ``strings`` subcommand group to the argparse subparsers ``sub``.

    Each leaf parser sets ``handler`` (a function of the parsed args) with ``set_defaults``.
    """
    group = sub.add_parser("strings", help="string-based synthesis of structured shapes (shape graphs, "
                                           "graph sampling, string VAE, instantiation)")
    leaves = group.add_subparsers(dest="strings_command", metavar="STRINGS_COMMAND", parser_class=type(group))
    leaves.required = True

    p = leaves.add_parser("graph", help="shape graphs of a procmod-shapes/1 file or of asset files (glTF, GLB, URDF; "
                                        "one shape per file): one procmod-graph/1 JSON per shape")
    p.add_argument("shapes", metavar="SHAPES", nargs="+", help=SHAPES_HELP)
    p.add_argument("--out", required=True, help="output folder")
    p.add_argument("--tolerance", type=float, help=TOLERANCE_HELP)
    _add_overwrite(p)
    p.set_defaults(handler=_graph)

    p = leaves.add_parser("encode", help="strings of a graph, one a line (the canonical one by default)")
    p.add_argument("graph", metavar="GRAPH.json")
    p.add_argument("--random", type=int_arg, metavar="N", help="N distinct random strings instead (fewer if the "
                                                               "graph has fewer)")
    p.add_argument("--seed", type=int_arg, default=0, help="random seed (default 0)")
    p.set_defaults(handler=_encode)

    p = leaves.add_parser("decode", help="the procmod-graph/1 JSON of a string, to stdout")
    p.add_argument("string", metavar="STRING")
    p.set_defaults(handler=_decode)

    p = leaves.add_parser("augment", help="grow a collection of valid shape variants by graph-based sampling")
    p.add_argument("shapes", metavar="SHAPES", nargs="+", help=SHAPES_HELP)
    p.add_argument("--count", type=int_arg, required=True, help="shapes in the collection (inputs included)")
    p.add_argument("--out", required=True, help="output folder")
    p.add_argument("--seed", type=int_arg, default=0, help="random seed (default 0)")
    p.add_argument("--parallel", type=int_arg, default=8, help="random subgraphs per round (default 8)")
    p.add_argument("--rounds", type=int_arg, default=200, help="at most this many rounds (default 200)")
    p.add_argument("--seconds", type=float, help="stop after this many seconds")
    p.add_argument("--workers", type=int_arg, help="local worker processes (0: one per core; default inline)")
    p.add_argument("--scheduler", help="dask scheduler address tcp://host:8786 (overrides --workers)")
    p.add_argument("--strings-per-shape", type=int_arg, default=8,
                   help="random strings of each shape written to strings.txt (default 8)")
    p.add_argument("--translations-only", action="store_true",
                   help="dock by translations only, so every variant keeps the inputs' orientation (default: keep "
                        "the rotation docking computes, at whatever angle the parts are)")
    p.add_argument("--any-axis", action="store_true",
                   help="let docking turn pieces about any axis, for a set with no up (default: about the vertical, "
                        "z, only: a dock that tilts it turns pieces over)")
    p.add_argument("--max-parts", type=int_arg,
                   help="keep no variant of more parts than this (default: twice the largest input's, at least 120)")
    p.add_argument("--rotate", action="store_true", help=argparse.SUPPRESS)  # the default now; kept for old scripts
    p.add_argument("--tolerance", type=float, help=TOLERANCE_HELP + "; kept in the collection, so that train and "
                                                                    "sample use it too")
    p.add_argument("--distinct", choices=("histogram", "graph"), default="histogram",
                   help="which variants are duplicates: 'histogram' (default, seed 001's conservative rule: "
                        "a node-type histogram seen before) or 'graph' (a shape graph isomorphic to one seen)")
    _add_overwrite(p)
    p.set_defaults(handler=_augment)

    p = leaves.add_parser("train", help="train the string VAE and the edge-category tagger on a collection")
    p.add_argument("collection", metavar="DIR", help="a folder made by 'strings augment' (or a shapes file)")
    p.add_argument("--out", required=True, help="model folder (an interrupted training resumes from it)")
    p.add_argument("--epochs", type=int_arg, default=40, help="VAE epochs (default 40)")
    p.add_argument("--tagger-epochs", type=int_arg, default=24, help="tagger epochs (default 24)")
    p.add_argument("--latent", type=int_arg, default=24, help="the VAE's latent dimensions (default 24)")
    p.add_argument("--hidden", type=int_arg, default=128, help="recurrent units a layer (default 128)")
    p.add_argument("--layers", type=int_arg, default=1, help="recurrent layers (default 1)")
    p.add_argument("--cell", choices=("gru", "lstm"), default="gru", help="recurrent cell (default gru)")
    p.add_argument("--kl-weight", type=float, default=0.1, help="final KL weight beta (default 0.1)")
    p.add_argument("--kl-warmup", type=int_arg, default=10, help="epochs of linear beta warm-up (default 10)")
    p.add_argument("--strings-per-shape", type=int_arg, default=8, help="VAE training strings per shape (default 8)")
    p.add_argument("--tagger-strings-per-shape", type=int_arg, default=16,
                   help="tagger training strings per shape (default 16)")
    p.add_argument("--held-out", type=float, default=0.2,
                   help="fraction of variants held out (default 0.2; the input shapes always train)")
    p.add_argument("--device", default="cpu",
                   help="torch device to train on: cpu (default), cuda or cuda:N; the model is saved for the CPU")
    p.add_argument("--seed", type=int_arg, default=0, help="random seed (default 0)")
    _add_overwrite(p)
    p.set_defaults(handler=_train)

    p = leaves.add_parser("sample", help="sample strings from a trained model; write graphs, strings and meshes")
    p.add_argument("model", metavar="MODEL")
    p.add_argument("-n", type=int_arg, default=16, help="latent points to decode (default 16)")
    p.add_argument("--out", required=True, help="output folder")
    p.add_argument("--mode", choices=("prior", "perturb", "interpolate", "path"), default="prior",
                   help="prior: z ~ N(0, I); perturb / interpolate / path: seed 001 section 5.2")
    p.add_argument("--seed", type=int_arg, default=0, help="random seed (default 0)")
    p.add_argument("--unconstrained", action="store_true", help="decode without grammar masks (checked after)")
    p.add_argument("--no-meshes", action="store_true", help="do not instantiate the valid samples")
    _add_overwrite(p)
    p.set_defaults(handler=_sample)

    p = leaves.add_parser("instantiate", help="build a string as a 3D shape (GLB or OBJ)")
    p.add_argument("model", metavar="MODEL")
    p.add_argument("string", metavar="STRING")
    p.add_argument("--out", required=True, metavar="FILE.glb")
    p.add_argument("--seed", type=int_arg, default=0, help="random seed (default 0)")
    p.add_argument("--votes", type=int_arg, default=8, help="strings of the graph the tagger votes over (default 8)")
    p.add_argument("--majority-vote", action="store_true",
                   help="count each string's labels (seed 001) instead of averaging the tagger's probabilities")
    p.add_argument("--overwrite", action="store_true", help="replace an existing --out file")
    p.set_defaults(handler=_instantiate)


def _add_overwrite(parser) -> None:
    parser.add_argument("--overwrite", action="store_true",
                        help="replace --out whole even if it holds something other than an earlier output of "
                             "this command (an earlier one is replaced without it)")


def _seed(seed: int) -> int:
    if seed < 0:
        raise InvalidArgumentError(f"--seed must be a non-negative integer, got {seed}")
    return seed


def _shape_sources(paths, count: int) -> list | None:
    """The file each of ``count`` shapes came from, when they are asset files one shape
    a file (folders expanded), for messages; None otherwise (a shapes JSON)."""
    from ..core.errors import ProcmodError
    from ..geometry.assets import asset_files, is_asset_file

    if not any(Path(p).is_dir() or is_asset_file(p) for p in paths):
        return None
    try:
        files = asset_files(paths)
    except ProcmodError:
        return None
    return [str(f) for f in files] if len(files) == count > 1 else None


TOLERANCE_HELP = ("contact tolerance in world units: parts this close count as touching (default: a shapes file's "
                  "\"contact_tolerance\", else 0.001 x the median part diagonal)")


LARGE_TOLERANCE = 0.1  # of the median part's size: a contact tolerance above it gets a note


def _take_tolerance(shape_set, tolerance) -> None:
    """A --tolerance given on the command line, checked, as the set's contact tolerance."""
    if tolerance is None:
        return
    from .shapes import checked_tolerance

    shape_set.tolerance = checked_tolerance(tolerance, "--tolerance")


def _graph(args) -> None:
    from ..core.runfolder import GRAPHS_FOLDER, RunFolder
    from .contacts import (contact_kinds, contact_tolerance, enclosed_advice, enclosing_parts, gaps_to_close,
                           joining_text, loose_parts, near_miss_note, only_enclosed, shape_graph)
    from .assets import read_shape_inputs, resized_note, size_note
    from .grammar import Grammar, ring_rule_note
    from ..core.paths import output_path
    from .shapes import write_graph

    shape_set = read_shape_inputs(args.shapes)
    _take_tolerance(shape_set, args.tolerance)
    out = output_path(args.out)
    folder = RunFolder(out, GRAPHS_FOLDER, args.overwrite, inputs=args.shapes)
    tolerance = contact_tolerance(shape_set)
    graphs = [shape_graph(shape_set, s, tolerance) for s in shape_set.shapes]
    with folder.writing() as tmp:
        for i, g in enumerate(graphs):
            write_graph(g, tmp / f"shape_{i:03d}.json")
    grammar = Grammar.from_graphs(graphs)
    # a name is cut as messages cut them (a 5,000-character node name had filled the screen)
    types = ", ".join(f"{cut_text(name, 80)}={letter}" for name, letter in sorted(shape_set.letters.items()))
    import networkx as nx

    named = _shape_sources(args.shapes, len(graphs))
    needs = []  # per shape with gaps, the tolerance that closes them
    kinds = contact_kinds(graphs)
    for i, g in enumerate(graphs):
        pieces = sorted(nx.connected_components(g), key=len, reverse=True) if len(g) else []
        cycles = g.number_of_edges() - g.number_of_nodes() + len(pieces)
        print(f"shape {i}: {g.number_of_nodes()} parts, {g.number_of_edges()} contacts, {cycles} independent cycles")
        join, misses = gaps_to_close(shape_set, shape_set.shapes[i], g, tolerance, kinds)
        if len(pieces) > 1:
            enclosed = enclosing_parts(shape_set, shape_set.shapes[i], pieces)
            fix = (only_enclosed(pieces, enclosed) and enclosed_advice(join) or
                   "move the parts to touch, or give --tolerance in world units to count gaps up to it as contacts ("
                   f"{joining_text(join)}" + (", with near misses left at it" if misses else "") + ")")
            print(printable(f"note: {loose_parts(g, pieces, i, named, shape_set.letters, tolerance, enclosed)}; a "
                            f"string encodes one connected shape, so 'strings augment' refuses it: {fix}"),
                  file=sys.stderr)
        elif misses:
            print(printable(f"note: {near_miss_note(shape_set.shapes[i], misses, tolerance, i, named)}"),
                  file=sys.stderr)
        if join is not None or misses:
            needs.append(max([join or 0.0] + [t for *_, t in misses]))
    for note in (size_note(shape_set, named), resized_note(shape_set)):
        if note is not None:
            print(printable(f"note: {note}"), file=sys.stderr)
    if len(needs) > 1:
        print(f"note: --tolerance {max(needs):.2g} closes every gap named above ({len(needs)} shapes); a tolerance "
              "far past the gaps a hand leaves joins parts that only stand near each other", file=sys.stderr)
    print(printable(f"types: {types}"))  # part names from the input files: one line each, whatever they hold
    print(printable("rules: " + "; ".join(f"{t}: {' | '.join(sorted(k or '-' for k in keys))}"
                                          for t, keys in sorted(grammar.rules.items()))))
    print(printable(ring_rule_note(graphs, grammar)))
    print(f"wrote {len(graphs)} graphs to {out}/")


def _encode(args) -> None:
    from .codec import GraphError

    try:
        _encode_graph(args)
    except GraphError as exc:  # a graph the syntax cannot write: the message names the file, as read errors do
        raise type(exc)(f"{cut_text(str(args.graph))}: {exc}") from None


def _encode_graph(args) -> None:
    from .codec import GraphError, encode
    from .shapes import read_graph

    g = read_graph(args.graph)
    if args.random is None:
        print(encode(g))
        return
    if args.random < 1:
        raise InvalidArgumentError(f"--random must be a positive number of strings, got {args.random}")
    # "up to N": a graph with few strings stops early (PATIENCE); one with billions would
    # hold every string found in memory, so N has a ceiling, and each prints when found
    _at_most(args.random, "--random", MAX_RANDOM_STRINGS)
    found = 0
    for s in random_strings(g, args.random, np.random.default_rng(_seed(args.seed))):
        print(s, flush=True)
        found += 1
    if not found:  # every walk drawn left more rings open than the syntax has labels
        raise GraphError("no random walk of this graph fits the string syntax's ring labels (a part touching a "
                         "hundred others leaves a ring open for each): its canonical string (strings encode without "
                         "--random) is written another way")


# ``strings encode --random N`` stops drawing once this many draws in a row (and at least
# as many as it has strings) found nothing new: a graph with 56 distinct strings would
# otherwise be encoded 4N times (400,000 for N = 100,000: minutes) to find no more.
PATIENCE = 1000


def random_strings(g, count: int, rng: np.random.Generator):
    """Up to ``count`` distinct random strings of ``g``, yielded as found, drawn as
    :func:`~procmod.strings.codec.strings_of` draws them (``canonical=False``: same
    generator, same order, same strings), but giving up after ``max(PATIENCE, strings
    found)`` draws in a row without a new one, not only after ``4 * count`` draws.

    Each draw is one root and neighbour order: a string missed by that many draws in a
    row is rarer than one in about ``PATIENCE`` draws."""
    from .codec import RingLimitError, encode

    seen, stale = set(), 0
    for _ in range(4 * count):
        if len(seen) >= count or stale >= max(PATIENCE, len(seen)):
            break
        try:
            s = encode(g, rng=rng)
        except RingLimitError:  # a walk leaving more rings open than there are labels: no string
            stale += 1
            continue
        if s in seen:
            stale += 1
            continue
        seen.add(s)
        stale = 0
        yield s


def _decode(args) -> None:
    from .codec import decode
    from .shapes import graph_to_dict

    print(json.dumps(graph_to_dict(decode(args.string))))


def _augment(args) -> None:
    from ..progress import progress_bar

    from ..core.runfolder import COLLECTION, RunFolder
    from ..parallel import check_scheduler, open_executor
    from .pipeline import write_collection
    from .shapes import check_copies
    from .assets import read_shape_inputs, resized_note, size_note
    from .sampling import AugmentParams, augment, with_part_limit
    from ..core.paths import output_path

    shape_set = read_shape_inputs(args.shapes)
    _take_tolerance(shape_set, args.tolerance)
    if args.count < 1 or args.parallel < 1 or args.rounds < 1:
        raise InvalidArgumentError("--count, --parallel and --rounds must be positive integers")
    if args.seconds is not None and not (math.isfinite(args.seconds) and args.seconds > 0):
        raise InvalidArgumentError(f"--seconds must be a positive number of seconds, got {args.seconds}")
    if args.strings_per_shape < 1:
        raise InvalidArgumentError(f"--strings-per-shape must be a positive integer, got {args.strings_per_shape}")
    if args.max_parts is not None and args.max_parts < 1:
        raise InvalidArgumentError(f"--max-parts must be a positive integer, got {args.max_parts}")
    _at_most(args.parallel, "--parallel", MAX_PARALLEL)
    _at_most(args.strings_per_shape, "--strings-per-shape", MAX_STRINGS_PER_SHAPE)
    if args.workers is not None and args.workers < 0:
        raise InvalidArgumentError(f"--workers must be >= 0 (0 = one per core), got {args.workers}")
    if args.scheduler is not None:
        check_scheduler(args.scheduler)
    _seed(args.seed)
    out = output_path(args.out)
    folder = RunFolder(out, COLLECTION, args.overwrite, inputs=args.shapes)
    check_copies(shape_set, out / "shapes.json", COLLECTION.patterns)  # refused now, not after the rounds
    import networkx as nx

    from .codec import RingLimitError, encode
    from .contacts import (DEFAULT_TOLERANCE, contact_kinds, contact_tolerance, enclosed_advice, enclosing_parts,
                           gaps_to_close, joining_text, loose_parts, median_part_size, near_miss_note, only_enclosed,
                           shape_graph)
    named = _shape_sources(args.shapes, len(shape_set.shapes))
    tolerance = contact_tolerance(shape_set)
    part_size = median_part_size(shape_set.library)
    if tolerance > LARGE_TOLERANCE * part_size:
        # every part then touches its neighbours' neighbours: the grammar learns that, and
        # sampling finds few shapes (or none: --tolerance 1e6 ran to --rounds silently)
        print(f"note: the contact tolerance {tolerance:.3g} is {tolerance / part_size:.0%} of the median part's "
              f"size ({part_size:.3g}): parts that far apart count as touching, so the shape graphs hold contacts "
              "the shapes do not have and few new shapes may be found; give the gap the parts were placed with",
              file=sys.stderr)
    from .sampling import SeenShapes
    alike = SeenShapes(shape_set, "graph")  # inputs with the same shape graph (a shape given twice)
    graphs = [shape_graph(shape_set, shape, tolerance) for shape in shape_set.shapes]
    kinds = contact_kinds(graphs)
    for i, (shape, g) in enumerate(zip(shape_set.shapes, graphs)):  # refused now, not after the first round
        if not alike.add(shape, g):
            source = f" ({named[i]})" if named else ""
            print(printable(f"note: input shape {i}{source} has the same shape graph as an earlier input shape (the "
                            "same parts in the same contacts, wherever they are placed): its strings are that "
                            "shape's, and the grammar counts them once more"), file=sys.stderr)
        pieces = sorted(nx.connected_components(g), key=len, reverse=True)
        join, misses = gaps_to_close(shape_set, shape, g, tolerance, kinds)
        if len(pieces) > 1:
            given = ("the --tolerance given" if args.tolerance is not None else "the shapes file's contact_tolerance"
                     if shape_set.tolerance is not None else f"{DEFAULT_TOLERANCE:g} x the median part's size")
            enclosed = enclosing_parts(shape_set, shape, pieces)
            fix = (only_enclosed(pieces, enclosed) and enclosed_advice(join) or
                   "move the parts to touch, or give --tolerance in world units to count gaps up to it as contacts "
                   f"({joining_text(join)}; 'strings graph --tolerance' shows what it joins)")
            raise InvalidArgumentError(
                f"{loose_parts(g, pieces, i, named, shape_set.letters, tolerance, enclosed)} (the contact tolerance: "
                f"{given}); a string encodes one connected shape: {fix}")
        if misses:
            print(printable(f"note: {near_miss_note(shape, misses, tolerance, i, named)}"), file=sys.stderr)
        try:  # a shape no string can write: refused now (it ran for minutes, then failed writing the collection)
            encode(g)
        except RingLimitError as exc:
            source = f" ({named[i]})" if named else ""
            raise InvalidArgumentError(f"shape {i}{source} ({len(g)} parts, {g.number_of_edges()} contacts) cannot "
                                       f"be written as a string: {exc}; a lattice this large is beyond "
                                       "strings") from None
    for note in (size_note(shape_set, named), resized_note(shape_set)):
        if note is not None:
            print(printable(f"note: {note}"), file=sys.stderr)
    if len(shape_set.shapes) > 2:
        print(f"note: {len(shape_set.shapes)} input shapes; seed 001 uses one or two", file=sys.stderr)
    bar = progress_bar(total=args.count, unit=" shapes")
    bar.update(len(shape_set.shapes))

    def progress(row):
        bar.n = row["shapes"]
        bar.refresh()

    if args.any_axis and args.translations_only:
        raise InvalidArgumentError("--any-axis lets docking turn pieces, --translations-only forbids turns: give one")
    params = with_part_limit(AugmentParams(rotate=not args.translations_only, upright=not args.any_axis,
                                           distinct=args.distinct, max_parts=args.max_parts), shape_set.shapes)
    with open_executor(args.workers, args.scheduler,
                       note=lambda text: print(f"note: {text}", file=sys.stderr)) as executor:
        result = augment(shape_set, args.count, seed=_seed(args.seed), parallel=args.parallel,
                         max_rounds=args.rounds, executor=executor, params=params,
                         progress=progress, seconds=args.seconds)
    bar.close()
    shapes_read = str(args.shapes[0]) if len(args.shapes) == 1 else [str(p) for p in args.shapes]
    settings = {"shapes": shapes_read, "count": args.count, "seed": args.seed, "parallel": args.parallel,
                "max_rounds": args.rounds, "seconds": args.seconds, **asdict(params)}
    with folder.writing() as tmp:
        strings = write_collection(shape_set, result.shapes, tmp, result.rounds, args.strings_per_shape, args.seed,
                                   settings=settings)
    seconds = result.rounds[-1]["seconds"] if result.rounds else 0.0
    grown = len(result.shapes) - len(shape_set.shapes)
    if grown == 0 and result.rounds:
        print(f"note: {_no_growth(result.rounds, args)}", file=sys.stderr)
    print(f"{len(result.shapes)} shapes ({grown} new) after "
          f"{len(result.rounds)} rounds in {seconds:.1f} s; {len(strings)} strings; wrote {out}/")


def _no_growth(rounds: list, args) -> str:
    """Why an augment grew no shape, as far as its rounds tell (h119: walls of bricks placed
    by eye, 0.5 mm off, grew none in 200 rounds without a word)."""
    attempts, valid = sum(r["attempts"] for r in rounds), sum(r["valid"] for r in rounds)
    if valid == 0:
        widen = ("a larger --tolerance" if args.tolerance is not None else
                 "--tolerance with the largest gap or overlap between touching parts (in world units)")
        return (f"no new shape in {len(rounds)} rounds: none of the {attempts:,} attempts docked a piece where its "
                "boundary matches; parts placed by hand a little apart or overlapping dock only within the contact "
                f"tolerance: give {widen}, or --any-axis for a set with no up")
    return (f"no new shape in {len(rounds)} rounds: the {valid:,} shapes made (of {attempts:,} attempts) were all "
            "alike to shapes held already" + (" by their node-type histograms: --distinct graph counts shapes of "
                                              "other contacts as new" if args.distinct == "histogram" else "")
            + "; more --rounds may find others")


def _train(args) -> None:
    from ..progress import progress_bar

    from .tagger import TaggerConfig
    from .pipeline import train_model
    from ..core.paths import output_path
    from .vae import VAEConfig

    if not 0 <= args.held_out < 1:
        raise InvalidArgumentError(f"--held-out must be in [0, 1), got {args.held_out}")
    vae = VAEConfig(cell=args.cell, hidden=args.hidden, layers=args.layers, latent=args.latent,
                    kl_weight=args.kl_weight, kl_warmup=args.kl_warmup, epochs=args.epochs)
    with spelled({name: "--" + name.replace("_", "-") for name in ("hidden", "layers", "latent", "kl_weight",
                                                                    "kl_warmup", "epochs")}):
        vae.check()  # (its messages name the fields; a model file's are named so, with the file)
    tagger = TaggerConfig(epochs=args.tagger_epochs)
    if not 1 <= args.tagger_epochs <= 1_000_000:  # 0 or -3 trained nothing, without a word
        raise InvalidArgumentError(f"--tagger-epochs must be a whole number from 1 to 1,000,000, got "
                                   f"{args.tagger_epochs}")
    bars = {}

    def progress(stage, row):
        # epochs of the VAE and the tagger, then the held-out strings the tagger labels
        counted = "done" if stage == "held-out" else "epoch"
        total = row["total"] if stage == "held-out" else args.epochs if stage == "vae" else args.tagger_epochs
        bar = bars.get(stage)
        if bar is None:
            unit = " strings" if stage == "held-out" else " epochs"
            bar = bars[stage] = progress_bar(total=total, unit=unit, desc=stage)
        bar.n = row[counted]
        bar.set_postfix({k: f"{v:.3g}" for k, v in row.items() if k not in (counted, "total", "seconds", "device")},
                       refresh=False)
        bar.refresh()

    if args.strings_per_shape < 1 or args.tagger_strings_per_shape < 1:
        raise InvalidArgumentError("--strings-per-shape and --tagger-strings-per-shape must be positive integers")
    _at_most(args.strings_per_shape, "--strings-per-shape", MAX_STRINGS_PER_SHAPE)
    _at_most(args.tagger_strings_per_shape, "--tagger-strings-per-shape", MAX_STRINGS_PER_SHAPE)
    out = output_path(args.out)
    meta = train_model(args.collection, out, vae, tagger, args.strings_per_shape, args.held_out,
                       _seed(args.seed), progress, tagger_strings_per_shape=args.tagger_strings_per_shape,
                       device=args.device, overwrite=args.overwrite)
    for bar in bars.values():
        bar.close()
    acc = meta.get("tagger_held_out_accuracy")
    if args.held_out > 0 and not meta.get("held_out_shapes"):
        print(f"note: no shape held out: all {meta['train_shapes']} are input shapes, which always train "
              f"(--held-out holds out variants 'procmod strings augment' grew)", file=sys.stderr)
    print(f"trained on {meta['training_strings']} strings of {meta['train_shapes']} shapes; "
          f"{meta['categories']} edge categories; tagger accuracy on held-out strings: "
          f"{'n/a' if acc is None else f'{100 * acc:.1f}%'}; model in {out}/")


def _sample(args) -> None:
    from ..core.serialize import write_text_atomic
    from .codec import decode
    from .latent import GraphIndex, interpolate, latent_path, one_per_graph, perturb, sample_path
    from .pipeline import TrainedModel
    from .render import write_shape_mesh, write_shape_png, write_sheet
    from ..core.paths import output_path
    from .shapes import graph_to_dict

    from ..core.limits import check_memory
    from ..core.runfolder import STRING_SAMPLES, RunFolder

    if args.n < 1:
        raise InvalidArgumentError(f"-n must be a positive number of samples, got {args.n}")
    model = TrainedModel(args.model)
    rng = np.random.default_rng(_seed(args.seed))
    out = output_path(args.out)
    folder = RunFolder(out, STRING_SAMPLES, args.overwrite, inputs=[args.model])
    # the latent points and their decoded strings are held together: a lower bound per point
    check_memory(f"-n {args.n:,} latent points", 8.0 * args.n * (model.vae.net.config.latent + 64),
                 "ask for fewer")
    train = model.check_training_strings()
    vae = model.vae
    if args.mode == "prior":
        z = rng.standard_normal((args.n, vae.net.config.latent))
        decoded = vae.decode(z, constrained=not args.unconstrained, rng=rng)
    else:
        anchors = vae.encode(train)
        decoded = []
        distinct = len({tuple(a) for a in np.asarray(anchors).tolist()})
        if args.mode == "path" and distinct < PATH_POINTS:
            raise InvalidArgumentError(
                f"--mode path walks a latent path of {PATH_POINTS} points through the model's training encodings, "
                f"and this model has {distinct} distinct ones; train it on more shapes (procmod strings augment "
                "makes more) or use --mode interpolate")
        for _ in range(args.n):
            i, j = (int(k) for k in rng.integers(len(train), size=2))
            if args.mode == "perturb":
                decoded.append(perturb(vae, anchors[i], train[i], rng))
            elif args.mode == "interpolate":
                found = interpolate(vae, anchors[i], anchors[j], 5, rng)
                decoded.append(found[len(found) // 2] if found else None)
            else:
                path = latent_path(anchors[i], anchors[j], anchors, PATH_POINTS)
                found = sample_path(vae, path, 2, rng)
                decoded.append(found[int(rng.integers(len(found)))] if found else None)
    valid = [s for s in decoded if vae.is_valid(s)]
    # one table written three ways had been written, instantiated and counted as "unique" three times (h69)
    unique = one_per_graph(valid, decode)
    known = GraphIndex(decode(s) for s in dict.fromkeys(train))
    novel = [s for s in unique if decode(s) not in known]  # a graph no training string has
    with folder.writing() as tmp:
        write_text_atomic(tmp / "samples.txt", "\n".join(unique) + ("\n" if unique else ""))
        built, shapes, rows = 0, [], []
        novel_set = set(novel)
        for k, s in enumerate(unique):
            write_text_atomic(tmp / f"sample_{k:03d}.json", json.dumps(graph_to_dict(decode(s))) + "\n")
            row = {"sample": k, "string": s, "novel": s in novel_set}
            rows.append(row)
            if args.no_meshes:
                continue
            result = model.instantiate(s, rng)
            row["instantiated"] = result.success
            if not result.success:  # why not: the search's own words (budget spent, proven impossible, ...)
                row["reason"] = result.reason
            if result.success:
                built += 1
                write_shape_mesh(model.shape_set, result.shape, tmp / f"sample_{k:03d}.glb")
                write_shape_png(model.shape_set, result.shape, tmp / f"sample_{k:03d}.png", 200)
                shapes.append((k, result.shape))
        if shapes:
            write_sheet(model.shape_set, [s for _, s in shapes], tmp / "contact_sheet.png", 160,
                        labels=[str(k) for k, _ in shapes])
        summary = {"mode": args.mode, "decoded": len(decoded), "valid": len(valid), "unique": len(unique),
                   "novel": len(novel), "instantiated": built, "samples": rows}
        write_text_atomic(tmp / "summary.json", json.dumps(summary, indent=1) + "\n")
    print(f"{args.n} points: {len(valid)} valid, {len(unique)} unique, {len(novel)} novel; "
          + ("" if args.no_meshes else f"{built} instantiated; ") + f"wrote {out}/")


def _instantiate(args) -> None:
    from ..core.runfolder import check_output_file
    from .pipeline import InstantiationError, TrainedModel
    from .render import write_shape_mesh
    from ..core.paths import output_path

    out = output_path(args.out)
    if out.suffix.lower() not in (".glb", ".obj"):
        raise InvalidArgumentError(f"--out must end in .glb or .obj, got {out.name!r}")
    if args.votes < 1:
        raise InvalidArgumentError(f"--votes must be a positive integer, got {args.votes}")
    _at_most(args.votes, "--votes", MAX_VOTES)
    # --out may not be the model folder, a file in it (its part meshes) or a file its files
    # name: checked now, and again once the model is read (the files it names) and before writing
    check_output_file(out, make_parent=True, inputs=[args.model], overwrite=args.overwrite)
    model_folder = Path(args.model).resolve()
    if model_folder.is_dir() and out.resolve().is_relative_to(model_folder):
        # a file of the user's in a model folder stops 'strings train' resuming into it, and
        # the --overwrite it advises would delete the trained model
        raise InvalidArgumentError(f"--out {cut_text(str(out))} is inside the model folder "
                                   f"{cut_text(str(args.model))}; write the shape elsewhere (training again into "
                                   "that folder must find only its own files)")
    model = TrainedModel(args.model)
    check_output_file(out, make_parent=True, inputs=[args.model], overwrite=args.overwrite)
    result = model.instantiate(args.string, np.random.default_rng(_seed(args.seed)), votes=args.votes,
                               soft_vote=not args.majority_vote)
    if not result.success:
        hint = ("no choice of the example poses realises this graph (often a ring of a length the example "
                "shapes never show); sample another string" if "every candidate pose tried" in result.reason
                else "try another --seed")
        raise InstantiationError(f"could not build {args.string!r}: {result.reason}; {hint}")
    check_output_file(out, make_parent=True, inputs=[args.model], overwrite=args.overwrite)
    out.parent.mkdir(parents=True, exist_ok=True)
    write_shape_mesh(model.shape_set, result.shape, out)
    print(f"wrote {out} ({len(result.shape)} parts, {result.fallbacks} Monte Carlo fallbacks)")
