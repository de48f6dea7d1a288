"""Measures of motion, computed from motions and features alone (no model): the paper's
metrics (Sec. 5: coverage, global diversity by patch nearest neighbours, local
diversity) in ``paper``, physical plausibility (foot skating, jerk, ground penetration)
in ``plausibility``, and the frequency bands of a motion in ``bands``; ``oracles`` holds
slow versions of the paper's metrics, written from their definitions, for the tests.
"""

from mrlib.metrics.paper import (
    condition_fidelity,
    coverage,
    coverage_profile,
    global_diversity,
    local_diversity,
    metric_features,
    reconstruction_error,
)
from mrlib.metrics.plausibility import plausibility_report

__all__ = [
    "metric_features",
    "coverage",
    "coverage_profile",
    "global_diversity",
    "local_diversity",
    "reconstruction_error",
    "condition_fidelity",
    "plausibility_report",
]
