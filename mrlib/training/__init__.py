"""Training (paper, Sec. 3.4). Read ``trainer`` top to bottom: :func:`train`, the
:class:`Trainer` (the state of a run), the block loop (``run_blocks``) and one iteration
(``critic_steps``, ``generator_step``). Around it:

* ``data``: the training set of clips and labels (:class:`TrainingSet`);
* ``build``: what a run builds first (the packed batches of every clip's pyramid, the
  networks, the optimisers, the body-model pass);
* ``signals``: the control signal, where labels become conditions (and what a new
  signal, such as ``mrlib.speech``'s, provides);
* ``objective``: the paper's objective as pure functions (Eq. 11-16);
* ``monitor``: the loss log, the progress bars, Ctrl-C, the divergence check;
* ``checkpoints``: what a checkpoint holds (``mrlib.model.checkpoint`` writes it);
* ``run``: the run folder, its lock, what a run returns, and the model cache.
"""

from mrlib.training.data import TrainingSet
from mrlib.training.monitor import TrainingDivergedError
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
