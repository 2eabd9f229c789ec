"""reconstruct: reconstruction from captures, and evaluation against ground truth.

Public API: :func:`evaluate` and :class:`EvaluationResult` (from
:mod:`reconstruct.evaluate`; open3d and scipy load only when used).
"""

from reconstruct.evaluate import EvaluationResult, evaluate

__all__ = ["evaluate", "EvaluationResult"]
