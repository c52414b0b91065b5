"""Evaluation: attitude errors on the rotation manifold, metrics, comparisons, paper reproductions."""
from quadest.evaluation.metrics import (AXES, error_angles, euler_errors, summarize_errors,
                                        time_estimator)

__all__ = ["AXES", "error_angles", "euler_errors", "summarize_errors", "time_estimator"]
