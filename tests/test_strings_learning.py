import json
import math
from pathlib import Path

import networkx as nx
import numpy as np
import pytest
import torch

from procmod.core.errors import InvalidArgumentError
from procmod.strings.codec import decode, encode_with_order, parse, strings_of
from procmod.strings.decoding import star_set
from procmod.strings.categories import EdgeCategories
from procmod.strings.tagger import (Tagger, TaggerConfig, TaggerModel, string_mask, string_structure, tagging_accuracy,
                                    tagging_examples, train_tagger)
from procmod.strings.latent import latent_path, naive_graph, path_statistics, search_graph
from procmod.strings.automaton import Constraint, _Prefix
from procmod.strings.contacts import shape_graph
from procmod.strings.grammar import Grammar
from procmod.strings.shapes import read_shapes
from procmod.strings.torch_utils import ModelFileError
from procmod.strings.vae import StringModel, VAEConfig, Vocab, train_vae

SETS = Path(__file__).resolve().parents[1] / "examples_sets" / "strings"
TINY = VAEConfig(embed=8, hidden=16, latent=4, epochs=2, batch=16, kl_warmup=1)


@pytest.fixture(scope="module")
def moonbase():
    ss = read_shapes(SETS / "moonbase.json")
    graphs = [shape_graph(ss, s) for s in ss.shapes]
    rng = np.random.default_rng(0)
    strings = [s for g in graphs for s in strings_of(g, 6, rng)]
    return ss, graphs, Grammar.from_graphs(graphs), strings


@pytest.fixture(scope="module")
def categories(moonbase):
    ss, graphs, _, _ = moonbase
    return EdgeCategories.fit(ss, ss.shapes, graphs)


def _weights(model):
    return {k: v.clone() for k, v in model.net.state_dict().items()}


def test_vae_training_resumes_bit_identically(tmp_path, moonbase):
    _, _, grammar, strings = moonbase
    straight = train_vae(strings, grammar, tmp_path / "a", TINY, seed=5)
    train_vae(strings, grammar, tmp_path / "b", TINY, seed=5, stop_after=1)  # "killed" after one epoch
    meta = json.loads((tmp_path / "b" / "vae.json").read_text())
    assert meta["train"]["epoch"] == 1
    resumed = train_vae(strings, grammar, tmp_path / "b", TINY, seed=5)
    a, b = _weights(straight), _weights(resumed)
    assert all(torch.equal(a[k], b[k]) for k in a)
    loaded = StringModel.load(tmp_path / "b")
    assert all(torch.equal(a[k], v) for k, v in loaded.net.state_dict().items())
    hist = meta["train"]["history"]
    assert hist[0]["beta"] == pytest.approx(TINY.kl_weight)  # warm-up of one epoch


def test_resumed_vae_takes_the_ring_rule_and_refuses_other_rules(tmp_path, moonbase):
    _, _, grammar, strings = moonbase
    assert grammar.ring_multiple == 4  # moon-base rings: 8, 12
    train_vae(strings, grammar, tmp_path / "m", TINY, seed=1)
    meta = json.loads((tmp_path / "m" / "vae.json").read_text())
    del meta["grammar"]["ring_length_multiple"]  # as saved before the rule existed
    (tmp_path / "m" / "vae.json").write_text(json.dumps(meta))
    assert StringModel.load(tmp_path / "m").grammar.ring_multiple == 1
    resumed = train_vae(strings, grammar, tmp_path / "m", TINY, seed=1)
    assert resumed.grammar == grammar and resumed.constraint.ring_multiple == 4
    other = Grammar({**grammar.rules, "Z": frozenset({""})}, grammar.ring_multiple)
    with pytest.raises(ModelFileError, match="other tiling rules"):
        train_vae(strings, other, tmp_path / "m", TINY, seed=1)


