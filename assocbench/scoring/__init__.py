"""Scoring: per-frame counts against the truth, and their aggregation into a summary."""
