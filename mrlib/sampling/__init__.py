"""Sampling a trained model: generation and reconstruction (``generation``: ``generate``
one motion, a batch or every level's output; ``reconstruct``), the condition that drives
each level (``conditions``: ``Condition``) and how the generator is sampled (``sampler``:
``Sampler``), the foot-contact clean-up (``cleanup``), restyling a clip of one's own
(``restyling``: ``restyle``) and control beyond labels (``constraints``: paths,
keyframes, body parts, loops).
"""

from mrlib.model.trained import GenerativeModel, load_model
from mrlib.sampling import constraints
from mrlib.sampling.cleanup import cleanup_foot_contacts
from mrlib.sampling.conditions import Condition
from mrlib.sampling.generation import generate, reconstruct
from mrlib.sampling.restyling import restyle
from mrlib.sampling.sampler import Sampler

__all__ = [
    "GenerativeModel",
    "load_model",
    "Condition",
    "Sampler",
    "generate",
    "reconstruct",
    "cleanup_foot_contacts",
    "restyle",
    "constraints",
]
