"""The multi-resolution GAN (paper, Sec. 3.2-3.4): its configuration and presets
(``config``), the pyramid of lengths and noise amplitudes (``pyramid``), the generator
with its FiLM encoders (``generator``), the patch critics (``critic``), both built of
skeleton-aware convolutions (``skeleton_conv``), and the loss terms as pure functions
(``losses``).
"""

from mrlib.model.config import LossWeights, ModelConfig, TrainConfig
from mrlib.model.presets import PRESETS, describe_presets, get_preset

__all__ = ["ModelConfig", "LossWeights", "TrainConfig", "PRESETS", "get_preset", "describe_presets"]
