"""Scoring: per-frame counts against the truth, their aggregation into a summary, and the
accuracy and consistency of an estimated trajectory (``trajectory``)."""
