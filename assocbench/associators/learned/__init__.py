"""The learned associator: per-pair ``features``, boosted trees as plain data (``forest``), an
assignment on their log-odds (``associator``); ``train`` fits a model from an export (scikit-learn:
``pip install 'assocbench[learn]'``; inference needs numpy only)."""

from .associator import Learned

__all__ = ["Learned"]
