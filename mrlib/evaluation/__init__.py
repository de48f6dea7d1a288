"""Evaluating a trained model: the evaluation protocol (``evaluate``) and its table and
CSV (``results``), calibration rows from real capture (``calibration``), condition
fidelity per label (``fidelity``), the evidence that a crossover mixes the two labels'
bands (``crossover``) and the measures of restyling (``restyle_evidence``).
"""

from mrlib.evaluation.calibration import CalibrationOptions
from mrlib.evaluation.evaluate import evaluate_model
from mrlib.evaluation.results import EvaluationResult, EvaluationSettings

__all__ = ["evaluate_model", "EvaluationResult", "EvaluationSettings", "CalibrationOptions"]