def test_resumed_vae_refuses_other_strings_and_adopts_old_checkpoints(tmp_path, moonbase):
    _, _, grammar, strings = moonbase
    train_vae(strings, grammar, tmp_path / "m", TINY, seed=1, stop_after=1)
    # same vocabulary and tiling rules, other strings (a collection grown again): refused
    with pytest.raises(ModelFileError, match="other strings"):
        train_vae(strings[1:], grammar, tmp_path / "m", TINY, seed=1)
    train_vae(strings, grammar, tmp_path / "m", TINY, seed=1)  # trained to the end
    meta = json.loads((tmp_path / "m" / "vae.json").read_text())
    assert meta["train"]["epoch"] == TINY.epochs
    del meta["train"]["data"]  # as saved before the fingerprint was kept: resumed, then checked
    (tmp_path / "m" / "vae.json").write_text(json.dumps(meta))
    train_vae(strings, grammar, tmp_path / "m", TINY, seed=1)
    assert json.loads((tmp_path / "m" / "vae.json").read_text())["train"]["data"]
    with pytest.raises(ModelFileError, match="other strings"):
        train_vae(strings[1:], grammar, tmp_path / "m", TINY, seed=1)


@pytest.fixture(scope="module")
def castle():
    ss = read_shapes(SETS / "castle.json")
    graphs = [shape_graph(ss, s) for s in ss.shapes]
    rng = np.random.default_rng(0)
    return Grammar.from_graphs(graphs), [s for g in graphs for s in strings_of(g, 6, rng)]


def test_constrained_decoding_only_ends_on_valid_strings(tmp_path, castle):
    # castle, not moon base: the tiny moon-base model dead-ends on nearly every point
    # (0-1 of 60 finish), which would leave nothing to check
    grammar, strings = castle
    model = train_vae(strings, grammar, tmp_path / "m", TINY, seed=1)
    rng = np.random.default_rng(0)
    z = rng.standard_normal((60, TINY.latent))
    out = model.decode(z, constrained=True, rng=rng, max_len=120)
    # the same model decoding freely ends every point on a string the grammar refuses, so
    # the validity below is the constraint's doing
    free = model.decode(z, constrained=False, rng=np.random.default_rng(0), max_len=120)
    assert any(s is not None and not model.is_valid(s) for s in free)
    # 4 to 14 of 60 points finish, with or without wrap-up (training seeds 1-3, decoding
    # seeds 0-2); none of 60 at the lowest of these rates, 1/15, has probability 1.6%
    finished = [s for s in out if s is not None]
    assert finished and all(model.is_valid(s) for s in finished)
    # same seed, same strings: the first points' stream again (z, then the decoding's draws)
    rng, again = np.random.default_rng(0), np.random.default_rng(0)
    first = model.decode(rng.standard_normal((15, TINY.latent)), constrained=True, rng=rng, max_len=120)
    assert model.decode(again.standard_normal((15, TINY.latent)), constrained=True, rng=again, max_len=120) == first
    # without wrap-up too, whatever ends is valid
    plain = [s for s in model.decode(z, constrained=True, rng=np.random.default_rng(0), max_len=120, wrap=False)
             if s is not None]
    assert plain and all(model.is_valid(s) for s in plain)
    assert model.wrap_nodes == round(0.8 * model.max_nodes / 1.25)


def test_constraint_masks_follow_syntax_and_rules(moonbase):
    _, _, grammar, strings = moonbase
    c = Constraint(Vocab(set("".join(strings)) | set("()123456789")), grammar)
    p = _Prefix()
    assert "(" not in c.allowed(p) and "" not in c.allowed(p)
    for ch in "AD":
        assert ch in c.allowed(p)
        c.advance(p, ch)
    # an antenna (A) touches only a dome (D): after "AD" the dome needs its module next
    allowed = c.allowed(p)
    assert "M" in allowed and "A" not in allowed and "" not in allowed and ")" not in allowed


@pytest.mark.parametrize("text, closes", [("A1AA2AAA(AAAA2)AA1", False), ("A1AAA2AA(AAAAA2)AA1", True),
                                          ("A1AAAAAA1", False), ("A1AAAAAAA1", True)])
