"""Neural guides for SMC (seeds 003/004): features, networks, traces, training, proposals.

A guide holds one small network per random-choice site of a model; ``smc(model, target,
guide=g)`` draws every choice from the guide's proposal and weights particles by
prior / proposal x likelihood.
"""

from .features import CONDITIONS, FeatureExtractor, FeatureSettings, GuideError
from .guide import (Guide, GuidedProposer, RecordingProposer, guide_paths, new_guide_for, pretrained_guides,
                    site_key)

__all__ = ["CONDITIONS", "FeatureExtractor", "FeatureSettings", "Guide", "GuideError", "GuidedProposer",
           "RecordingProposer", "guide_paths", "new_guide_for", "pretrained_guides", "site_key"]
