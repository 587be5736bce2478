"""Program induction from part-based examples (seed 000): a learned program is a model."""
