"""Scoring: per-frame counts against the truth, their summary, and trajectory accuracy and
consistency."""
