"""How well a motion walks a ground path (:func:`path_error`), by arc length: where
along the path the pelvis is at each frame, not only how near it is (the distance to the
nearest path point alone scores a walker that stops near the start as well as one that
walks the whole path). Paths and how a motion is bent onto one:
``mrlib.sampling.constraints.path``.
"""

from __future__ import annotations

import numpy as np

from mrlib.representation.motion import Motion
from mrlib.sampling.arguments import checked
from mrlib.sampling.constraints.common import pelvis_rest
from mrlib.sampling.constraints.path import GroundPath, check_path_spec, parse_path

__all__ = ["path_error"]

# path_error follows the pelvis along the path in steps of REACH_STEP_M, searching
# REACH_WINDOW_M (or MAX_TRAVEL_SPEED / fps) either side of the last frame's arc length
REACH_STEP_M = 0.01
REACH_WINDOW_M = 0.5
MAX_TRAVEL_SPEED = 6.0  # m/s: faster than a sprint


def _arc_reached(path: GroundPath, xz: np.ndarray, fps: float, start: float) -> np.ndarray:
    """``(T,)`` arc length along ``path`` reached by ground points ``xz (T, 2)``: from
    ``start``, each frame moves to the nearest path point within ``REACH_WINDOW_M`` (or
    ``MAX_TRAVEL_SPEED`` / fps) of the previous frame's, in ``REACH_STEP_M`` steps, so the
    point found moves along the path as the walker does (a figure-eight's crossing does
    not switch lobes, and a walker that stops stops it)."""
    w = max(REACH_WINDOW_M, MAX_TRAVEL_SPEED / fps)
    grid = np.arange(-w, w + REACH_STEP_M / 2, REACH_STEP_M)
    out = np.empty(len(xz))
    s = float(start)
    for t, x in enumerate(xz):
        cand = s + grid
        q, _ = path.at(cand)
        s = float(cand[np.argmin(((q - x) ** 2).sum(-1))])
        out[t] = s
    return out


@checked(path=check_path_spec)
def path_error(motion: Motion, path: GroundPath | str, body=None) -> dict[str, float]:
    """How well the pelvis walks ``path``, by arc length (where along the path it is,
    not only how near: a walker that stops near the start stays near the path).

    The pelvis ground projection is followed along the path frame by frame (the arc
    length it has reached, :func:`_arc_reached`) and compared with a schedule, the arc
    length it should have reached by each frame: the path's times if it has them, else
    an even pace that ends where the walk ended (the arc it reached, spread evenly over
    the motion's duration), so a walker that stalls part-way is behind schedule while it
    stands and ahead before.

    Returns:
        A dict of floats:

        * ``mean_m``, ``max_m``: distance (metres) from the pelvis at each frame to the
          path point at the schedule's arc length: mean and max over frames.
        * ``lateral_mean_m``, ``lateral_max_m``: distance (metres) from the pelvis to the
          path point at the arc length it reached (the nearest around it): how far off
          the line it walks, wherever along it.
        * ``progress``: the share of the path walked, the arc length reached at the last
          frame over the path's length (laps of a closed path; about 0 for a walker that
          never leaves the start, negative for one that walks it backwards).
    """
    from mrlib.representation.body import resolve_body

    path = parse_path(path)
    body = resolve_body(body, shared=True)
    pel = motion.trans[:, [0, 2]].astype(np.float64) + pelvis_rest(motion, body)[[0, 2]]
    reached = _arc_reached(path, pel, motion.fps, 0.0)
    t = np.arange(motion.num_frames) / motion.fps
    if path.times is not None:
        goal = path.arc_at_time(t)
    else:
        goal = reached[-1] * t / max(t[-1], 1e-9)
    d = np.linalg.norm(pel - path.at(goal)[0], axis=1)
    side = np.linalg.norm(pel - path.at(reached)[0], axis=1)
    return {
        "mean_m": float(d.mean()),
        "max_m": float(d.max()),
        "lateral_mean_m": float(side.mean()),
        "lateral_max_m": float(side.max()),
        "progress": float(reached[-1] / path.length),
    }
