"""Evaluating a trained model: the evaluation protocol and its CSV (``evaluate``),
calibration rows from real capture (``calibration``), condition fidelity per label
(``fidelity``) and the evidence that a crossover mixes the two labels' bands
(``crossover``).
"""

from mrlib.evaluation.evaluate import EvaluationResult, evaluate_model

__all__ = ["evaluate_model", "EvaluationResult"]