def test_constraint_closes_rings_only_as_the_ring_rule_allows(text, closes):
    """With every ring a multiple of 4 long, a ring label closes only a ring of such a length
    that, with the rings closed before it, shares an even number of contacts (else the ring
    around both has the wrong length: 8 + 8 - 2 * 3 = 10)."""
    grammar = Grammar({"A": frozenset({"AA", "AAA"})}, ring_multiple=4)
    constraint = Constraint(Vocab(set("A()12")), grammar)
    p = _Prefix()
    for c in text[:-1]:
        assert c in constraint.allowed(p), (text, c)
        constraint.advance(p, c)
    assert ("1" in constraint.allowed(p)) == closes
    assert Grammar({"A": frozenset({"AA", "AAA"})}).is_valid(parse(text).graph)  # only the rule decides


def test_constraint_does_not_count_a_leaf_as_a_way_to_close_a_ring():
    """A column (C) with three beams can only take a floor tile (F), a leaf: that closes no
    ring, so with ring 1 open (and too short to close here) the decoder must not get there."""
    grammar = Grammar({"B": frozenset({"CC"}), "C": frozenset({"BBBF", "BBF", "BF"}), "F": frozenset({"C"})}, 4)
    constraint = Constraint(Vocab(set("BCF()12")), grammar)
    p = _Prefix()
    text = "FC1BC(BCF)(BC(F)BC(F)BC(BCF)F)"  # ends with no token allowed: a dead end
    refused = None
    for i, c in enumerate(text):
        allowed = constraint.allowed(p)
        assert allowed, f"dead end after {text[:i]!r}"
        if c not in allowed:
            refused = i
            break
        constraint.advance(p, c)
    assert refused is not None and refused < len(text)


def test_constraint_counts_open_ring_labels_as_neighbours(moonbase):
    _, _, grammar, strings = moonbase
    c = Constraint(Vocab(set("".join(strings)) | set("()123456789")), grammar)
    p = _Prefix()
    for ch in "C1MC":  # corridor C M corridor; the first corridor's ring label promises its 2nd module
        assert ch in c.allowed(p), ch
        c.advance(p, ch)
    assert "M" in c.allowed(p)
    # opening label 2 here would promise this corridor a second module besides its M, so no
    # letter could follow it: the look-ahead rejects it; and the rule check alone, after
    # "C1MC2", must not let an M bond to the corridor (M + M + the open label = 3 neighbours)
    assert "2" not in c.allowed(p)
    c.advance(p, "2")
    assert "M" not in c._allowed(p) and "(" not in c._allowed(p)


def test_constraint_rejects_branches_and_leaves_that_strand_an_open_ring(moonbase):
    _, _, grammar, strings = moonbase
    c = Constraint(Vocab(set("".join(strings)) | set("()123456789")), grammar)
    p = _Prefix()
    for ch in "M1CMCM(CMD)D":  # ring 1 is open on the first module; the dome can take only an antenna
        c.advance(p, ch)
    allowed = c.allowed(p)
    # "(A" or "A" would end the path at a leaf with ring 1 still open: a dead end
    assert "(" not in allowed and "A" not in allowed and "" not in allowed


def test_wrap_up_stops_opening_rings_and_branches(moonbase):
    _, _, grammar, strings = moonbase
    c = Constraint(Vocab(set("".join(strings)) | set("()123456789")), grammar)
    p = _Prefix()
    for ch in "M1CM":
        c.advance(p, ch)
    free = c.allowed(p)
    assert "(" in free and "2" in free and "C" in free
    wrapped = c.allowed(p, wrap_nodes=3)
    assert "(" not in wrapped and "2" not in wrapped and "C" in wrapped
    assert c.closes(p, "1") and not c.closes(p, "2") and c.closes(p, ")") and not c.closes(p, "C")


def test_string_structure_and_tree_states(moonbase, categories):
    st = string_structure("C1CC(N)CC1O")
    assert st[:, 0].tolist() == [0, 1, 1, 3, 4, 4, 4, 4, 8, 9, 9]
    assert st[1].tolist()[1:] == [1, 9] and st[9].tolist()[1:] == [1, 9]  # the ring edge: C0 - C8
    assert st[2].tolist()[1:] == [1, 3] and st[0].tolist()[1:] == [0, 0]
    _, _, _, strings = moonbase
    vocab = Vocab(set("".join(strings)) | set("()123456789"))
    torch.manual_seed(0)
    net = Tagger(len(vocab), len(categories), TaggerConfig(hidden=8, embed=8, layers=1))
    model = TaggerModel(net, vocab, categories)
    tok, _, _, struct = model._tensors(strings[:5])
    emb = net.embedding(tok)
    fast = net._tree_states(emb, struct)
    # the same states, computed character by character from the parent's state
    slow = torch.zeros((tok.shape[0], tok.shape[1] + 1, 8))
    rows = torch.arange(tok.shape[0])
    for i in range(tok.shape[1]):
        slow[:, i + 1] = net.tree_cell(emb[:, i], slow[rows, struct[:, i, 0]])
    assert torch.allclose(fast, slow[:, 1:], atol=1e-6)


