"""Neural guides for SMC (seeds 003/004): features, networks, traces, training, proposals.

A guide holds one small network per random-choice site of a model; ``smc(model, target,
guide=g)`` draws every choice from the guide's proposal and weights particles by
prior / proposal x likelihood.
"""

from ..core.lazy import lazy_getattr

# Imported on first use (torch is slow to import; ``procmod --help`` must not wait for it).
_LAZY = {**dict.fromkeys(("CONDITIONS", "FeatureExtractor", "FeatureSettings", "GuideError"), "features"),
         **dict.fromkeys(("Guide", "GuidedProposer", "RecordingProposer", "guide_paths", "new_guide_for",
                          "pretrained_guides", "site_key"), "guide")}


__getattr__ = lazy_getattr(__name__, _LAZY, globals())


__all__ = ["CONDITIONS", "FeatureExtractor", "FeatureSettings", "Guide", "GuideError", "GuidedProposer",
           "RecordingProposer", "guide_paths", "new_guide_for", "pretrained_guides", "site_key"]
