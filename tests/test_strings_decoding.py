"""Structured decoding of edge categories: stars seen in training and ring closure."""

import itertools
from pathlib import Path

import numpy as np
import pytest

from procmod.strings.codec import parse
from procmod.strings.decoding import CategoryDecoder, DecoderParams, star_set, stars_of_labelling
from procmod.strings.categories import EdgeCategories
from procmod.strings.tagger import category_decoder, string_mask, tagging_examples
from procmod.strings.contacts import shape_graph
from procmod.strings.shapes import read_shapes

SETS = Path(__file__).resolve().parents[1] / "examples_sets" / "strings"


def _edge_chars(text):
    """Per edge (min, max), the characters that write it."""
    out = {}
    for i, e in enumerate(parse(text).char_edges):
        if e is not None:
            out.setdefault((min(e), max(e)), []).append(i)
    return out


def test_stars_of_a_labelling():
    text = "C1CC(N)CC1O"  # a six-ring with two branches
    chars = _edge_chars(text)
    labels = np.zeros(len(text), dtype=int)
    for n, (_, idx) in enumerate(sorted(chars.items())):
        labels[idx] = n + 1
    stars = dict(enumerate(stars_of_labelling(text, labels)))
    edges = sorted(chars)
    for v in range(parse(text).graph.number_of_nodes()):
        mine = tuple(sorted(n + 1 for n, e in enumerate(edges) if v in e))
        assert stars[v] == (parse(text).graph.nodes[v]["type"], mine)
    # every symmetric target sequence contributes its stars
    other = np.where(labels > 0, 9, 0)
    assert set(star_set([(text, [labels.tolist(), other.tolist()])])) == \
        set(stars_of_labelling(text, labels)) | set(stars_of_labelling(text, other))


def _objective(text, prob, labels, seen, penalty):
    """Log-probability of a labelling of the edges less the penalty per unseen star."""
    chars = _edge_chars(text)
    per_char = np.zeros(len(text), dtype=int)
    for e, idx in chars.items():
        per_char[idx] = labels[e]
    score = sum(np.log(prob[i, per_char[i]]) for idx in chars.values() for i in idx)
    unseen = sum(s not in seen for s in stars_of_labelling(text, per_char))
    return score - penalty * unseen


def test_decoding_with_a_wide_beam_is_the_exact_optimum(rng):
    """With a beam holding every labelling, the result is the brute-force optimum of
    log-probability less the penalty per part with an unseen star."""
    text = "A1BAB1(A)B"  # a four-ring with two pendant parts: 6 edges
    chars = _edge_chars(text)
    k = 3  # categories 1, 2 (0 is the dummy)
    seen = [("A", (1, 2)), ("A", (1, 1, 2)), ("A", (1,)), ("B", (1, 2)), ("B", (2, 2, 2)), ("B", (1,)), ("B", (2,))]
    params = DecoderParams(beam=2 ** len(chars), candidates=2, penalty=3.0)
    decoder = CategoryDecoder(None, seen, params=params)
    for _ in range(20):
        prob = np.zeros((len(text), k))
        for idx in chars.values():
            p = rng.dirichlet([1.0, 1.0])
            prob[idx, 1:] = p
        prob[prob.sum(1) == 0, 0] = 1.0
        out = decoder.decode(text, prob)
        got = {e: int(out[idx[0]]) for e, idx in chars.items()}
        assert all(len({int(out[i]) for i in idx}) == 1 for idx in chars.values())  # a ring edge agrees
        best = max(_objective(text, prob, dict(zip(chars, c)), set(seen), 3.0)
                   for c in itertools.product((1, 2), repeat=len(chars)))
        assert _objective(text, prob, got, set(seen), 3.0) == pytest.approx(best)


def test_an_unseen_star_is_repaired_at_its_least_sure_edge():
    text = "ABA"  # a B between two As; seen: a B has one edge of each category
    prob = np.zeros((3, 3))
    prob[0, 0] = 1.0
    prob[1] = [0.0, 0.9, 0.1]  # A-B: surely 1
    prob[2] = [0.0, 0.6, 0.4]  # B-A: argmax 1 too, but B with (1, 1) is unseen
    decoder = CategoryDecoder(None, [("B", (1, 2)), ("A", (1,)), ("A", (2,))])
    assert prob.argmax(1).tolist() == [0, 1, 1]
    assert decoder.decode(text, prob).tolist() == [0, 1, 2]
    assert decoder.faults(text, [0, 1, 1]) == 1 and decoder.faults(text, [0, 1, 2]) == 0
    # without stars the decoder keeps the argmax
    assert CategoryDecoder(None).decode(text, prob).tolist() == [0, 1, 1]


