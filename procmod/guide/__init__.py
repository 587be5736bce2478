"""Neural guides for SMC (seeds 003/004): features, networks, traces, training, proposals."""
