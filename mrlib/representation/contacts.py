"""Foot contact labels from foot-vertex speeds (paper, Sec. 3.1).

For each of the six foot vertices F = (left big toe, left small toe, left heel, right
big toe, right small toe, right heel) — order ``mrlib.representation.skeleton.CONTACT_NAMES``, vertex
ids ``BodyModel.foot_vertex_ids`` — and each frame t, the label is

    c[t, j] = 1  if  || d/dt V_j(beta, theta_t) ||_2 < threshold  else 0,

with the velocity taken by finite differences of the posed mesh (metres per second).
``foot_vertex_velocity`` is the differentiable version the contact-consistency loss uses
on generated motion.

Threshold. ``DEFAULT_CONTACT_THRESHOLD`` (m/s) was tuned on the 15 Bandai-Namco
``walk_*_001`` clips (30 fps, retargeted to the default body). Foot-vertex speeds there
are bimodal: 40 % of the samples are below 0.08 m/s (planted feet, with mocap jitter
and skin roll) and 30 % above 1.5 m/s (swing). At 0.25 m/s a foot (any of its three
vertices) is labelled in contact 55 % of the time (heels 41 %, toes 50-53 %), at least
one foot is down in 97 % of the frames, and consecutive heel strikes alternate
left/right 99 % of the time (worst clip 87 %). At 0.1-0.2 m/s feet are labelled in
contact 45-53 % of the time and alternation is slightly worse (worst clip 81-83 %); at
0.4-0.5 m/s contacts extend into the swing and alternation breaks on some clips (worst
clip 61 % and 52 %). Adjust it with ``threshold=``.

No height gate is applied by default: the speed test alone gave clean alternation on
the walks, and a height gate depends on where the ground is (retargeted clips are not
always exactly at y = 0). ``max_height`` adds one when wanted (a vertex higher than
``max_height`` metres above the clip's lowest foot vertex is never in contact).
"""

from __future__ import annotations

from typing import Any

import numpy as np
import torch

from mrlib.errors import ClipTooShortError, MotionValueError
from mrlib.representation.skeleton import NUM_JOINTS

__all__ = [
    "DEFAULT_CONTACT_THRESHOLD",
    "finite_difference_velocity",
    "foot_vertex_positions",
    "foot_vertex_velocity",
    "foot_contacts",
    "contacts_from_velocity",
]

DEFAULT_CONTACT_THRESHOLD = 0.25  # m/s; tuned on Bandai walks, see the module docstring


def finite_difference_velocity(x: torch.Tensor, fps: float, dim: int = -3) -> torch.Tensor:
    """Time derivative of ``x`` along ``dim`` (the frame axis), in units per second.

    Central differences inside, one-sided differences at the first and last frame.

    Args:
        x: ``(..., T, ...)`` positions; ``T >= 2`` along ``dim``.
        fps: frames per second.
    Returns:
        Tensor of the same shape as ``x``.
    """
    T = x.shape[dim]
    if T < 2:
        raise ClipTooShortError(f"velocity needs at least 2 frames, got {T}")
    x = x.movedim(dim, 0)
    v = torch.empty_like(x)
    v[1:-1] = (x[2:] - x[:-2]) * (fps / 2.0)
    v[0] = (x[1] - x[0]) * fps
    v[-1] = (x[-1] - x[-2]) * fps
    return v.movedim(0, dim)


def foot_vertex_positions(
    body: Any, rotmat: torch.Tensor, trans: torch.Tensor, betas: Any = None
) -> torch.Tensor:
    """Positions of the six foot vertices, ``(..., T, 6, 3)`` metres.

    Args:
        body: a ``mrlib.representation.body.BodyModel``.
        rotmat: ``(..., T, 24, 3, 3)`` local joint rotations.
        trans: ``(..., T, 3)`` root translation.
        betas: ``(NB,)`` or ``(..., NB)`` (one shape per sequence) or None.
    """
    if rotmat.ndim < 4 or tuple(rotmat.shape[-3:]) != (NUM_JOINTS, 3, 3):
        raise MotionValueError(
            f"rotmat must have shape (..., T, 24, 3, 3), got {tuple(rotmat.shape)}"
        )
    if tuple(trans.shape) != tuple(rotmat.shape[:-3]) + (3,):
        raise MotionValueError(
            f"trans must have shape {tuple(rotmat.shape[:-3]) + (3,)} to match rotmat, "
            f"got {tuple(trans.shape)}"
        )
    if betas is not None:
        betas = torch.as_tensor(betas)
        if betas.ndim > 1:  # one shape per sequence: broadcast over the frame axis
            betas = betas.unsqueeze(-2)
    out = body(rotmat, trans, betas, vertex_ids=list(body.foot_vertex_ids))
    return out.vertices


def foot_vertex_velocity(
    body: Any, rotmat: torch.Tensor, trans: torch.Tensor, fps: float, betas: Any = None
) -> torch.Tensor:
    """Velocities of the six foot vertices, ``(..., T, 6, 3)`` in m/s; differentiable.

    Args:
        body: a ``mrlib.representation.body.BodyModel``.
        rotmat: ``(..., T, 24, 3, 3)`` local joint rotations.
        trans: ``(..., T, 3)`` root translation (metres).
        fps: frames per second.
        betas: ``(NB,)``, ``(..., NB)`` (per sequence) or None.
    """
    if not (np.isfinite(fps) and fps > 0):
        raise MotionValueError(f"fps must be positive, got {fps}")
    return finite_difference_velocity(foot_vertex_positions(body, rotmat, trans, betas), fps)


def contacts_from_velocity(
    velocity: torch.Tensor | np.ndarray, threshold: float = DEFAULT_CONTACT_THRESHOLD
) -> np.ndarray:
    """``(..., 6, 3)`` velocities (m/s) -> ``(..., 6)`` float32 labels in {0, 1}."""
    speed = np.linalg.norm(np.asarray(torch.as_tensor(velocity).detach().cpu()), axis=-1)
    return (speed < threshold).astype(np.float32)


def foot_contacts(
    motion: Any,
    body: Any = None,
    threshold: float = DEFAULT_CONTACT_THRESHOLD,
    *,
    max_height: float | None = None,
) -> np.ndarray:
    """Contact labels of a clip: 1 where a foot vertex moves slower than ``threshold``.

    Args:
        motion: a ``mrlib.Motion`` (poses, trans, fps, betas).
        body: a ``BodyModel``; None loads the default one (``load_body_model()``).
        threshold: speed threshold in m/s (see the module docstring for the default).
        max_height: optional height gate in metres above the lowest foot vertex of the
            clip; None (default) disables it.
    Returns:
        ``(T, 6)`` float32 array in {0, 1}, channel order ``CONTACT_NAMES``.
    """
    if not (np.isfinite(threshold) and threshold > 0):
        raise MotionValueError(
            f"contact threshold must be a positive speed in m/s, got {threshold}"
        )
    from mrlib.representation.body import resolve_body

    body = resolve_body(body)
    if motion.num_frames < 2:
        raise ClipTooShortError(f"{motion!r}: contact labels need at least 2 frames")
    with torch.no_grad():
        R, trans, betas = body.motion_inputs(motion)
        pos = foot_vertex_positions(body, R, trans, betas)  # (T, 6, 3)
        vel = finite_difference_velocity(pos, motion.fps)
    c = contacts_from_velocity(vel, threshold)
    if max_height is not None:
        y = pos[..., 1].cpu().numpy()
        c = c * (y < y.min() + max_height)
    return c.astype(np.float32)
