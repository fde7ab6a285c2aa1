"""The learned associator: per-pair features (``features``), boosted trees kept as plain data
(``forest``), an assignment on their log-odds (``associator``); ``train`` fits a model from an
export (it needs scikit-learn: ``pip install 'assocbench[learn]'``; inference needs numpy only)."""

from .associator import Learned

__all__ = ["Learned"]