def test_tagger_masks_are_minus_infinity_and_training_learns(tmp_path, moonbase, categories):
    ss, graphs, _, strings = moonbase
    cats = categories
    text = strings[0]
    mask, edges = string_mask(text, cats)
    assert mask[[i for i, e in enumerate(edges) if e is None]].sum(1).tolist() == \
        [1] * sum(e is None for e in edges)
    vocab = Vocab(set("".join(strings)) | set("()123456789"))
    net = Tagger(len(vocab), len(cats), TaggerConfig(hidden=8, embed=8, layers=1))
    model = TaggerModel(net, vocab, cats)
    tok, m, _, st = model._tensors([text])
    logits = net(tok, m, st)
    assert torch.isneginf(logits[~m]).all() and torch.isfinite(logits[m]).all()
    prob = model.predict([text])[0]
    assert np.all(prob[~mask] == 0)
    examples = tagging_examples(ss, ss.shapes, graphs, cats, 6, np.random.default_rng(0))
    assert all(len(t) == len(s) for s, t in examples)
    every = tagging_examples(ss, ss.shapes, graphs, cats, 6, np.random.default_rng(0), every_symmetry=True)
    # the same strings; the canonical target sequence comes first among the symmetric ones
    assert [s for s, _ in every] == [s for s, _ in examples]
    assert all(t[0] == c and all(len(x) == len(s) for x in t) for (s, t), (_, c) in zip(every, examples))
    assert any(len(t) > 1 for _, t in every)  # a turned copy of a moon base labels differently
    # accuracy takes the closest symmetric sequence: predicting any one of them is right
    untrained = TaggerModel(Tagger(len(vocab), len(cats), TaggerConfig(hidden=8, embed=8, layers=1)), vocab, cats)
    text, seqs = next((s, t) for s, t in every if len(t) > 1)
    pred = untrained.predict([text])[0].argmax(1)
    best = max(sum(int(pred[i] == q[i]) for i in range(len(q)) if q[i] > 0) for q in seqs)
    n = sum(1 for k in seqs[0] if k > 0)
    assert tagging_accuracy(untrained, [(text, seqs)], structured=False) == pytest.approx(best / n)
    examples = every
    first = train_tagger(examples, vocab, cats, tmp_path / "t", TaggerConfig(epochs=1, hidden=16, embed=8, layers=1))
    loss1 = json.loads((tmp_path / "t" / "tagger.json").read_text())["train"]["history"][-1]["loss"]
    train_tagger(examples, vocab, cats, tmp_path / "t", TaggerConfig(epochs=6, hidden=16, embed=8, layers=1))
    loss6 = json.loads((tmp_path / "t" / "tagger.json").read_text())["train"]["history"][-1]["loss"]
    assert loss6 < loss1
    # the stars of the training labellings are kept with the tagger, for structured decoding
    assert TaggerModel.load(tmp_path / "t").stars == star_set(examples)
    assert first is not None


