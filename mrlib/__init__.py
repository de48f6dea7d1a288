"""mrlib: multi-resolution conditional generative modelling of SMPL human motion.

The public API, in the order data flows through it::

    motion = mrlib.load_motion("clip.bvh")            # BVH / AMASS npz / EasyMocap -> SMPL
    body = mrlib.load_body_model()                      # real SMPL or the embedded default body
    x = mrlib.motion_to_features(motion, body)          # (T, 153) model features
    contacts = mrlib.foot_contacts(motion, body)        # (T, 6) foot contact labels
    result = mrlib.train.train(mrlib.TrainingSet.from_motions(clips), mrlib.tutorial(), "runs/x")
    model = mrlib.load_model(result.checkpoint)
    new = mrlib.generate(model, "walk_happy", length=600, seed=0)
    sad = mrlib.restyle(model, "my_walk.bvh", "walk_sad", level=4, seed=0)  # a clip restyled

Conventions (metres, Y up, 6D = first two matrix columns) are stated in ``mrlib.skeleton``;
``docs/architecture.md`` maps the modules onto the paper. Rendering helpers import
pyvista / matplotlib only when called. Submodules keep their own names (``mrlib.train``,
``mrlib.evaluate``, ``mrlib.sample``, ``mrlib.speech``, ...).

Shape letters, the same in every module's docstrings and comments:

====  =====================================================================
B     samples of a batch (generated clips, crossover samples, ...)
N     training clips; also windows of a clip where a metric slides one
T     frames of one clip (``T_i`` at pyramid level i, ``T_a`` speech frames)
S     frames of a packed batch: B samples end to end (``mrlib.pyramid``)
L     pyramid levels; i a level (1-based in the public API, 0-based inside)
J     joints (24 for SMPL)
C     feature channels of the model (153, ``mrlib.features``)
D     channels of a condition or of metric features
K     labels; also selected vertices in ``mrlib.body`` / ``mrlib.plausibility``
V     mesh vertices
E     FiLM embedding size
====  =====================================================================
"""

# restyle: a module that is called as its function, mrlib.restyle(model, clip, label)
from mrlib import datasets, restyle, threads
from mrlib.body import BodyModel, BodyOutput, load_body_model
from mrlib.config import ModelConfig, TrainConfig, get_preset, paper, tutorial
from mrlib.contacts import DEFAULT_CONTACT_THRESHOLD, foot_contacts, foot_vertex_velocity
from mrlib.data import TrainingSet
from mrlib.errors import (
    BodyModelError,
    BVHFormatError,
    ClipTooShortError,
    JointMapError,
    MotionFileError,
    MotionValueError,
    MrlibError,
    UnsupportedFormatError,
)
from mrlib.evaluate import EvaluationResult, evaluate_model
from mrlib.features import (
    NUM_FEATURES,
    FeatureNormalizer,
    feature_layout,
    features_to_motion,
    motion_to_features,
)
from mrlib.io import load_label, load_motion, save_motion
from mrlib.metrics import (
    condition_fidelity,
    coverage,
    coverage_profile,
    global_diversity,
    local_diversity,
    metric_features,
    reconstruction_error,
)
from mrlib.motion import Motion
from mrlib.plausibility import plausibility_report
from mrlib.plots import plot_contacts
from mrlib.render import animate_skeleton, plot_skeleton_strip, render_meshes, save_gif
from mrlib.sample import cleanup_foot_contacts, generate, load_model, reconstruct

__version__ = "0.1.0"

__all__ = [
    # data
    "Motion",
    "load_motion",
    "save_motion",
    "load_label",
    "datasets",
    "threads",
    # body and contacts
    "BodyModel",
    "BodyOutput",
    "load_body_model",
    "foot_contacts",
    "foot_vertex_velocity",
    "DEFAULT_CONTACT_THRESHOLD",
    # features
    "NUM_FEATURES",
    "feature_layout",
    "motion_to_features",
    "features_to_motion",
    "FeatureNormalizer",
    # the model: configure, train, sample
    "ModelConfig",
    "TrainConfig",
    "paper",
    "tutorial",
    "get_preset",
    "TrainingSet",
    "load_model",
    "generate",
    "reconstruct",
    "restyle",
    "cleanup_foot_contacts",
    # evaluation
    "evaluate_model",
    "EvaluationResult",
    "plausibility_report",
    # metrics
    "metric_features",
    "coverage",
    "coverage_profile",
    "global_diversity",
    "local_diversity",
    "reconstruction_error",
    "condition_fidelity",
    # plots and renders
    "plot_contacts",
    "render_meshes",
    "plot_skeleton_strip",
    "animate_skeleton",
    "save_gif",
    # errors
    "MrlibError",
    "MotionFileError",
    "BVHFormatError",
    "JointMapError",
    "MotionValueError",
    "UnsupportedFormatError",
    "ClipTooShortError",
    "BodyModelError",
]
