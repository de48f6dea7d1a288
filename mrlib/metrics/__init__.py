"""Measures of motion, computed from motions and features alone (no model): the paper's
metrics (Section "Evaluation and Discussion"): coverage, Eq. (17)-(18), in ``coverage``,
global diversity by patched nearest neighbours, Eq. (19), and local diversity, Eq. (20),
in ``diversity``, both on the features, frame distances and window nearest neighbours of
``windows``; physical plausibility (foot skating, jerk, ground penetration) in
``plausibility``, and the frequency bands of a motion in ``bands``; ``oracles`` holds
slow versions of the paper's metrics, written from their definitions, for the tests.
"""

from mrlib.metrics.coverage import condition_fidelity, coverage, coverage_profile
from mrlib.metrics.diversity import global_diversity, local_diversity
from mrlib.metrics.plausibility import plausibility_report
from mrlib.metrics.windows import metric_features, reconstruction_error

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