def test_vote_maps_every_edge(moonbase, categories):
    ss, graphs, _, strings = moonbase
    cats = categories
    vocab = Vocab(set("".join(strings)) | set("()123456789"))
    model = TaggerModel(Tagger(len(vocab), len(cats), TaggerConfig(hidden=8, embed=8, layers=1)), vocab, cats)
    vote = model.vote(graphs[0], 4, np.random.default_rng(0), ss)
    assert set(vote) == {(min(e), max(e)) for e in graphs[0].edges}
    for (a, b), k in vote.items():
        name = cats.names[k]
        ta, tb = sorted((graphs[0].nodes[a]["type"], graphs[0].nodes[b]["type"]))
        assert name is not None and name[:2] == (ta, tb)
    # ranked: the voted category first, then the others (soft: by averaged probability;
    # majority vote: every category that got a vote, most votes first)
    for soft in (True, False):
        vote = model.vote(graphs[0], 4, np.random.default_rng(0), ss, soft=soft)
        ranked = model.vote(graphs[0], 4, np.random.default_rng(0), ss, ranked=True, soft=soft)
        assert {e: r[0] for e, r in ranked.items()} == vote
        assert all(len(set(r)) == len(r) and set(r) <= set(cats.allowed(*sorted(
            (graphs[0].nodes[e[0]]["type"], graphs[0].nodes[e[1]]["type"])))) for e, r in ranked.items())


def test_soft_vote_weighs_confident_strings(moonbase, categories):
    """One confident string against four that lean the other way: the majority vote follows
    the four, the soft vote (averaged probabilities) the confident one."""
    ss, graphs, _, strings = moonbase
    cats = categories
    vocab = Vocab(set("".join(strings)) | set("()123456789"))
    model = TaggerModel(Tagger(len(vocab), len(cats), TaggerConfig(hidden=8, embed=8, layers=1)), vocab, cats)

    def predict(texts):
        out = []
        for k, text in enumerate(texts):
            parsed = parse(text)
            types = [parsed.graph.nodes[v]["type"] for v in parsed.graph.nodes]
            prob = np.zeros((len(text), len(cats)))
            for i, e in enumerate(parsed.char_edges):
                allowed = cats.allowed(*sorted((types[e[0]], types[e[1]]))) if e is not None else []
                if len(allowed) < 2:
                    prob[i, allowed[0] if allowed else 0] = 1.0
                    continue
                first, second = (0.95, 0.05) if k == 0 else (0.45, 0.55)
                prob[i, allowed[0]], prob[i, allowed[1]] = first, second
            out.append(prob / prob.sum(1, keepdims=True))
        return out

    model.predict = predict
    g = graphs[0]
    pair = {e: cats.allowed(*sorted((g.nodes[e[0]]["type"], g.nodes[e[1]]["type"]))) for e in
            ((min(e), max(e)) for e in g.edges)}
    contested = [e for e, allowed in pair.items() if len(allowed) >= 2]
    assert contested
    hard = model.vote(g, 5, np.random.default_rng(0), None, structured=False, soft=False)
    soft = model.vote(g, 5, np.random.default_rng(0), None, structured=False, soft=True)
    assert all(hard[e] == pair[e][1] for e in contested)
    assert all(soft[e] == pair[e][0] for e in contested)


def _script_tagger(model, monkeypatch, labelling_of):
    """Make ``model.predict`` say, for the k-th string a vote draws, the labelling
    ``labelling_of(k)`` (``{graph edge (min, max): category}``) with 0.9 confidence: the
    strings' node orders are recorded as the vote encodes them."""
    import procmod.strings.tagger as tagger_module

    orders = {}
    size = len(model.categories)

    def recording_encode(graph, root=None, rng=None):
        text, order = encode_with_order(graph, root, rng)
        orders[text] = order
        return text, order

    def predict(texts):
        out = []
        for k, text in enumerate(texts):
            said, order = labelling_of(k), orders[text]
            prob = np.zeros((len(text), size))
            for i, e in enumerate(parse(text).char_edges):
                if e is None:
                    prob[i, 0] = 1.0
                    continue
                prob[i, said[(min(order[e[0]], order[e[1]]), max(order[e[0]], order[e[1]]))]] = 1.0
            out.append(0.9 * prob + 0.1 / size)
        return out

    monkeypatch.setattr(tagger_module, "encode_with_order", recording_encode)
    model.predict = predict


