"""Where a body in SMPL parameters stands: which world axis is up, and where the floor is.

Used by the npz and EasyMocap readers (``mrlib.io.npz``) for files that do not say: an
AMASS file is Z up, a BEAT2 one Y up, an EasyMocap folder is in a camera's frame, and a
file written for another body model (SMPL-X's pelvis sits lower than SMPL's) floats or
sinks on mrlib's body.

* :func:`detect_npz_up_axis`: the signed world axis that both the pelvis's own up axis
  (SMPL's rest body stands along +Y) and the pelvis-to-head direction point along, on
  average over the clip, by a clear margin; else a one-line refusal naming ``up_axis=``.
* :func:`floor_height`: the height the feet stand at, the median over frames with a foot
  in contact of the lowest such foot vertex.
* :func:`stance`: how a loaded ``Motion`` stands (head over pelvis over ankles, feet on
  y = 0), to check a file was read upright and on the floor.
"""

from __future__ import annotations

import numpy as np
import torch

from mrlib.errors import MotionFileError
from mrlib.io.axes import detect_up_axis
from mrlib.io.bodyfit import default_body
from mrlib.representation.rotations import axis_angle_to_matrix
from mrlib.representation.skeleton import JOINT_NAMES

__all__ = ["detect_npz_up_axis", "floor_height", "stance", "FLOOR_TOLERANCE_M"]

FLOOR_TOLERANCE_M = 0.005  # a floor closer than this to y = 0 is left where it is
# how clearly the body's up directions must pick one axis: the mean up vector's largest
# component at least this long, and this many times the next largest
_UP_MIN, _UP_MARGIN = 0.5, 2.0


def detect_npz_up_axis(poses, trans, betas, body=None, *, source=None) -> tuple[str, str]:
    """The up axis of SMPL parameters ``poses (T, 24, 3)``, ``trans (T, 3)`` in an unknown
    world, and the reason in words: the signed world axis that both the pelvis's own up
    axis (SMPL's rest body stands along +Y) and the pelvis-to-head vector (posed on
    ``body``) point along, on average over the clip (up to 500 frames, evenly spaced).

    Raises:
        MotionFileError: the two disagree, or neither points clearly along one axis (a
            clip lying down, or upside down and tumbling), naming ``up_axis=``.
    """
    from mrlib.representation.body import resolve_body

    body = resolve_body(default_body() if body is None else body)
    T = len(poses)
    idx = np.unique(np.linspace(0, T - 1, min(T, 500)).round().astype(int))
    R = axis_angle_to_matrix(torch.from_numpy(np.asarray(poses[idx], np.float64)))
    pelvis_up = R[:, 0, :, 1].numpy()  # the pelvis's +Y in the world, (T', 3)
    with torch.no_grad():
        out = body.forward(R.to(body.device, body.dtype), None, _betas_for(body, betas))
    J = out.joints.double().cpu().numpy()
    head = J[:, JOINT_NAMES.index("head")] - J[:, 0]
    head /= np.maximum(np.linalg.norm(head, axis=-1, keepdims=True), 1e-9)
    votes = {}
    for name, v in (("the pelvis's up axis", pelvis_up), ("the pelvis-to-head direction", head)):
        m = v.mean(0)
        order = np.argsort(-np.abs(m))
        clear = abs(m[order[0]]) >= _UP_MIN and abs(m[order[0]]) >= _UP_MARGIN * abs(m[order[1]])
        votes[name] = (detect_up_axis(v) if clear else None, m)
    axes = {a for a, _ in votes.values()}
    shown = "; ".join(
        f"{n} averages ({', '.join(f'{x:+.2f}' for x in m)})" for n, (_, m) in votes.items()
    )
    if len(axes) != 1 or None in axes:
        raise MotionFileError(
            source if source is not None else "<poses>",
            f"cannot tell the up axis from the body ({shown}): pass up_axis= "
            "(--up-axis on the command line), e.g. 'z' for AMASS, 'y' for BEAT2",
        )
    axis = axes.pop()
    return axis, f"told from the body: {shown}"


def _betas_for(body, betas) -> torch.Tensor | None:
    if betas is None:
        return None
    from mrlib.representation.body import fit_betas

    return torch.as_tensor(fit_betas(betas, body.num_betas), dtype=body.dtype).to(body.device)


def floor_height(poses, trans, betas, fps: float, body=None) -> float | None:
    """Height (m) the feet of a Y-up clip stand at: the median, over frames with a foot
    vertex slower than the contact threshold, of the lowest such vertex; None when no
    frame has one."""
    from mrlib.representation.body import resolve_body
    from mrlib.representation.contacts import contacts_from_velocity, finite_difference_velocity

    if len(poses) < 2:
        return None
    body = resolve_body(default_body() if body is None else body)
    R = axis_angle_to_matrix(torch.from_numpy(np.asarray(poses, np.float64)))
    t = torch.from_numpy(np.asarray(trans, np.float64))
    with torch.no_grad():
        out = body.forward(R.to(body.device, body.dtype), t.to(body.device, body.dtype),
                           _betas_for(body, betas), vertex_ids=list(body.foot_vertex_ids))  # fmt: skip
    F = out.vertices.double().cpu()
    c = contacts_from_velocity(finite_difference_velocity(F, fps)) > 0.5
    y = F[..., 1].numpy()
    lows = np.where(c, y, np.inf).min(1)[c.any(1)]
    return float(np.median(lows)) if len(lows) else None


def stance(motion, body=None) -> dict[str, float]:
    """How ``motion`` (a ``Motion``, Y up) stands on ``body`` (default mrlib's):

    * ``head_above_pelvis``, ``pelvis_above_ankles``: shares of frames (1.0 upright);
    * ``floor_cm``: over frames with a foot in contact, the median distance of the lowest
      contact foot vertex from y = 0 (cm; NaN with no contact at all).
    """
    from mrlib.representation.contacts import foot_contacts, foot_vertex_positions

    body = default_body() if body is None else body
    J = body.motion_joints(motion)
    head, pelvis = J[:, JOINT_NAMES.index("head"), 1], J[:, 0, 1]
    ankles = J[:, [JOINT_NAMES.index("left_ankle"), JOINT_NAMES.index("right_ankle")], 1]
    R, t, b = body.motion_inputs(motion)
    feet = foot_vertex_positions(body, R, t, b).numpy()[..., 1]
    c = foot_contacts(motion, body) > 0.5
    low = np.where(c, feet, np.inf).min(1)[c.any(1)]
    return {
        "head_above_pelvis": float((head > pelvis).mean()),
        "pelvis_above_ankles": float((pelvis > ankles.max(1)).mean()),
        "floor_cm": float(np.median(np.abs(low)) * 100) if len(low) else float("nan"),
    }
