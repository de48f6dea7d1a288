"""Training (paper, Sec. 3.4): the training set of clips and labels (``data``), the
block-wise trainer and its run folder (``trainer``), checkpoints (``checkpoint``).
"""

from mrlib.training.data import TrainingSet
from mrlib.training.trainer import (
    Trainer,
    TrainingDivergedError,
    TrainResult,
    train,
    train_cached,
    train_or_reuse,
)

__all__ = [
    "TrainingSet",
    "train",
    "train_cached",
    "train_or_reuse",
    "Trainer",
    "TrainResult",
    "TrainingDivergedError",
]
