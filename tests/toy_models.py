"""Small hand-written models whose log-priors and distributions are known in closed form."""

import math

from procmod.core import Bernoulli, Categorical, Model, Normal, Output, Target, Uniform
from procmod.geometry import Canvas, Segment

VIEWPORT = (-10.0, 10.0, -10.0, 10.0)


def canvas(params):
    return Canvas(VIEWPORT, 20, 20)


def toy_root(ctx, x):
    """x0 ~ Normal(x, 1); kind ~ Categorical(.2,.3,.5); maybe 'left' (0.7) and always 'right'."""
    x0 = ctx.sample("x0", Normal(x, 1.0))
    kind = ctx.sample("kind", Categorical([0.2, 0.3, 0.5], labels=("a", "b", "c")))
    ctx.emit(Segment(x0, 0.0, x0, 1.0, 0.5))
    ctx.maybe("left", 0.7, toy_leaf, x0 - 1.0, 0)
    ctx.spawn("right", toy_leaf, x0 + 1.0, 0 if kind == "a" else 1)


def toy_leaf(ctx, x, depth):
    """u ~ Uniform(-1, 1); a leaf at depth 0 may spawn one more (p = 0.4)."""
    u = ctx.sample("u", Uniform(-1.0, 1.0))
    ctx.emit(Segment(x, u, x, u + 1.0, 0.3))
    if depth == 0:
        ctx.maybe("more", 0.4, toy_leaf, x + u, 1)


TOY = Model("toy", "toy model for tests", toy_root, lambda p: (p["x"],), canvas,
            params={"x": 0.0}, rules=(toy_root, toy_leaf))


def toy_log_prior(derivation):
    """The toy model's log-prior computed by hand from the choice values."""
    cm = derivation.choice_map()
    x = derivation.model.params["x"]
    lp = -0.5 * (cm[((), "x0")] - x) ** 2 - 0.5 * math.log(2 * math.pi)
    lp += math.log({"a": 0.2, "b": 0.3, "c": 0.5}[cm[((), "kind")]])
    lp += math.log(0.7 if cm[((), "left")] else 0.3)
    for (address, name), value in cm.items():
        if name == "u":
            lp += math.log(0.5)
        elif name == "more":
            lp += math.log(0.4 if value else 0.6)
    return lp


def dup_root(ctx):
    ctx.sample("a", Normal(0, 1))
    ctx.sample("a", Normal(0, 1))


DUPLICATE = Model("dup", "reuses a choice name", dup_root, lambda p: (), canvas)


def tree_root(ctx, depth):
    """A stop-free branching model: each call draws v ~ Normal(0,1), emits, and maybe spawns two children."""
    v = ctx.sample("v", Normal(0.0, 1.0))
    ctx.emit(Segment(v, float(depth), v, depth + 0.5, 0.2))
    if depth < 3:
        ctx.maybe("a", 0.6, tree_root, depth + 1)
        ctx.maybe("b", 0.4, tree_root, depth + 1)


TREE = Model("tree2d", "stop-free branching toy", tree_root, lambda p: (0,), canvas)


def stopper_root(ctx):
    """Spawns three calls; the second stops the whole derivation with probability 1/2."""
    for site in ("one", "two", "three"):
        ctx.spawn(site, stopper_leaf, site)


def stopper_leaf(ctx, name):
    ctx.emit(Segment(0.0, 0.0, 1.0, 1.0, 0.2))
    if name == "two" and ctx.sample("halt", Bernoulli(0.5)):
        ctx.stop()


STOPPER = Model("stopper", "global stop toy", stopper_root, lambda p: (), canvas)


# ---------------------------------------------------------------------------------------
# Models with exact posteriors, for the engines' correctness tests. Their output is a
# running sum of emitted numbers; the target is a Gaussian observation of that sum.


class Value(float):
    """An emitted number."""


class SumOutput(Output):
    """A running sum: neither a 2D canvas nor 3D parts; the Output defaults otherwise."""

    dimension = 0

    def __init__(self):
        self.total = 0.0

    def add(self, value):
        self.total += float(value)

    def copy(self):
        other = SumOutput()
        other.total = self.total
        return other


