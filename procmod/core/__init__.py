"""procmod's runtime: models, rules, derivations, choice maps, distributions, and the
contracts (:mod:`.protocols`) outputs, targets and proposers fulfil.

This package imports nothing else of procmod.
"""

from .choicemap import ChoiceMap, format_address, is_within
from .distributions import (Bernoulli, Categorical, Distribution, GaussianMixture, Normal,
                            TruncatedNormal, Uniform)
from .errors import (DerivationFormatError, DistributionError, InvalidArgumentError, ModelError, ProcmodError,
                     UnknownModelError)
from .model import Model
from .protocols import (MaskedTarget, Output, OverlayTarget, PartCachingOutput, Proposer, RemovableOutput,
                        Target, check_declared)
from .runtime import (Choice, ChoicePolicy, Context, Derivation, Future, GuidedPolicy, Node, ReplayPolicy,
                      ReplayResult, SpawnRecord,
                      finish, follow_order, program_order, random_order, regenerate, replay,
                      run_forward, same_args, set_maybe, start, step)
from .serialize import (derivation_from_dict, derivation_to_dict, load_derivation,
                        save_derivation, write_text_atomic)

__all__ = [name for name in dir() if not name.startswith("_")]