@pytest.fixture(scope="module")
def moonbase_labelled():
    ss = read_shapes(SETS / "moonbase.json")
    graphs = [shape_graph(ss, s) for s in ss.shapes]
    cats = EdgeCategories.fit(ss, ss.shapes, graphs)
    examples = tagging_examples(ss, ss.shapes, graphs, cats, 3, np.random.default_rng(0), every_symmetry=True)
    decoder = category_decoder(cats, None, ss)
    return cats, examples, decoder


def test_training_labellings_close_their_rings_and_a_wrong_ring_edge_does_not(moonbase_labelled):
    """The labellings of training shapes close every ring; a ring edge whose category does not
    close is set right by decoding, even where the tagger prefers it."""
    cats, examples, decoder = moonbase_labelled
    tried = 0
    for text, seqs in examples:
        for seq in seqs:  # every symmetric copy of a shape closes its rings
            assert decoder.faults(text, seq) == 0
        chars = _edge_chars(text)
        ring_edges = [e for e, idx in chars.items() if len(idx) == 2]
        assert ring_edges  # the moon base inputs have rings
        truth = np.array(seqs[0])
        allowed, _ = string_mask(text, cats)
        for e in ring_edges:
            for wrong in np.flatnonzero(allowed[chars[e][0]]):
                if wrong == truth[chars[e][0]]:
                    continue
                bad = truth.copy()
                bad[chars[e]] = wrong
                if decoder.faults(text, bad) == 0:
                    continue  # the labelling of another shape (a turned root reads categories differently)
                # the tagger prefers the wrong category on this edge only: decoding restores the truth
                prob = np.where(allowed, 0.01, 0.0)
                prob[np.arange(len(text)), truth] = 1.0
                prob[chars[e], wrong], prob[chars[e], truth[chars[e][0]]] = 0.6, 0.3
                prob /= prob.sum(1, keepdims=True)
                assert prob.argmax(1)[chars[e][0]] == wrong
                assert decoder.decode(text, prob).tolist() == truth.tolist()
                tried += 1
    assert tried > 0


# -- colonnade: a chain of columns and beams whose turns the graph does not fix ---------------

def _colonnade_chain(cells, ring=False):
    """A column (with its floor) at each cell and a beam between consecutive cells (and,
    with ``ring``, from the last cell back to the first), written as a string whose node
    order is ``parts``' order; transforms as in make_sets.py."""
    def placed(x, y, z, quarter=0):
        c, s = [(1, 0), (0, 1)][quarter]
        return np.array([[c, -s, 0, x], [s, c, 0, y], [0, 0, 1, z], [0, 0, 0, 1]], dtype=float)

    def beam(a, b):
        return "beam", placed(a[0] + b[0], a[1] + b[1], 2.95, 0 if a[1] == b[1] else 1)
    parts, text = [], ""
    for n, (i, j) in enumerate(cells):
        if n:
            parts.append(beam(cells[n - 1], (i, j)))
            text += "B"
        parts += [("column", placed(2 * i, 2 * j, 1.55)), ("floor", placed(2 * i, 2 * j, 0.15))]
        text += ("C1(F)" if ring and not n else "C(F)") if n < len(cells) - 1 or ring else "CF"
    if ring:
        parts.append(beam(cells[-1], cells[0]))
        text += "B1"
    return text, parts


def _labels_of_placement(cats, ss, text, parts):
    """Per-character categories of ``text`` read off the parts' placement."""
    from procmod.strings.frames import canonical_frame

    frames = [canonical_frame(ss.library, p, m, cats.groups) for p, m in parts]
    letters = [ss.letters[p] for p, _ in parts]
    labels = np.zeros(len(text), dtype=int)
    for i, e in enumerate(parse(text).char_edges):
        if e is not None:
            a, b = e
            labels[i] = cats.category_of_frames(frames[a], frames[b], letters[a], letters[b])
    return labels