def test_soft_vote_turns_each_string_back_before_averaging(moonbase, categories, monkeypatch):
    """Strings that see the shape turned by a quarter turn (their labels permuted) are turned
    back before their probabilities are added: four turned strings and one upright one give
    the upright labelling, with and without structured decoding."""
    ss, graphs, _, strings = moonbase
    cats = categories
    g = graphs[0]
    truth = cats.edge_categories(ss, ss.shapes[0], g)
    turn = cats.symmetry_permutations(ss)[1]  # a quarter turn about the vertical
    assert all(turn.get(k) is not None for k in truth.values())
    assert any(turn[k] != k for k in truth.values())
    assert any(turn.get(turn[k]) != k for k in truth.values())  # not its own inverse
    vocab = Vocab(set("".join(strings)) | set("()123456789"))
    model = TaggerModel(Tagger(len(vocab), len(cats), TaggerConfig(hidden=8, embed=8, layers=1)), vocab, cats)
    turned = {e: turn[c] for e, c in truth.items()}
    _script_tagger(model, monkeypatch, lambda k: truth if k == 0 else turned)
    for structured in (False, True):
        vote = model.vote(g, 5, np.random.default_rng(0), ss, structured=structured)
        assert vote == truth


def test_vote_moves_each_string_by_the_automorphism_that_agrees(monkeypatch):
    """A colonnade ring's strings cannot say which columns are its corners: four strings
    labelled with the corners one place along the ring (the same court, parts renamed) and
    one with the true corners give the true labelling once each string is moved back by
    the ring's automorphism; left unmoved (``automorphisms=1``) they mix two courts."""
    from procmod.strings.categories import shape_labelings
    from procmod.strings.automorphisms import type_automorphisms

    ss = read_shapes(SETS / "colonnade.json")
    graphs = [shape_graph(ss, s) for s in ss.shapes]
    cats = EdgeCategories.fit(ss, ss.shapes, graphs)
    g = graphs[0]
    truth = cats.edge_categories(ss, ss.shapes[0], g)
    plain = shape_labelings(ss, ss.shapes[0], g, cats, automorphisms=1)
    renamed = None
    for m in type_automorphisms(g):
        renamed = {(a, b): truth[(min(m[a], m[b]), max(m[a], m[b]))] for a, b in truth}
        if renamed not in plain:  # corners moved: not a turn or mirror of the court
            break
    strings = [s for g_ in graphs for s in strings_of(g_, 4, np.random.default_rng(0))]
    vocab = Vocab(set("".join(strings)) | set("()123456789%0"))
    model = TaggerModel(Tagger(len(vocab), len(cats), TaggerConfig(hidden=8, embed=8, layers=1)), vocab, cats)
    _script_tagger(model, monkeypatch, lambda k: truth if k == 0 else renamed)
    for structured in (False, True):
        assert model.vote(g, 5, np.random.default_rng(0), ss, structured=structured) == truth
    unmoved = model.vote(g, 5, np.random.default_rng(0), ss, structured=False, automorphisms=1)
    assert unmoved != truth and unmoved not in plain


def test_tagger_reads_ring_labels_past_nine(moonbase, categories):
    """A string with a ring label from %10 on is read by a tagger whose training strings
    never needed one (the ring pairs come from the structure input)."""
    ss, graphs, _, strings = moonbase
    vocab = Vocab(set("".join(strings)) | set("()123456789"))
    assert "%" not in vocab.chars and "0" not in vocab.chars
    text = next(s for s in strings if "1" in s)
    wide = text.replace("1", "%10")
    assert set(parse(wide).graph.edges) == set(parse(text).graph.edges)  # the same graph
    model = TaggerModel(Tagger(len(vocab), len(categories), TaggerConfig(hidden=8, embed=8, layers=1)), vocab,
                        categories)
    wide_prob = model.predict([wide])[0]
    assert wide_prob.shape[0] == len(wide) and np.allclose(wide_prob.sum(1), 1)
    with pytest.raises(InvalidArgumentError, match="not in the model's vocabulary"):
        vocab.encode(wide)


def test_search_graphs_and_paths(rng):
    strings = ["AB", "ABB", "BA", "ABBB", "AAB", "BBA"]
    z = rng.normal(size=(len(strings), 3))
    ours = search_graph(z, strings, k=2)
    assert ours.has_edge(0, 2) and ours.edges[0, 2]["weight"] == 0  # AB and BA are one graph
    stats = path_statistics(ours, 20, rng)
    assert stats["components"] == 1 and stats["avg_weight"] <= stats["max_weight"]
    naive = naive_graph(strings, k=1)
    assert naive.number_of_nodes() == len(strings)
    path = latent_path(z[0], z[1], z, 5)
    assert len(path) == 5 and np.allclose(path[0], z[0]) and np.allclose(path[-1], z[1])


