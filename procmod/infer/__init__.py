"""Engines that control a model toward a target, all on one contract (see ``common``)."""

from ..parallel import InlineExecutor
from .common import Budget, HistoryRow, Result, Scored, Tracker, evaluate, evaluate_all, parse_budget
from .forward import forward
from .ga import ga
from .mcmc import mcmc, temperature_ladder
from .smc import effective_sample_size, resample, smc, sosmc

ENGINES = {"forward": forward, "smc": smc, "sosmc": sosmc, "mcmc": mcmc, "ga": ga}

__all__ = [name for name in dir() if not name.startswith("_")]
