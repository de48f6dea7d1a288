"""mrlib: multi-resolution conditional generative modelling of SMPL human motion
(Moreno-Villamarin, Hilsmann and Eisert, CVMP 2024).

The public API, in the order data flows through it::

    motion = mrlib.load_motion("clip.bvh")              # BVH / AMASS npz / EasyMocap -> SMPL
    data = mrlib.TrainingSet.from_motions(clips)        # clips with their labels
    result = mrlib.train(data, mrlib.get_preset("demo"), "runs/x")
    model = mrlib.load_model(result.checkpoint)
    new = mrlib.generate(model, "walk_happy", length=600, seed=0)
    mixed = mrlib.generate(model, mrlib.Condition.crossover("walk_sad", "walk_happy", 4),
                           num=8, seed=0, sampler=mrlib.Sampler(fine_noise=0.5))
    sad = mrlib.restyle(model, "my_walk.bvh", "walk_sad", level=4, seed=0)
    mrlib.evaluate_model(model).save("runs/x/eval")  # cleaned and raw samples, calibration rows
    mrlib.save_motion(new, "new.bvh")

The packages, bottom up (each imports only from those before it; ``python -m
mrlib.tools.layers`` checks it): ``representation`` (skeleton, rotations, Motion, the
SMPL body, features, contacts), ``io`` (files), ``datasets``, ``metrics``, ``model``
(config and presets, pyramid, generator, critic, losses), ``sampling`` (conditions,
generate, clean-up, restyle, ``constraints``), ``training``, ``evaluation``, ``speech``, ``viz`` (plots, renders,
widgets), ``app`` (command line, demo). ``docs/architecture.md`` maps them onto the
paper; conventions (metres, Y up, 6D = first two matrix columns) are stated in
``mrlib.representation.skeleton``.

Shape letters, the same in every module's docstrings and comments:

====  =====================================================================
B     samples of a batch (generated clips, crossover samples, ...)
N     training clips; also windows of a clip where a metric slides one
T     frames of one clip (``T_i`` at pyramid level i, ``T_a`` speech frames)
S     frames of a packed batch: B samples end to end (``mrlib.model.pyramid``)
L     pyramid levels; i a level (1-based in the public API, 0-based inside)
J     joints (24 for SMPL)
C     feature channels of the model (153, ``mrlib.representation.features``)
D     channels of a condition or of metric features
K     labels; also selected vertices in ``mrlib.representation.body`` / ``mrlib.metrics.plausibility``
V     mesh vertices
E     FiLM embedding size
====  =====================================================================
"""

from mrlib import datasets, errors, threads, viz
from mrlib.errors import MrlibError
from mrlib.evaluation import evaluate_model
from mrlib.io import load_motion, save_motion
from mrlib.model.config import TrainConfig
from mrlib.model.presets import PRESETS, get_preset
from mrlib.representation import Motion, load_body_model
from mrlib.sampling import Condition, Sampler, constraints, generate, load_model, restyle
from mrlib.training import TrainingSet, train

__version__ = "0.1.0"

__all__ = [
    "Motion",
    "load_motion",
    "save_motion",
    "load_body_model",
    "TrainingSet",
    "TrainConfig",
    "PRESETS",
    "get_preset",
    "train",
    "load_model",
    "generate",
    "Condition",
    "Sampler",
    "restyle",
    "constraints",
    "evaluate_model",
    "MrlibError",
    "errors",
    "datasets",
    "threads",
    "viz",
]
