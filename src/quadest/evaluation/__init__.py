"""Evaluation: attitude errors on the rotation manifold, metrics, the one runner that estimates
and scores (:mod:`.runner`), comparisons, benchmarks, speed, paper reproductions."""

from quadest.evaluation.metrics import AXES, error_angles, euler_errors, summarize_errors
from quadest.evaluation.runner import estimate, estimate_all, evaluation_mask, score

__all__ = [
    "AXES",
    "error_angles",
    "estimate",
    "estimate_all",
    "euler_errors",
    "evaluation_mask",
    "score",
    "summarize_errors",
]