class SumTarget(Target):
    """log N(obs; sum, s^2), normalised, so SMC's Z estimate is a real density value.
    Subclasses Target for its default capabilities (as a user's target would)."""

    name = "sum"

    def __init__(self, obs, s):
        self.obs, self.s = obs, s

    def configure(self, model):
        return model

    def new_output(self, model):
        return SumOutput()

    def log_likelihood(self, output):
        d = output.total - self.obs
        return -0.5 * d * d / self.s ** 2 - 0.5 * math.log(2 * math.pi * self.s ** 2)

    def score(self, output):
        return -abs(output.total - self.obs)


def mix_root(ctx):
    k = ctx.sample("k", Categorical([0.3, 0.5, 0.2]))
    x = ctx.sample("x", Normal(0.0, 1.0))
    ctx.emit(Value(k + x))
    ctx.maybe("child", 0.5, mix_child)


def mix_child(ctx):
    ctx.emit(Value(ctx.sample("y", Normal(0.0, 1.0))))


MIX = Model("mix", "discrete + continuous + maybe toy", mix_root, lambda p: (), lambda p: SumOutput(),
            rules=(mix_root, mix_child))


def _normal_pdf(x, var):
    return math.exp(-0.5 * x * x / var) / math.sqrt(2 * math.pi * var)


# The likelihood sd of the marginal-likelihood (Z) checks on MIX. SMC's Z estimate is
# unbiased under any likelihood, but under one narrower than the draws' spread (sd 1 for
# the prior, 1.2-1.5 for test_guide's poor guide) it has infinite variance: a particle
# resampled from a poor fit carries L(new) / L(old), unbounded, to the next emit. Under sd
# 0.5 one run in a few thousand estimated Z at 200x its value, and 3 windows of 400 seeds in
# 10 had a standard error over 0.1 Z: such a check passes or fails by its seeds (a change of
# random streams found it). Under sd 2 the variance is finite: 20 windows of 400 seeds all
# had a standard error under 0.07 Z.
Z_CHECK_S = 2.0


def mix_exact(obs, s):
    """Exact marginal likelihood Z and posterior P(k, child) of MIX under SumTarget(obs, s)."""
    joint = {}
    for k, pk in enumerate([0.3, 0.5, 0.2]):
        for c in (False, True):
            joint[(k, c)] = pk * 0.5 * _normal_pdf(obs - k, 1 + c + s * s)
    z = sum(joint.values())
    return z, {key: v / z for key, v in joint.items()}



def order_root(ctx):
    """MIX split over two sibling calls: ``a`` draws k (and maybe MIX's child), ``b`` draws
    x; each emits what it drew. The same prior over the same sum as MIX (so ``mix_exact``
    gives Z and P(k, child)), but two futures are pending after the root, and the order in
    which SOSMC expands them changes the intermediate weights (k is scored first, or x)."""
    ctx.spawn("a", order_a)
    ctx.spawn("b", order_b)


def order_a(ctx):
    ctx.emit(Value(ctx.sample("k", Categorical([0.3, 0.5, 0.2]))))
    ctx.maybe("child", 0.5, mix_child)


def order_b(ctx):
    ctx.emit(Value(ctx.sample("x", Normal(0.0, 1.0))))


ORDER = Model("order", "MIX as sibling futures", order_root, lambda p: (), lambda p: SumOutput(),
              rules=(order_root, order_a, order_b, mix_child))

def count_root(ctx, depth):
    ctx.emit(Value(ctx.sample("v", Normal(0.0, 1.0))))
    if depth < 4:
        ctx.maybe("next", 0.6, count_root, depth + 1)


COUNT = Model("count", "trans-dimensional toy: 1-5 calls", count_root, lambda p: (0,),
              lambda p: SumOutput(), rules=(count_root,))


def _count_joint(obs, s):
    prior = {n: 0.6 ** (n - 1) * (0.4 if n < 5 else 1.0) for n in range(1, 6)}
    return {n: p * _normal_pdf(obs, n + s * s) for n, p in prior.items()}


def count_exact(obs, s):
    """Exact posterior over the number of calls of COUNT under SumTarget(obs, s)."""
    joint = _count_joint(obs, s)
    z = sum(joint.values())
    return {n: v / z for n, v in joint.items()}


