"""mrlib: multi-resolution conditional generative modelling of SMPL motion."""

__version__ = "0.1.0"
