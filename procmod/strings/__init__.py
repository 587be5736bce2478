"""String-based synthesis of structured shapes (seed 001)."""