def count_evidence(obs, s):
    """The marginal likelihood Z of COUNT under SumTarget(obs, s)."""
    return sum(_count_joint(obs, s).values())


# ---------------------------------------------------------------------------------------
# Models whose states differ in which MCMC moves they offer: some states have no `maybe`
# site, some no continuous choice. An MCMC whose acceptance ratio ignores how likely each
# move type is in the old and in the new state samples them with the wrong frequencies.


class FlatTarget(SumTarget):
    """A constant likelihood: the posterior is the prior."""

    name = "flat"

    def __init__(self):
        super().__init__(0.0, 1.0)

    def log_likelihood(self, output):
        return 0.0


def gate_root(ctx):
    """coin ~ Bernoulli(0.5); only a True coin opens a maybe site (p = 0.5) for a leaf."""
    if ctx.sample("coin", Bernoulli(0.5)):
        ctx.maybe("leaf", 0.5, gate_leaf)


def gate_leaf(ctx):
    ctx.emit(Value(1.0))


GATE = Model("gate", "a coin that gates the only maybe site", gate_root, lambda p: (),
             lambda p: SumOutput(), rules=(gate_root, gate_leaf))


def gate_exact(target):
    """Exact posterior over (coin, leaf) of GATE; leaf is None where there is no site."""
    like = {False: math.exp(target.log_likelihood(_total(0.0))),
            True: math.exp(target.log_likelihood(_total(1.0)))}
    joint = {(False, None): 0.5 * like[False], (True, False): 0.25 * like[False],
             (True, True): 0.25 * like[True]}
    z = sum(joint.values())
    return {key: v / z for key, v in joint.items()}


def _total(value):
    out = SumOutput()
    out.add(value)
    return out


SWITCH_K = (0.3, 0.4, 0.3)


def switch_root(ctx):
    """k ~ Categorical(SWITCH_K) picks what the state offers MCMC: k = 0 nothing to move but
    k; k = 1 one continuous choice x ~ Normal(0, 1), no maybe site; k = 2 a maybe site
    (p = 0.5) for MIX's child (one continuous choice y ~ Normal(0, 1)). Emits k, then x or y."""
    k = ctx.sample("k", Categorical(list(SWITCH_K)))
    ctx.emit(Value(k))
    if k == 1:
        ctx.emit(Value(ctx.sample("x", Normal(0.0, 1.0))))
    elif k == 2:
        ctx.maybe("child", 0.5, mix_child)


SWITCH = Model("switch", "states with and without maybe sites and continuous choices", switch_root,
               lambda p: (), lambda p: SumOutput(), rules=(switch_root, mix_child))


def switch_key(derivation):
    """(k, child) of a SWITCH derivation; child is None where there is no maybe site."""
    cm = derivation.choice_map()
    return cm[((), "k")], cm.get(((), "child"))


def switch_exact(obs, s):
    """Exact posterior over (k, child) of SWITCH under SumTarget(obs, s)."""
    p0, p1, p2 = SWITCH_K
    joint = {(0, None): p0 * _normal_pdf(obs, s * s),
             (1, None): p1 * _normal_pdf(obs - 1, 1 + s * s),
             (2, False): p2 * 0.5 * _normal_pdf(obs - 2, s * s),
             (2, True): p2 * 0.5 * _normal_pdf(obs - 2, 1 + s * s)}
    z = sum(joint.values())
    return {key: v / z for key, v in joint.items()}


FAN_N = (0.2, 0.2, 0.2, 0.2, 0.2)


def fan_root(ctx):
    """n ~ Categorical(FAN_N) plain spawns of a leaf with b ~ Bernoulli(0.5) that emits b:
    no maybe site and no continuous choice, so every MCMC move regenerates a subtree, and
    the states differ in their number of calls, n + 1."""
    n = ctx.sample("n", Categorical(list(FAN_N)))
    for i in range(n):
        ctx.spawn(f"c{i}", fan_leaf)


def fan_leaf(ctx):
    ctx.emit(Value(float(ctx.sample("b", Bernoulli(0.5)))))


FAN = Model("fan", "a random number of plain spawns", fan_root, lambda p: (), lambda p: SumOutput(),
            rules=(fan_root, fan_leaf))

