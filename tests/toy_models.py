"""Small hand-written models whose log-priors and distributions are known in closed form."""

import math

from procmod.core import Bernoulli, Categorical, Model, Normal, Uniform
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


class SumOutput:
    def __init__(self):
        self.total = 0.0

    def add(self, value):
        self.total += float(value)

    def copy(self):
        other = SumOutput()
        other.total = self.total
        return other


class SumTarget:
    """log N(obs; sum, s^2), normalised, so SMC's Z estimate is a real density value."""

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


def mix_exact(obs, s):
    """Exact marginal likelihood Z and posterior P(k, child) of MIX under SumTarget(obs, s)."""
    joint = {}
    for k, pk in enumerate([0.3, 0.5, 0.2]):
        for c in (False, True):
            joint[(k, c)] = pk * 0.5 * _normal_pdf(obs - k, 1 + c + s * s)
    z = sum(joint.values())
    return z, {key: v / z for key, v in joint.items()}


def count_root(ctx, depth):
    ctx.emit(Value(ctx.sample("v", Normal(0.0, 1.0))))
    if depth < 4:
        ctx.maybe("next", 0.6, count_root, depth + 1)


COUNT = Model("count", "trans-dimensional toy: 1-5 calls", count_root, lambda p: (0,),
              lambda p: SumOutput(), rules=(count_root,))


def count_exact(obs, s):
    """Exact posterior over the number of calls of COUNT under SumTarget(obs, s)."""
    prior = {n: 0.6 ** (n - 1) * (0.4 if n < 5 else 1.0) for n in range(1, 6)}
    joint = {n: p * _normal_pdf(obs, n + s * s) for n, p in prior.items()}
    z = sum(joint.values())
    return {n: v / z for n, v in joint.items()}
