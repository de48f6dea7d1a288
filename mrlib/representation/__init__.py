"""Motion as the paper represents it (Sec. 3.1): SMPL poses, the body, the model's
features (joint rotations in 6D, root displacement, foot contacts) and contact labels.

Modules, bottom up: ``skeleton`` (joint tree and conventions), ``rotations`` (axis-angle,
matrices, 6D), ``motion`` (the :class:`Motion` container), ``smpl_files`` and ``body``
(the SMPL body and its joint regressor), ``contacts`` (foot contact labels),
``features`` (motion to and from the ``(T, 153)`` model features).
"""

from mrlib.representation.body import BodyModel, BodyOutput, load_body_model
from mrlib.representation.contacts import DEFAULT_CONTACT_THRESHOLD, foot_contacts
from mrlib.representation.features import (
    NUM_FEATURES,
    FeatureNormalizer,
    feature_layout,
    features_to_motion,
    motion_to_features,
)
from mrlib.representation.motion import Motion

__all__ = [
    "Motion",
    "BodyModel",
    "BodyOutput",
    "load_body_model",
    "foot_contacts",
    "DEFAULT_CONTACT_THRESHOLD",
    "NUM_FEATURES",
    "feature_layout",
    "motion_to_features",
    "features_to_motion",
    "FeatureNormalizer",
]