def test_graph_index_knows_graphs_up_to_isomorphism():
    from procmod.strings.codec import decode
    from procmod.strings.latent import GraphIndex
    index = GraphIndex([decode("C1CC(N)CC1O")])
    assert decode("OC1CCC(N)CC1") not in index  # a 6-ring, not the 5-ring
    assert decode("NC1CCC(O)C1") in index  # the same graph written from another root
    assert decode("C1CC(O)CC1N") in index


def test_tagger_learning_rate_decay_resumes_and_loads(tmp_path, moonbase, categories):
    ss, graphs, _, strings = moonbase
    vocab = Vocab(set("".join(strings)) | set("()123456789"))
    examples = tagging_examples(ss, ss.shapes, graphs, categories, 2, np.random.default_rng(0), every_symmetry=True)
    cfg = TaggerConfig(epochs=3, hidden=8, embed=8, lr_final=0.1)
    straight = train_tagger(examples, vocab, categories, tmp_path / "a", cfg)
    train_tagger(examples, vocab, categories, tmp_path / "b", TaggerConfig(**{**cfg.__dict__, "epochs": 1}))
    # another configuration in the folder (epochs aside) is refused, naming train_tagger's argument
    with pytest.raises(ModelFileError, match=r"another configuration; use a new folder$"):
        train_tagger(examples, vocab, categories, tmp_path / "b", TaggerConfig(**{**cfg.__dict__, "lr_final": 0.5}))
    with pytest.raises(ModelFileError, match=r"other strings.*other seed / tagger_strings_per_shape / held_out "
                                             r"than it was trained with; repeat those, or use a new folder$"):
        train_tagger(examples[1:], vocab, categories, tmp_path / "b", cfg)
    resumed = train_tagger(examples, vocab, categories, tmp_path / "b", cfg)
    # dropout's masks too: a resumed training had trained another tagger (the global
    # generator was seeded once a start, not once an epoch)
    a, b = _weights(straight), _weights(resumed)
    assert cfg.dropout > 0 and all(torch.equal(a[k], b[k]) for k in a)
    meta = json.loads((tmp_path / "a" / "tagger.json").read_text())
    del meta["train"]["data"]  # a finished tagger saved before the fingerprint was kept
    (tmp_path / "a" / "tagger.json").write_text(json.dumps(meta))
    train_tagger(examples, vocab, categories, tmp_path / "a", cfg)
    with pytest.raises(ModelFileError, match="other strings"):
        train_tagger(examples[1:], vocab, categories, tmp_path / "a", cfg)
    assert straight is not None
    # the schedule is a function of the epoch: a resumed run ends at the same rate (loaded
    # with weights_only=True, so the rate must be stored as a plain float)
    for folder in ("a", "b"):
        _, state, opt = TaggerModel.load(tmp_path / folder, with_optimizer=True)
        assert opt["param_groups"][0]["lr"] == pytest.approx(cfg.lr * 0.1)
        assert state["epoch"] == 3


