"""Rotation conversions between axis-angle, matrices and the 6D form, batched.

Thin, named wrappers over `roma <https://naver.github.io/roma/>`_ so the rest of mrlib
speaks one vocabulary. Every function takes any number of leading batch dimensions
(``(..., 3)``, ``(..., 3, 3)``, ``(..., 6)``) and works on any device and float dtype.

The 6D representation (Zhou et al., "On the Continuity of Rotation Representations in
Neural Networks", CVPR 2019) is the first two **columns** of the rotation matrix,
``[R00, R10, R20, R01, R11, R21]``; it maps back through Gram-Schmidt
(``roma.special_gramschmidt``), which accepts any non-degenerate 6-vector.
"""

from __future__ import annotations

import roma
import torch

__all__ = [
    "axis_angle_to_matrix",
    "matrix_to_axis_angle",
    "matrix_to_6d",
    "sixd_to_matrix",
    "axis_angle_to_6d",
    "sixd_to_axis_angle",
    "geodesic_distance",
]


def axis_angle_to_matrix(aa: torch.Tensor) -> torch.Tensor:
    """``(..., 3)`` axis-angle (radians) -> ``(..., 3, 3)`` rotation matrices."""
    return roma.rotvec_to_rotmat(aa)


def matrix_to_axis_angle(R: torch.Tensor) -> torch.Tensor:
    """``(..., 3, 3)`` rotation matrices -> ``(..., 3)`` axis-angle, angle in [0, pi]."""
    return roma.rotmat_to_rotvec(R)


def matrix_to_6d(R: torch.Tensor) -> torch.Tensor:
    """``(..., 3, 3)`` -> ``(..., 6)``: the first two columns, column after column."""
    return R[..., :, :2].transpose(-1, -2).reshape(*R.shape[:-2], 6)


def sixd_to_matrix(x: torch.Tensor) -> torch.Tensor:
    """``(..., 6)`` -> ``(..., 3, 3)`` by Gram-Schmidt on the two columns."""
    cols = x.reshape(*x.shape[:-1], 2, 3).transpose(-1, -2)  # (..., 3, 2)
    return roma.special_gramschmidt(cols)


def axis_angle_to_6d(aa: torch.Tensor) -> torch.Tensor:
    """``(..., 3)`` -> ``(..., 6)``."""
    return matrix_to_6d(axis_angle_to_matrix(aa))


def sixd_to_axis_angle(x: torch.Tensor) -> torch.Tensor:
    """``(..., 6)`` -> ``(..., 3)``."""
    return matrix_to_axis_angle(sixd_to_matrix(x))


def geodesic_distance(R1: torch.Tensor, R2: torch.Tensor) -> torch.Tensor:
    """Angle in radians of ``R1^T R2`` for ``(..., 3, 3)`` inputs, ``(...)`` output."""
    return roma.rotmat_geodesic_distance(R1, R2)
