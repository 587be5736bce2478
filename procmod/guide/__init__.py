"""Neural guides for SMC (seeds 003/004): features, networks, traces, training, proposals.

A guide holds one small network per random-choice site of a model; ``smc(model, target,
guide=g)`` draws every choice from the guide's proposal and weights particles by
prior / proposal x likelihood.
"""

import importlib

# Imported on first use (torch is slow to import; ``procmod --help`` must not wait for it).
_LAZY = {**dict.fromkeys(("CONDITIONS", "FeatureExtractor", "FeatureSettings", "GuideError"), "features"),
         **dict.fromkeys(("Guide", "GuidedProposer", "RecordingProposer", "guide_paths", "new_guide_for",
                          "pretrained_guides", "site_key"), "guide")}


def __getattr__(name):
    module = _LAZY.get(name)
    if module is None:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    value = getattr(importlib.import_module(f".{module}", __name__), name)
    globals()[name] = value  # later lookups skip this hook
    return value


__all__ = ["CONDITIONS", "FeatureExtractor", "FeatureSettings", "Guide", "GuideError", "GuidedProposer",
           "RecordingProposer", "guide_paths", "new_guide_for", "pretrained_guides", "site_key"]
