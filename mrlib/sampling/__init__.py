"""Sampling a trained model: generation and reconstruction (``generate`` one motion,
``generate_many`` a list, ``generate_levels`` a motion with every level's output), the foot
contact clean-up (``cleanup``), restyling a clip of one's own (``restyle``), reference
samples per label (``references``) and control beyond labels (``constraints``: paths,
keyframes, body parts, loops).
"""

from mrlib.model.trained import GenerativeModel, load_model
from mrlib.sampling import constraints
from mrlib.sampling.cleanup import cleanup_foot_contacts
from mrlib.sampling.generation import (
    generate,
    generate_levels,
    generate_many,
    reconstruct,
    reconstruct_levels,
)
from mrlib.sampling.restyling import restyle

__all__ = [
    "GenerativeModel",
    "load_model",
    "generate",
    "generate_many",
    "generate_levels",
    "reconstruct",
    "reconstruct_levels",
    "cleanup_foot_contacts",
    "restyle",
    "constraints",
]
