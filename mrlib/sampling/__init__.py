"""Sampling a trained model: generation and reconstruction (``generate``), the foot
contact clean-up (``cleanup``), restyling a clip of one's own (``restyle``), reference
samples per label (``references``) and control beyond labels (``constraints``: paths,
keyframes, body parts, loops).
"""

from mrlib.model.trained import GenerativeModel, load_model
from mrlib.sampling import constraints
from mrlib.sampling.cleanup import cleanup_foot_contacts
from mrlib.sampling.generation import generate, reconstruct
from mrlib.sampling.restyling import restyle

__all__ = [
    "GenerativeModel",
    "load_model",
    "generate",
    "reconstruct",
    "cleanup_foot_contacts",
    "restyle",
    "constraints",
]