@pytest.fixture(scope="module")
def colonnade_fitted():
    ss = read_shapes(SETS / "colonnade.json")
    graphs = [shape_graph(ss, s) for s in ss.shapes]
    return ss, EdgeCategories.fit(ss, ss.shapes, graphs)


def test_clearances_are_the_closest_non_neighbours(colonnade_fitted):
    ss, cats = colonnade_fitted
    # columns stand on a 2 m grid and never touch; a beam's two columns are its neighbours,
    # so the closest column that is not is the one round a corner: 1 m along the beam, 2 m
    # across, 1.4 m down
    assert cats.clearance[("C", "C")] == pytest.approx(2.0)
    assert cats.clearance[("F", "F")] == pytest.approx(2.0)
    assert cats.clearance[("B", "C")] == pytest.approx(np.sqrt(1.0 + 4.0 + 1.4 ** 2))
    # kept through JSON; categories saved before clearances load without them
    assert EdgeCategories.from_json(cats.to_json()).clearance == cats.clearance
    old = cats.to_json()
    del old["clearance"]
    assert EdgeCategories.from_json(old).clearance is None


def test_a_chain_that_turns_back_onto_itself_is_a_fault(colonnade_fitted):
    """Three left turns bring a fifth column onto the first: no ring says so, the
    clearance does (and only with clearances kept)."""
    ss, cats = colonnade_fitted
    decoder = category_decoder(cats, None, ss)
    text, parts = _colonnade_chain([(0, 0), (1, 0), (1, 1), (0, 1)])  # a U: nothing clashes
    assert decoder.faults(text, _labels_of_placement(cats, ss, text, parts)) == 0
    text, parts = _colonnade_chain([(0, 0), (1, 0), (1, 1), (0, 1), (0, 0)])
    labels = _labels_of_placement(cats, ss, text, parts)
    # pairs that clash: the fifth column with the first, its floor with the first floor, each
    # of those with the other's column / floor, the last beam with the first column and the
    # first beam with the fifth column
    assert decoder.faults(text, labels) == 6
    old = EdgeCategories.from_json({k: v for k, v in cats.to_json().items() if k != "clearance"})
    assert category_decoder(old, None, ss).faults(text, labels) == 0


def test_a_ring_closes_only_where_its_last_part_lands(colonnade_fitted):
    """The closing edge's category must be its parts' pose, not merely the nearest category
    to a pose metres off (which would let any ring close)."""
    from procmod.strings.frames import canonical_frame

    ss, cats = colonnade_fitted
    decoder = category_decoder(cats, None, ss)
    column = canonical_frame(ss.library, "column", np.eye(4), cats.groups)
    beam_pose = np.eye(4)
    beam_pose[:3, 3] = [1.0, 0.0, 1.4]
    beam = canonical_frame(ss.library, "beam", beam_pose, cats.groups)
    k = cats.category_of_frames(column, beam, "C", "B")
    assert decoder._closes(column, beam, "C", "B", k)
    far = beam.copy()
    far[:3, 3] += [4.0, 2.0, 0.0]
    assert cats.category_of_frames(column, far, "C", "B") == k  # the nearest category is still k
    assert not decoder._closes(column, far, "C", "B", k)


def test_a_fault_found_late_is_searched_again_wider(colonnade_fitted):
    """The tagger prefers a wrong turn early in a ring of columns: a beam of one has dropped
    the right turn by the time the ring fails to close; the wider retry, made only because
    the labelling found has a fault, keeps it."""
    ss, cats = colonnade_fitted
    cells = [(0, 0), (1, 0), (2, 0), (2, 1), (2, 2), (1, 2), (0, 2), (0, 1)]
    text, parts = _colonnade_chain(cells, ring=True)
    truth = _labels_of_placement(cats, ss, text, parts)
    narrow = CategoryDecoder(cats, None, *_geometry(cats, ss), DecoderParams(beam=1, retry_beam=0))
    assert narrow.faults(text, truth) == 0
    # the beam leaving the corner column at (2, 0): the tagger would go straight on
    straight, straight_parts = _colonnade_chain(cells[:3] + [(3, 0)])  # numbered as the ring
    turn = _edge_chars(text)[(6, 8)][0]  # column 6 (the third cell's) to beam 8
    wrong = _labels_of_placement(cats, ss, straight, straight_parts)[_edge_chars(straight)[(6, 8)][0]]
    assert wrong != truth[turn]
    allowed, _ = string_mask(text, cats)
    prob = np.where(allowed, 0.01, 0.0)
    prob[np.arange(len(text)), truth] = 1.0
    prob[turn, wrong], prob[turn, truth[turn]] = 1.0, 0.5
    prob /= prob.sum(1, keepdims=True)
    assert narrow.faults(text, narrow.decode(text, prob)) > 0
    retried = CategoryDecoder(cats, None, *_geometry(cats, ss), DecoderParams(beam=1, retry_beam=64))
    assert retried.decode(text, prob).tolist() == truth.tolist()


