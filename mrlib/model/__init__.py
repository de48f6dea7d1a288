"""The multi-resolution GAN (paper, Sec. 3.2-3.4): its configuration and presets
(``config``), the pyramid of lengths and noise amplitudes (``pyramid``), the generators
and critics with FiLM and skeleton-aware convolutions (``networks``), and the loss terms
of Eq. 6 as pure functions (``losses``).
"""

from mrlib.model.config import (
    PRESETS,
    LossWeights,
    ModelConfig,
    TrainConfig,
    describe_presets,
    get_preset,
)

__all__ = ["ModelConfig", "LossWeights", "TrainConfig", "PRESETS", "get_preset", "describe_presets"]