@pytest.mark.skipif(not torch.cuda.is_available(), reason="needs a CUDA device")
def test_training_on_cuda_saves_cpu_checkpoints_that_resume_anywhere(tmp_path, moonbase, categories):
    """Tagger and VAE trained on the GPU: the checkpoints hold CPU tensors, the models come
    back on the CPU, predict what a reloaded copy predicts, and resume on the CPU."""
    ss, graphs, grammar, strings = moonbase
    vocab = Vocab(set("".join(strings)) | set("()123456789"))
    examples = tagging_examples(ss, ss.shapes, graphs, categories, 2, np.random.default_rng(0), every_symmetry=True)
    cfg = TaggerConfig(epochs=2, hidden=8, embed=8)
    tagger = train_tagger(examples, vocab, categories, tmp_path / "t", cfg, device="cuda")
    assert all(p.device.type == "cpu" for p in tagger.net.parameters())
    payload = torch.load(tmp_path / "t" / "tagger.pt", weights_only=True)
    assert all(v.device.type == "cpu" for v in payload["model"].values())
    texts = [s for s, _ in examples[:5]]
    again = TaggerModel.load(tmp_path / "t")
    assert all(np.allclose(a, b, atol=1e-5) for a, b in zip(tagger.predict(texts), again.predict(texts)))
    train_tagger(examples, vocab, categories, tmp_path / "t", TaggerConfig(**{**cfg.__dict__, "epochs": 3}))
    assert json.loads((tmp_path / "t" / "tagger.json").read_text())["train"]["epoch"] == 3
    vae = train_vae(strings, grammar, tmp_path / "v", TINY, seed=2, device="cuda")
    assert all(p.device.type == "cpu" for p in vae.net.parameters())
    loaded = StringModel.load(tmp_path / "v")
    assert all(torch.equal(a, b) for a, b in zip(vae.net.state_dict().values(), loaded.net.state_dict().values()))
    train_vae(strings, grammar, tmp_path / "v", VAEConfig(**{**TINY.__dict__, "epochs": 3}), seed=2)
    assert json.loads((tmp_path / "v" / "vae.json").read_text())["train"]["epoch"] == 3


def test_graph_rounds_pass_messages_along_graph_edges(moonbase, categories):
    """One round of message passing: a letter's state depends on its graph neighbours'
    string states (tree and ring edges, however far apart in the string) and on nothing
    else; the result equals a node-by-node computation of the mean-message GRU update."""
    _, _, _, strings = moonbase
    vocab = Vocab(set("".join(strings)) | set("()123456789") | set("CNO"))
    torch.manual_seed(0)
    net = Tagger(len(vocab), len(categories), TaggerConfig(hidden=4, embed=4, graph_rounds=1))
    text = "C1CC(N)CC1O"  # letters at 0, 2, 3, 5, 7, 8, 10; ring edge 0-8
    struct = torch.from_numpy(string_structure(text))[None]
    h = torch.randn((1, len(text), 8), requires_grad=True)
    g = net._graph_states(h, struct)
    neighbours = {0: [2, 8], 2: [0, 3], 3: [2, 5, 7], 5: [3], 7: [3, 8], 8: [7, 0, 10], 10: [8]}
    for v, nb in neighbours.items():
        msg = net.message(h[0, nb]).mean(0)
        assert torch.allclose(g[0, v], net.graph_cell(msg[None], h[0, v][None])[0], atol=1e-6)
    grad = torch.autograd.grad(g[0, 0].sum(), h)[0][0].abs().sum(1)
    assert grad[8] > 0 and grad[2] > 0  # the ring partner and the tree child
    assert grad[3] == 0 and grad[5] == 0 and grad[10] == 0  # two or more steps away
    assert torch.equal(g[0, 1], h[0, 1])  # non-letters keep their string state
    with pytest.raises(InvalidArgumentError):
        Tagger(len(vocab), len(categories), TaggerConfig(tree=False, graph_rounds=1))


def test_decoding_has_room_for_strings_as_long_as_the_training_ones(tmp_path):
    """A fixed 320-character cap made most decodings of a 400-part shape's own encodings
    come back invalid (None), with no word of why."""
    g = nx.path_graph(300)
    nx.set_node_attributes(g, {v: "AB"[v % 2] for v in g}, "type")
    strings = strings_of(g, 3, np.random.default_rng(0))
    longest = max(map(len, strings))  # 300 letters, and a branch's brackets
    assert longest >= 300
    config = VAEConfig(embed=8, hidden=16, latent=4, epochs=1, batch=16, kl_warmup=1)
    model = train_vae(strings, Grammar.from_graphs([g]), tmp_path / "m", config, seed=0)
    assert model.net.config.max_len == math.ceil(1.5 * longest) > 320
    assert StringModel.load(tmp_path / "m").net.config.max_len == model.net.config.max_len
    train_vae(strings, Grammar.from_graphs([g]), tmp_path / "m", config, seed=0)  # resumes: the same config
    # short strings keep the default
    short = train_vae(["AB", "BA"], Grammar.from_graphs([decode("AB")]), tmp_path / "s", config, seed=0)
    assert short.net.config.max_len == 320
