"""Measurement models and pose algebra shared by the tracks and estimators; ``synthetic`` draws
problems from them."""