def _geometry(cats, ss):
    """``frame_of`` and ``root_poses`` of :func:`category_decoder` for ``ss``."""
    d = category_decoder(cats, None, ss)
    return d.frame_of, d.root_poses


def test_a_ring_has_its_rotations_and_reflections_as_automorphisms():
    from procmod.strings.automorphisms import type_automorphisms

    path = parse("CBC").graph  # its two ends swap
    assert len(type_automorphisms(path)) == 2
    ring = parse("C1BCBCBCB1").graph  # four columns, four beams: turns by two places, mirrors
    auts = type_automorphisms(ring)
    assert len(auts) == 8 and auts[0] == {v: v for v in ring.nodes}
    for m in auts:
        assert all(ring.nodes[m[v]]["type"] == ring.nodes[v]["type"] for v in ring.nodes)
        assert {(min(m[a], m[b]), max(m[a], m[b])) for a, b in ring.edges} == \
            {(min(a, b), max(a, b)) for a, b in ring.edges}
    assert len(type_automorphisms(ring, limit=3)) == 3
    mixed = parse("C1BCBCBNB1").graph  # one column is another type: only the mirror through it
    assert len(type_automorphisms(mixed)) == 2


def test_shape_labellings_include_the_same_shape_with_its_parts_renamed(colonnade_fitted):
    """A colonnade ring's parts look alike to its graph: moving every part to the place of
    its image under an automorphism gives the same shape, whose categories are the
    labelling moved by that automorphism; every such labelling is among the shape's."""
    from procmod.strings.categories import shape_labelings
    from procmod.strings.automorphisms import type_automorphisms
    from procmod.strings.shapes import Shape

    ss, cats = colonnade_fitted
    shape = ss.shapes[0]  # a ring of 14 columns round a 5 x 4 court
    g = shape_graph(ss, shape)
    auts = type_automorphisms(g)
    assert len(auts) == 28  # the ring's 14 turns and 14 mirrors
    plain = shape_labelings(ss, shape, g, cats, automorphisms=1)
    every = shape_labelings(ss, shape, g, cats)
    keys = {tuple(sorted(lab.items())) for lab in every}
    assert len(keys) == len(every) > len(plain)
    for m in auts:
        renamed = Shape.of(shape.parts, [shape.transforms[m[v]] for v in range(len(shape))])
        assert shape_graph(ss, renamed).edges == g.edges  # the same shape, parts renamed
        assert tuple(sorted(cats.edge_categories(ss, renamed, g).items())) in keys
    # only the court's own symmetries (itself, its half turn, its two mirrors) are a turn or
    # mirror of the whole shape; the other 24 move its corners along the ring
    def moved(m):
        return {(a, b): plain[0][(min(m[a], m[b]), max(m[a], m[b]))] for a, b in plain[0]}
    assert sum(moved(m) in plain for m in auts) == 4
    assert all(moved(m) in every for m in auts)


@pytest.mark.parametrize("bad", [{"penalty": -1.0}, {"penalty": float("inf")}, {"penalty": float("nan")},
                                 {"beam": 0}, {"candidates": 0}])
def test_decoder_params_are_checked(bad):
    """The search stops building extensions by a bound that holds only for a finite penalty
    >= 0; such settings are refused with a message, not searched wrongly."""
    from procmod.core.errors import ProcmodError

    with pytest.raises(ProcmodError, match="must be"):
        DecoderParams(**bad)
