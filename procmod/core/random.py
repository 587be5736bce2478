"""A numpy Generator whose scalar draws come from blocks: for engines' hot loops.

``numpy.random.Generator.random()`` costs about a microsecond per call, most of it call
overhead; SMC makes a few such draws per particle-step, so a tenth of its budget. A
:class:`BlockGenerator` draws ``block`` uniforms (or standard normals) at a time and hands
them out one by one. It is deterministic given the generator's seed, like the generator
itself, but its stream differs from the generator's own scalar calls (blocks of each kind
are drawn when first needed). Everything else (arrays, ``integers``, ``choice``, ...) is
passed to the wrapped generator.
"""

from __future__ import annotations

import numpy as np


class BlockGenerator:
    """``generator`` with block-buffered scalar ``random()`` and ``standard_normal()``."""

    __slots__ = ("generator", "block", "_uniforms", "_normals")

    def __init__(self, generator: np.random.Generator, block: int = 4096):
        self.generator = generator
        self.block = int(block)
        self._uniforms = []
        self._normals = []

    def random(self, size=None, *args, **kwargs):
        """A uniform in [0, 1) (from the block), or ``generator.random(size, ...)``."""
        if size is not None or args or kwargs:
            return self.generator.random(size, *args, **kwargs)
        u = self._uniforms
        if not u:
            u.extend(self.generator.random(self.block).tolist())
        return u.pop()

    def standard_normal(self, size=None, *args, **kwargs):
        """A standard normal (from the block), or ``generator.standard_normal(size, ...)``."""
        if size is not None or args or kwargs:
            return self.generator.standard_normal(size, *args, **kwargs)
        z = self._normals
        if not z:
            z.extend(self.generator.standard_normal(self.block).tolist())
        return z.pop()

    def __getattr__(self, name):
        return getattr(self.generator, name)
