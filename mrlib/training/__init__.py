"""Training (paper, Sec. 3.4): the training set of clips and labels (``data``); the
block-wise :class:`Trainer` and :func:`train` (``trainer``), built from what a run
builds first (``build``), one iteration's objectives (``steps``: the paper's Eq. 6 and
WGAN-GP), the block loop and its loss log (``loop``), and the run folder, results and
model cache (``run``). Checkpoints are ``mrlib.model.checkpoint``.
"""

from mrlib.training.data import TrainingSet
from mrlib.training.loop import TrainingDivergedError
from mrlib.training.run import TrainResult
from mrlib.training.trainer import Trainer, train, train_cached, train_or_reuse

__all__ = [
    "TrainingSet",
    "train",
    "train_cached",
    "train_or_reuse",
    "Trainer",
    "TrainResult",
    "TrainingDivergedError",
]
