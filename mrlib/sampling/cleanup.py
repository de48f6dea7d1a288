"""Foot-contact clean-up: feet that stay put while labelled in contact, on the floor, with
motion that stays smooth (``cleanup_foot_contacts``); in closed form, vectorised over
frames, or by a per-frame optimisation (``method="optimise"``).

The paper refines predicted contacts by inverse kinematics (Sec. 3.4), as GANimator does
(Li et al., SIGGRAPH 2022), with a per-frame optimisation. Here the default
(``style="smooth"``) solves for the corrections of the whole clip at once, the
least-squares form of Kovar et al.'s footskate clean-up (SCA 2002: the root first, then
the legs, corrections blended in and out) with the blends replaced by a smoothness term,
as in spacetime motion editing (Gleicher, SIGGRAPH 1998; Lee and Shin, SIGGRAPH 1999):

1. **Offsets** (:func:`smooth_foot_offsets`). A root offset ``r(t)`` and one offset
   ``l_f(t)`` per foot (the foot moves rigidly with its ankle) minimise, per axis, one
   quadratic energy: the ground speed of every contact vertex while labelled in contact
   (``PIN_WEIGHT``), the jerk of the corrections weighted by the joints each one moves
   (24 for the root, 3 for a leg; time scale ``SMOOTH_S``), and their size, the legs'
   dearer than the root's (``ROOT_HOLD_S``, ``LEG_HOLD_S``): a single planted foot is
   held by moving the whole body, which changes no joint angle (the pose features of
   the coverage metric leave the root out), and the legs take only the difference
   between two planted feet. Sparse, banded, one factorisation: milliseconds.
2. **The floor** (:func:`_vertical`). Vertically, the lowest vertex of each planted foot
   is pulled onto the floor (``FLOOR_WEIGHT``) and no vertex may go more than
   ``FLOOR_SLACK`` below it (stiff springs on an active set): the root takes the slow
   part, a leg, dearer (``LIFT_HOLD_S``), the brief dips of its own foot. The floor is
   where the training clips' planted feet rest (``generate`` passes it,
   ``mrlib.sampling.generation.training_floor``), else estimated from the clip
   (:func:`contact_floor`).
3. **Two-bone IK** (hip - knee - ankle, law of cosines) takes each ankle by its leg's
   offset, the foot keeping its global orientation; bone lengths are kept.

``style="pin"`` is the clean-up before it (:func:`plant_feet`): every contact vertex
pinned to its mean position over its run, eased in and out over ``BLEND_S`` seconds,
the root taking the common correction low-passed over ``ROOT_SMOOTH_S``. It plants
harder but steps the feet's velocity at the blends, changes the leg angles more and
leaves feet under the floor. ``bench/cleanup_natural.py`` measures both on the Bandai
walks (coverage, skating, jerk, penetration).
"""

from __future__ import annotations

import inspect

import numpy as np
import torch
from scipy.ndimage import gaussian_filter1d

from mrlib.errors import MotionValueError
from mrlib.representation.body import resolve_body
from mrlib.representation.motion import Motion
from mrlib.representation.rotations import axis_angle_to_matrix, matrix_to_axis_angle
from mrlib.representation.skeleton import NUM_JOINTS, PARENTS
from mrlib.threads import with_policy

__all__ = [
    "LEGS",
    "BLEND_S",
    "ROOT_SMOOTH_S",
    "SMOOTH_S",
    "contact_runs",
    "contact_floor",
    "smooth_foot_offsets",
    "plant_feet_smooth",
    "pin_corrections",
    "two_bone_ik",
    "foot_transform",
    "plant_feet",
    "cleanup_foot_contacts",
    "contact_skating",
]

# (hip, knee, ankle) joint ids and contact channels of each foot
LEGS: tuple[tuple[tuple[int, int, int], tuple[int, int, int]], ...] = (
    ((1, 4, 7), (0, 1, 2)),
    ((2, 5, 8), (3, 4, 5)),
)
_EPS = 1e-6
BLEND_S = 2 / 15  # seconds over which a planted foot eases in and out (4 frames at 30 fps)
ROOT_SMOOTH_S = 0.1  # Gaussian sigma (s) of the root's share of the correction


def contact_runs(c: np.ndarray) -> np.ndarray:
    """``c (T,)`` bool -> ``(R, 2)`` inclusive ``[start, stop]`` frames of its True runs."""
    c = np.asarray(c, bool)
    d = np.diff(np.concatenate([[False], c, [False]]).astype(np.int8))
    return np.stack([np.flatnonzero(d == 1), np.flatnonzero(d == -1) - 1], 1)


def pin_corrections(
    pos: np.ndarray, contact: np.ndarray, blend: int = 4, floor: float | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """How far a contact point must move to stay planted: ``((T, 3), (T,))``.

    In every contact run, and on the frame either side of it, the point is pinned to its
    mean position over the run (not below height ``floor`` when given); over the next
    ``blend`` frames the correction of that edge frame fades out with a smoothstep
    weight. Returns the corrections (weight included) and the weights.
    """
    pos = np.asarray(pos, np.float64)
    T = len(pos)
    runs = contact_runs(contact)
    if len(runs) == 0:
        return np.zeros_like(pos), np.zeros(T)
    idx = np.arange(T)
    run_of = np.full(T, -1)
    for r, (s, e) in enumerate(runs):  # runs, not frames
        run_of[s : e + 1] = r
    means = np.stack([pos[s : e + 1].mean(0) for s, e in runs])  # (R, 3)
    if floor is not None:
        means[:, 1] = np.maximum(means[:, 1], floor)
    inside = run_of >= 0
    # the nearest contact frame before and after every frame
    prev_c = np.maximum.accumulate(np.where(inside, idx, -1))
    next_c = np.minimum.accumulate(np.where(inside, idx, T)[::-1])[::-1]
    d_prev = np.where(prev_c >= 0, idx - prev_c, T + 1)
    d_next = np.where(next_c < T, next_c - idx, T + 1)
    before = d_prev <= d_next
    near = np.clip(np.where(before, prev_c, next_c), 0, T - 1)
    dist = np.minimum(d_prev, d_next)
    # The run and the frame either side of it sit on the run's mean (so the velocity of
    # the run's end frames, a central difference, is zero too); further out, the
    # correction of that edge frame fades with a smoothstep, so the foot eases into and
    # out of its planted position.
    edge = np.clip(np.where(dist <= 1, idx, np.where(before, near + 1, near - 1)), 0, T - 1)
    corr = means[run_of[near]] - pos[edge]
    x = np.clip(1.0 - (dist - 1) / (blend + 1.0), 0.0, 1.0) if blend > 0 else (dist <= 1) * 1.0
    w = x * x * (3 - 2 * x)
    return w[:, None] * corr, w


def _normalise(v: np.ndarray) -> np.ndarray:
    return v / np.maximum(np.linalg.norm(v, axis=-1, keepdims=True), _EPS)


def _axis_angle(axis: np.ndarray, angle: np.ndarray) -> np.ndarray:
    """Rotation matrices ``(..., 3, 3)`` about unit ``axis (..., 3)`` by ``angle (...)``."""
    x, y, z = axis[..., 0], axis[..., 1], axis[..., 2]
    c, s = np.cos(angle), np.sin(angle)
    C = 1 - c
    return np.stack(
        [
            np.stack([c + x * x * C, x * y * C - z * s, x * z * C + y * s], -1),
            np.stack([y * x * C + z * s, c + y * y * C, y * z * C - x * s], -1),
            np.stack([z * x * C - y * s, z * y * C + x * s, c + z * z * C], -1),
        ],
        -2,
    )


def _angle(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    cos = (_normalise(u) * _normalise(v)).sum(-1)
    return np.arccos(np.clip(cos, -1.0, 1.0))


def two_bone_ik(
    a: np.ndarray,
    b: np.ndarray,
    c: np.ndarray,
    t: np.ndarray,
    Ga: np.ndarray,
    Gb: np.ndarray,
    bend_axis: np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:
    """New global rotations of the upper and middle joint so the end joint reaches ``t``.

    Args:
        a, b, c: ``(T, 3)`` positions of hip, knee and ankle; t: ``(T, 3)`` targets.
        Ga, Gb: ``(T, 3, 3)`` global rotations of hip and knee.
        bend_axis: ``(T, 3)`` fallback bending axis where the leg is straight (no plane).
    Returns:
        ``(Ga', Gb')``.
    """
    lab = np.linalg.norm(b - a, axis=-1)
    lcb = np.linalg.norm(b - c, axis=-1)
    lat = np.clip(np.linalg.norm(t - a, axis=-1), np.abs(lab - lcb) + 1e-4, lab + lcb - 1e-4)
    # 1. bend: set the angles at hip and knee for the wanted hip-ankle distance
    ac_ab_0 = _angle(c - a, b - a)
    ba_bc_0 = _angle(a - b, c - b)
    ac_ab_1 = np.arccos(np.clip((lcb**2 - lab**2 - lat**2) / (-2 * lab * lat), -1, 1))
    ba_bc_1 = np.arccos(np.clip((lat**2 - lab**2 - lcb**2) / (-2 * lab * lcb), -1, 1))
    axis0 = np.cross(c - a, b - a)
    straight = np.linalg.norm(axis0, axis=-1) < 1e-8
    axis0 = _normalise(np.where(straight[:, None], bend_axis, axis0))
    Ra = _axis_angle(axis0, ac_ab_1 - ac_ab_0)
    Rb = _axis_angle(axis0, ba_bc_1 - ba_bc_0)
    # positions after the bend (the hip rotation turns the whole leg about a)
    b1 = a + (Ra @ (b - a)[..., None])[..., 0]
    c1 = b1 + (Ra @ Rb @ (c - b)[..., None])[..., 0]
    # 2. swing: turn the leg about the hip so the ankle points at the target
    axis1 = np.cross(c1 - a, t - a)
    tiny = np.linalg.norm(axis1, axis=-1) < 1e-10
    axis1 = _normalise(np.where(tiny[:, None], axis0, axis1))
    Rs = _axis_angle(axis1, np.where(tiny, 0.0, _angle(c1 - a, t - a)))
    Ga1 = Rs @ Ra @ Ga
    Gb1 = Rs @ Ra @ Rb @ Gb
    return Ga1, Gb1


def foot_transform(
    points: np.ndarray,
    targets: np.ndarray,
    weights: np.ndarray,
    prior: float = 1e-3,
    floor: float | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per frame, the rigid motion of a foot that brings its pinned points onto their
    targets: ``x -> R (x - c) + d``.

    ``c`` and ``d`` are the ``weights``-weighted centres of the points and of their
    targets, so the pinned points land on their targets' mean; ``R`` is the weighted
    Procrustes (Kabsch) rotation of the points about those centres. Points that are not
    pinned enter with weight ``prior`` and the target "where the translation takes them"
    (lifted to ``floor`` when that would put them below it): they keep the rotation near
    the identity and settle it where the pinned points leave it free (one point, or the
    turn about the line of two).

    Args:
        points, targets: ``(T, K, 3)``; weights: ``(T, K)`` in [0, 1].
    Returns:
        ``R (T, 3, 3)``, ``c (T, 3)``, ``d (T, 3)`` (``R = I``, ``c = d = 0`` on frames
        without a pinned point).
    """
    P, w = np.asarray(points, np.float64), np.asarray(weights, np.float64)
    sw = w.sum(1, keepdims=True)  # (T, 1)
    pinned = sw[:, 0] > 1e-9
    c = (w[..., None] * P).sum(1) / np.maximum(sw, 1e-12)
    d = (w[..., None] * np.asarray(targets)).sum(1) / np.maximum(sw, 1e-12)
    free = P + (d - c)[:, None]  # unpinned points follow the translation
    if floor is not None:
        free[..., 1] = np.maximum(free[..., 1], floor)
    Q = np.where(w[..., None] > 1e-9, targets, free)
    a = w + prior  # (T, K)
    ca = (a[..., None] * P).sum(1) / a.sum(1, keepdims=True)
    qa = (a[..., None] * Q).sum(1) / a.sum(1, keepdims=True)
    H = np.einsum("tk,tki,tkj->tij", a, P - ca[:, None], Q - qa[:, None])  # sum a p q^T
    U, _, Vt = np.linalg.svd(H)
    V, Ut = np.swapaxes(Vt, -1, -2), np.swapaxes(U, -1, -2)
    D = np.broadcast_to(np.eye(3), H.shape).copy()
    D[:, 2, 2] = np.where(np.linalg.det(V @ Ut) < 0, -1.0, 1.0)
    R = V @ D @ Ut  # (T, 3, 3): R (p - ca) ~ q - qa
    R = np.where(pinned[:, None, None], R, np.eye(3))
    return R, np.where(pinned[:, None], c, 0.0), np.where(pinned[:, None], d, 0.0)


def _global_rotations(R: np.ndarray) -> np.ndarray:
    G = np.empty_like(R)
    for j in range(NUM_JOINTS):  # joints, vectorised over frames
        p = PARENTS[j]
        G[:, j] = R[:, j] if p < 0 else G[:, p] @ R[:, j]
    return G


def plant_feet(
    R: np.ndarray,
    joints: np.ndarray,
    feet: np.ndarray,
    contacts: np.ndarray,
    blend: int = 4,
    *,
    rotate_foot: bool = True,
    move_root: bool = True,
    root_smooth: float = 0.0,
) -> tuple[np.ndarray, np.ndarray, dict[str, int]]:
    """Local rotations ``(T, 24, 3, 3)`` and a root offset ``(T, 3)`` that plant the
    contact vertices.

    1. Every contact vertex is pinned over each of its contact runs
       (:func:`pin_corrections`); per foot and frame, the rigid motion that keeps its
       pinned vertices on their targets (:func:`foot_transform`) gives the ankle's target
       and, with ``rotate_foot``, the foot's new orientation (else the foot keeps its
       angle and the ankle moves by the mean correction).
    2. With ``move_root`` the whole body first moves by the feet's corrections, weighted
       by how pinned each foot is: a single planted foot is then held by the root alone,
       which changes no joint angle.
    3. Two-bone leg IK takes each ankle the rest of the way.

    Args:
        R: ``(T, 24, 3, 3)`` local rotations (``R[:, 0]`` the global orientation).
        joints: ``(T, 24, 3)`` joint positions of ``R`` (from the body model).
        feet: ``(T, 6, 3)`` positions of the six contact vertices.
        contacts: ``(T, 6)`` contact labels (> 0.5 is contact).
        blend: frames over which a correction eases in before and out after a run.
        root_smooth: Gaussian sigma (frames) of the root offset; 0 leaves it raw.
    Returns:
        The new rotations, the root offset (add it to the translation), and
        ``{"runs": number of vertex contact runs planted}``.
    """
    R = np.asarray(R, np.float64)
    J = np.asarray(joints, np.float64)
    F = np.asarray(feet, np.float64)
    c = np.asarray(contacts) > 0.5
    T = len(R)
    shapes = (R.shape, J.shape, F.shape, c.shape)
    if shapes != ((T, NUM_JOINTS, 3, 3), (T, NUM_JOINTS, 3), (T, 6, 3), (T, 6)):
        raise MotionValueError(
            "plant_feet needs R (T, 24, 3, 3), joints (T, 24, 3), feet (T, 6, 3) and "
            f"contacts (T, 6), got {shapes}"
        )
    G = _global_rotations(R)
    out = R.copy()
    runs = 0
    # one floor for the clip: the median height of the vertices while in contact
    floor = float(np.median(F[..., 1][c])) if c.any() else None
    # 1. per foot: how pinned it is, its ankle target and orientation
    plans = []
    for (hip, knee, ankle), chans in LEGS:
        corr = np.zeros((T, len(chans), 3))
        weight = np.zeros((T, len(chans)))
        for k, v in enumerate(chans):
            runs += len(contact_runs(c[:, v]))
            corr[:, k], weight[:, k] = pin_corrections(F[:, v], c[:, v], blend, floor)
        pinned = weight.max(1)  # (T,)
        if rotate_foot:
            pts = F[:, chans]
            Rf, cf, df = foot_transform(pts, pts + corr, weight, floor=floor)
            target = (Rf @ (J[:, ankle] - cf)[..., None])[..., 0] + df
            foot_G = Rf @ G[:, ankle]
        else:
            w = weight.sum(1)
            target = J[:, ankle] + corr.sum(1) / np.maximum(w, 1.0)[:, None]
            foot_G = G[:, ankle]
        moved = pinned > 1e-9
        target = np.where(moved[:, None], target, J[:, ankle])
        plans.append((hip, knee, ankle, moved, pinned, target, foot_G))
    # 2. the root takes the feet's common correction
    offset = np.zeros((T, 3))
    if move_root:
        total = sum(p[4] for p in plans)  # (T,)
        moves = sum(p[4][:, None] * (p[5] - J[:, p[2]]) for p in plans)
        offset = moves / np.maximum(total, 1.0)[:, None]
        if root_smooth > 0:  # a smooth root; the legs take what the smoothing leaves
            offset = gaussian_filter1d(offset, root_smooth, axis=0, mode="nearest", truncate=3.0)
    # 3. leg IK for what is left
    for hip, knee, ankle, moved, _, target, foot_G in plans:
        if not moved.any():
            continue
        Ga, Gb = G[:, hip], G[:, knee]
        Ga1, Gb1 = two_bone_ik(
            J[:, hip], J[:, knee], J[:, ankle], target - offset, Ga, Gb, bend_axis=Gb[:, :, 0]
        )
        Ga1 = np.where(moved[:, None, None], Ga1, Ga)
        Gb1 = np.where(moved[:, None, None], Gb1, Gb)
        foot_G = np.where(moved[:, None, None], foot_G, G[:, ankle])
        Gp = G[:, PARENTS[hip]]
        out[:, hip] = np.swapaxes(Gp, -1, -2) @ Ga1
        out[:, knee] = np.swapaxes(Ga1, -1, -2) @ Gb1
        out[:, ankle] = np.swapaxes(Gb1, -1, -2) @ foot_G
    return out, offset, {"runs": int(runs)}


# -- smooth planting: one banded least-squares problem per axis ----------------------------
SMOOTH_S = 0.15  # s: time scale below which a correction may not bend (its jerk weight)
ROOT_HOLD_S = 0.5  # s: how far the root's correction may drift (its magnitude weight)
LEG_HOLD_S = 0.04  # s: the same for a leg's (ankle's) correction: the legs move last
LIFT_HOLD_S = 0.01  # s: the same for a leg's vertical correction (it bends the knee)
SLIDE = 0.1  # m/s: contact vertices still faster than this are pinned harder (reweighted)
PIN_WEIGHT = 200.0  # weight of the contact vertices' speed against the other terms
FLOOR_WEIGHT = 100.0  # 1/s^2: pull of a planted foot's lowest vertex onto the floor
STIFF = 2e5  # 1/s^2: the springs that hold the feet above the floor (a soft constraint)
FLOOR_SLACK = 3e-3  # m: how far below the floor (where planted feet rest) a vertex may go
FLOOR_MARGIN = 1e-3  # m: the floor the feet are kept above, above the estimated floor


def _central_diff(T: int):
    """``(T, T)`` sparse central difference (one-sided at the ends), per frame."""
    from scipy import sparse

    rows = np.arange(T)
    lo, hi = np.clip(rows - 1, 0, T - 1), np.clip(rows + 1, 0, T - 1)
    scale = 1.0 / np.maximum(hi - lo, 1)
    return sparse.csr_matrix(
        (np.concatenate([scale, -scale]), (np.concatenate([rows, rows]), np.concatenate([hi, lo]))),
        shape=(T, T),
    )


def _diff(T: int, n: int):
    """``(T - n, T)`` sparse ``n``-th forward difference (``np.diff(x, n)``)."""
    from scipy import sparse

    D = sparse.identity(T, format="csr")
    for _ in range(n):
        D = (D[1:] - D[:-1]).tocsr()
    return D


def _vertical(
    y: np.ndarray, c: np.ndarray, floor: float, J3, fps: float, *, root_hold_s: float,
    leg_hold_s: float, floor_weight: float, iterations: int, move_root: bool = True,
    slack: float = 0.0, stiffness: float = STIFF,
) -> tuple[np.ndarray, np.ndarray]:  # fmt: skip
    """Vertical offsets of the root ``(T,)`` and of each foot ``(2, T)``, the smoothest
    (least jerk, weighted by the joints each moves, and least size) that set each
    foot's lowest vertex labelled in contact on ``floor`` (springs of stiffness
    ``floor_weight`` on the frames with one) and keep every vertex of ``y (T, 6)`` above
    it (stiff springs on the frames that would be below, an active set grown over
    ``iterations`` solves). The root, cheap in size but dear in jerk (it moves all 24
    joints), takes the slow part; a leg, dear in size, the brief dips of its foot."""
    from scipy import sparse
    from scipy.sparse.linalg import spsolve

    T = len(y)
    dt = 1.0 / fps
    level = floor + FLOOR_MARGIN
    I = sparse.identity(T)
    rest_w, rest, need = [], [], []
    for f in range(2):
        yf, cf = y[:, 3 * f : 3 * f + 3], c[:, 3 * f : 3 * f + 3]
        touching = cf.any(1)
        rest_w.append(touching * (floor_weight * dt))
        rest.append(np.where(touching, level - np.where(cf, yf, np.inf).min(1), 0.0))
        need.append(level - slack - yf.min(1))  # the lift each frame needs
    active = [np.zeros(T, bool), np.zeros(T, bool)]
    for _ in range(max(1, iterations)):
        W = [rest_w[f] + active[f] * (stiffness * dt) for f in range(2)]
        tgt = [rest_w[f] * rest[f] + active[f] * (stiffness * dt) * need[f] for f in range(2)]
        ll = [sparse.diags(W[f]) + 3 * J3 + I * (dt / leg_hold_s**2) for f in range(2)]
        if move_root:
            rr = sparse.diags(W[0] + W[1]) + 24 * J3 + I * (dt / root_hold_s**2)
            A = sparse.bmat([[rr, sparse.diags(W[0]), sparse.diags(W[1])],
                             [sparse.diags(W[0]), ll[0], None],
                             [sparse.diags(W[1]), None, ll[1]]])  # fmt: skip
            x = spsolve(A.tocsc(), np.concatenate([tgt[0] + tgt[1], tgt[0], tgt[1]]))
            r, l0, l1 = x[:T], x[T : 2 * T], x[2 * T :]
        else:
            r = np.zeros(T)
            l0, l1 = (spsolve(ll[f].tocsc(), tgt[f]) for f in range(2))
        grew = False
        for f, lf in enumerate((l0, l1)):
            new = active[f] | (r + lf < need[f] - FLOOR_MARGIN / 2)
            grew |= bool((new != active[f]).any())
            active[f] = new
        if not grew:
            break
    return r, np.stack([l0, l1])


def smooth_foot_offsets(
    feet: np.ndarray,
    contacts: np.ndarray,
    fps: float,
    *,
    floor: float | None = None,
    smooth_s: float = SMOOTH_S,
    root_hold_s: float = ROOT_HOLD_S,
    leg_hold_s: float = LEG_HOLD_S,
    move_root: bool = True,
    pin_weight: float = PIN_WEIGHT,
    floor_weight: float = FLOOR_WEIGHT,
    floor_slack: float = FLOOR_SLACK,
    floor_stiffness: float = STIFF,
    lift_hold_s: float = LIFT_HOLD_S,
    slide: float = SLIDE,
    reweight: int = 0,
    iterations: int = 6,
) -> tuple[np.ndarray, np.ndarray]:
    """A root offset ``(T, 3)`` and one offset per foot ``(2, T, 3)`` that stop the feet
    while they are labelled in contact and keep them above ``floor``, as smooth as
    possible: the minimiser of a quadratic energy, a sparse banded system per axis.

    With ``r`` the root's offset and ``l_f`` foot ``f``'s (the leg's IK takes the ankle,
    and with it the rigid foot, by ``l_f``), contact vertex ``k`` of foot ``f`` moves to
    ``p_fk + r + l_f``. Horizontally (x and z) the energy, per second of motion, is

    * ``pin_weight * sum c_fk |v(p_fk + r + l_f)|^2``: the ground speed of every vertex
      while labelled in contact (``v`` the central difference the skating metric uses).
      It pins the feet without choosing where: the size terms put each planted foot
      where the least correction is, about its mean position over the run (GANimator's
      target);
    * ``smooth_s^4 (24 |j(r)|^2 + 3 sum_f |j(l_f)|^2)``: the jerk of the corrections,
      weighted by the joints each one moves (the root all 24, a leg about 3), so the
      corrections ease in and out over about ``smooth_s`` with no velocity step;
    * ``|r|^2 / root_hold_s^2 + sum_f |l_f|^2 / leg_hold_s^2``: the size of the
      corrections, the legs' dearer than the root's, so what can be held by moving the
      whole body (a single planted foot) changes no joint angle.

    Vertically only the floor counts: the root alone (the legs with ``move_root=False``)
    lifts the body, as smoothly as possible, wherever the lowest foot vertex would be
    below ``floor`` (:func:`_lift`). Lifting a foot by its leg bends the knee, and near
    full extension a millimetre of height is a large knee angle: the poses the coverage
    metric compares would change; the root changes none.

    This is the least-squares form of Kovar et al.'s footskate clean-up (SCA 2002: the
    root first, then the legs, corrections blended in and out) and of GANimator's
    contact IK (Li et al., SIGGRAPH 2022), with the blends replaced by a smoothness term
    over the whole clip as in spacetime motion editing (Gleicher, SIGGRAPH 1998; Lee and
    Shin, SIGGRAPH 1999).

    Args:
        feet: ``(T, 6, 3)`` contact vertex positions (``CONTACT_NAMES`` order).
        contacts: ``(T, 6)`` labels, > 0.5 is contact.
        fps: frames per second.
        move_root: False keeps the root where it is (the legs take everything).
    Returns:
        ``(root offset (T, 3), leg offsets (2, T, 3))``.
    """
    from scipy import sparse
    from scipy.sparse.linalg import splu

    F = np.asarray(feet, np.float64)
    c = np.asarray(contacts) > 0.5
    T = len(F)
    root, legs = np.zeros((T, 3)), np.zeros((2, T, 3))
    if T < 4:
        return root, legs
    dt = 1.0 / fps
    J3 = _diff(T, 3) * fps**3
    J3 = (J3.T @ J3) * (dt * smooth_s**4)
    if floor is not None:  # vertical: on the floor and never below it
        root[:, 1], legs[:, :, 1] = _vertical(
            F[..., 1], c, floor, J3, fps, root_hold_s=root_hold_s, leg_hold_s=lift_hold_s,
            floor_weight=floor_weight, iterations=iterations, move_root=move_root,
            slack=floor_slack, stiffness=floor_stiffness,
        )  # fmt: skip
    if not c.any():
        return root, legs
    D1 = _central_diff(T) * fps  # m/s
    I = sparse.identity(T, format="csr")
    P = F[..., [0, 2]]  # (T, 6, 2) ground positions
    weight = c * (dt * pin_weight)  # (T, 6)
    reweight = int(reweight)
    for it in range(max(1, reweight + 1)):
        # per vertex: weighted speed operator; per foot: their sum
        A_k = [D1.T @ sparse.diags(weight[:, k]) @ D1 for k in range(6)]
        M = [(A_k[3 * f] + A_k[3 * f + 1] + A_k[3 * f + 2]).tocsr() for f in range(2)]
        ll = [M[f] + 3 * J3 + I * (dt / leg_hold_s**2) for f in range(2)]
        if move_root:
            rr = M[0] + M[1] + 24 * J3 + I * (dt / root_hold_s**2)
            A = sparse.bmat([[rr, M[0], M[1]], [M[0], ll[0], None], [M[1], None, ll[1]]])
        else:
            A = sparse.block_diag(ll)
        # right-hand side: -sum_k D1^T C_k D1 p_k per foot, for x and z at once
        g = [sum(A_k[k] @ P[:, k] for k in range(3 * f, 3 * f + 3)) for f in range(2)]
        b = -(np.concatenate([g[0] + g[1], g[0], g[1]]) if move_root else np.concatenate(g))
        x = splu(A.tocsc()).solve(np.ascontiguousarray(b))
        if move_root:
            r_, l0, l1 = x[:T], x[T : 2 * T], x[2 * T :]
        else:
            r_, l0, l1 = np.zeros((T, 2)), x[:T], x[T:]
        if it == reweight:
            break
        # vertex-frames still sliding faster than `slide` m/s weigh (speed / slide)^2 more
        moved = P + np.repeat(np.stack([r_ + l0, r_ + l1], 1), 3, axis=1)
        speed = np.linalg.norm(np.stack([D1 @ moved[:, k] for k in range(6)], 1), axis=-1)
        fast = c & (speed > slide)
        if not fast.any():
            break
        weight = weight * np.where(fast, (speed / slide) ** 2, 1.0)
    root[:, [0, 2]] = r_
    legs[0][:, [0, 2]], legs[1][:, [0, 2]] = l0, l1
    return root, legs


def plant_feet_smooth(
    R: np.ndarray,
    joints: np.ndarray,
    feet: np.ndarray,
    contacts: np.ndarray,
    fps: float,
    *,
    floor: float | None = None,
    move_root: bool = True,
    **kw,
) -> tuple[np.ndarray, np.ndarray, dict[str, int]]:
    """:func:`plant_feet` with the corrections of :func:`smooth_foot_offsets`: the root
    moves by its offset and two-bone IK takes each ankle by its leg's offset, the foot
    keeping its global orientation (so its vertices move with the ankle)."""
    R = np.asarray(R, np.float64)
    J = np.asarray(joints, np.float64)
    F = np.asarray(feet, np.float64)
    c = np.asarray(contacts) > 0.5
    T = len(R)
    shapes = (R.shape, J.shape, F.shape, c.shape)
    if shapes != ((T, NUM_JOINTS, 3, 3), (T, NUM_JOINTS, 3), (T, 6, 3), (T, 6)):
        raise MotionValueError(
            "plant_feet_smooth needs R (T, 24, 3, 3), joints (T, 24, 3), feet (T, 6, 3) and "
            f"contacts (T, 6), got {shapes}"
        )
    offset, legs = smooth_foot_offsets(F, c, fps, floor=floor, move_root=move_root, **kw)
    G = _global_rotations(R)
    out = R.copy()
    for ((hip, knee, ankle), _), l in zip(LEGS, legs, strict=True):
        moved = np.linalg.norm(l, axis=-1) > 1e-7
        if not moved.any():
            continue
        Ga, Gb = G[:, hip], G[:, knee]
        Ga1, Gb1 = two_bone_ik(
            J[:, hip], J[:, knee], J[:, ankle], J[:, ankle] + l, Ga, Gb, bend_axis=Gb[:, :, 0]
        )
        Ga1 = np.where(moved[:, None, None], Ga1, Ga)
        Gb1 = np.where(moved[:, None, None], Gb1, Gb)
        Gp = G[:, PARENTS[hip]]
        out[:, hip] = np.swapaxes(Gp, -1, -2) @ Ga1
        out[:, knee] = np.swapaxes(Ga1, -1, -2) @ Gb1
        out[:, ankle] = np.swapaxes(Gb1, -1, -2) @ G[:, ankle]
    runs = sum(len(contact_runs(c[:, v])) for v in range(6))
    return out, offset, {"runs": int(runs)}


# -- clean-up of a Motion ------------------------------------------------------------------
LEG_JOINTS = (1, 2, 4, 5, 7, 8, 10, 11)  # hips, knees, ankles, feet


def contact_skating(motion: Motion, body=None) -> float:
    """Mean speed (m/s) of the contact vertices on frames labelled in contact (both the
    frame and its predecessor): 0 for perfectly planted feet."""
    body = resolve_body(body)
    if motion.contacts is None:
        raise MotionValueError("motion has no contact labels")
    with torch.no_grad():
        R, t, b = body.motion_inputs(motion)
        p = body.forward(R, t, b, vertex_ids=list(body.foot_vertex_ids)).vertices  # (T, 6, 3)
    v = (p[1:] - p[:-1]).norm(dim=-1) * motion.fps  # (T-1, 6)
    c = torch.as_tensor(motion.contacts > 0.5)
    both = c[1:] & c[:-1]
    return float(v[both].mean()) if both.any() else 0.0


def _cleanup_ik(
    motion: Motion, body, blend: int, passes: int = 2, move_root: bool = True,
    root_smooth: float = 0.0,
) -> Motion:  # fmt: skip
    if motion.contacts is None:
        raise MotionValueError("motion has no contact labels to clean up")
    body = resolve_body(body)
    R, trans, betas = body.motion_inputs(motion)
    ids = list(body.foot_vertex_ids)
    Rn, tn = R.double().cpu().numpy(), trans.double().cpu().numpy()
    on = dict(device=body.device, dtype=body.dtype)  # a body on an accelerator stays there
    for _ in range(passes):  # each pass re-poses the feet on the planted ones' means
        with torch.no_grad():
            out = body.forward(
                torch.from_numpy(Rn).to(**on), torch.from_numpy(tn).to(**on), betas, vertex_ids=ids
            )
        J, F = out.joints.double().cpu().numpy(), out.vertices.double().cpu().numpy()
        Rn, offset, info = plant_feet(
            Rn, J, F, motion.contacts, blend, move_root=move_root, root_smooth=root_smooth
        )
        tn = tn + offset
    poses = matrix_to_axis_angle(torch.from_numpy(Rn)).numpy().astype(np.float32)
    meta = dict(
        motion.meta,
        contact_cleanup={
            "method": "ik",
            "blend": blend,
            "move_root": move_root,
            "root_smooth": round(float(root_smooth), 3),
            **info,
        },  # fmt: skip
    )
    return motion.replace(poses=poses, trans=tn.astype(np.float32), meta=meta)


FLOOR_PERCENTILE = 50.0  # of the lowest contact vertex's height: the floor a clip stands on


def contact_floor(
    feet: np.ndarray | list[np.ndarray],
    contacts: np.ndarray | list[np.ndarray],
    percentile: float = FLOOR_PERCENTILE,
) -> float | None:
    """The height (m) planted feet rest at: a percentile (the median by default) of the
    lowest vertex labelled in contact, over the frames that have one, pooled over clips.
    ``feet (T, 6, 3)``, ``contacts (T, 6)`` (> 0.5 is contact), or lists of them. None
    when no vertex is ever in contact. On the Bandai walks it lies 0.4 to 0.5 cm above
    the evaluation's ground (the first percentile of all foot-vertex heights)."""
    feet = [feet] if not isinstance(feet, (list, tuple)) else list(feet)
    contacts = [contacts] if not isinstance(contacts, (list, tuple)) else list(contacts)
    lows = []
    for F, c in zip(feet, contacts, strict=True):
        c = np.asarray(c) > 0.5
        y = np.asarray(F, np.float64)[..., 1]
        lows.append(np.where(c, y, np.inf).min(1)[c.any(1)])
    low = np.concatenate(lows) if lows else np.zeros(0)
    return float(np.percentile(low, percentile)) if len(low) else None


def _cleanup_smooth(
    motion: Motion, body, *, move_root: bool, floor_clamp: bool, floor_percentile: float,
    floor: float | None = None, passes: int = 1, **kw,
) -> Motion:  # fmt: skip
    if motion.contacts is None:
        raise MotionValueError("motion has no contact labels to clean up")
    body = resolve_body(body)
    R, trans, betas = body.motion_inputs(motion)
    ids = list(body.foot_vertex_ids)
    Rn, tn = R.double().cpu().numpy(), trans.double().cpu().numpy()
    on = dict(device=body.device, dtype=body.dtype)
    c = np.asarray(motion.contacts) > 0.5
    floor = floor if floor_clamp else None
    for _ in range(passes):
        with torch.no_grad():
            out = body.forward(
                torch.from_numpy(Rn).to(**on), torch.from_numpy(tn).to(**on), betas, vertex_ids=ids
            )
        J, F = out.joints.double().cpu().numpy(), out.vertices.double().cpu().numpy()
        if floor is None and floor_clamp:
            floor = contact_floor(F, c, floor_percentile)
        Rn, offset, info = plant_feet_smooth(
            Rn, J, F, c, motion.fps, floor=floor, move_root=move_root, **kw
        )
        tn = tn + offset
    poses = matrix_to_axis_angle(torch.from_numpy(Rn)).numpy().astype(np.float32)
    meta = dict(
        motion.meta,
        contact_cleanup={"method": "ik", "style": "smooth", "move_root": move_root,
                         "floor": None if floor is None else round(floor, 4),
                         **{k: round(float(v), 3) for k, v in kw.items()}, **info},
    )  # fmt: skip
    return motion.replace(poses=poses, trans=tn.astype(np.float32), meta=meta)


@with_policy
def cleanup_foot_contacts(
    motion: Motion,
    body=None,
    iterations: int = 150,
    lr: float = 0.02,
    weight_reg: float = 1e-2,
    weight_smooth: float = 1.0,
    *,
    method: str = "ik",
    blend: int | None = None,
    move_root: bool = True,
    root_smooth_s: float = ROOT_SMOOTH_S,
    style: str = "smooth",
    floor: float | None = None,
    floor_clamp: bool = True,
    floor_percentile: float = FLOOR_PERCENTILE,
    **options,
) -> Motion:
    """Plant feet during predicted contacts (the paper's IK post-processing, Sec. 3.4).

    ``method="ik"`` (default), ``style="smooth"`` (default): the root and each leg's
    ankle move by the smooth offsets of :func:`smooth_foot_offsets` (one sparse
    least-squares solve per axis: contact vertices held still, the corrections of least
    jerk, the root before the legs; the body lifted onto the floor and never far below
    it), analytic two-bone leg IK taking each ankle by its offset. ``floor`` is the
    height (m) planted feet rest at, when known (``generate`` passes its training
    clips', ``mrlib.sampling.generation.training_floor``); None estimates it from the
    motion (``contact_floor`` at ``floor_percentile``); ``floor_clamp=False`` leaves
    heights alone. ``move_root=False`` keeps the root path (the legs take everything).
    Further keyword ``options`` go to :func:`smooth_foot_offsets` (``smooth_s``,
    ``pin_weight``, ``leg_hold_s``, ...). Milliseconds per clip.

    ``style="pin"``: the clean-up before (:func:`plant_feet`): every contact vertex is
    pinned to its mean position over each contact run, eased in and out over ``blend``
    frames (default ``BLEND_S`` seconds); the root takes the planted feet's common
    correction, low-passed over ``root_smooth_s`` seconds (``move_root``), and two-bone
    leg IK the rest, the foot turning as a rigid body so that all its planted vertices
    hold. It plants harder but steps the feet's velocity at the blends (jerk), changes
    the leg angles more (coverage) and leaves feet under the floor
    (``bench/cleanup_natural.py``).

    ``method="optimise"``: for every contact vertex and every run of frames labelled in
    contact, the target is the vertex's mean position over the run (as GANimator does);
    axis-angle offsets of the leg joints (hips, knees, ankles, feet) are then optimised
    with Adam (``iterations``, ``lr``) to reach the targets, with a small penalty on the
    offsets (``weight_reg``) and on their frame-to-frame change (``weight_smooth``).
    It leaves the root trajectory untouched.
    """
    if method not in ("ik", "optimise"):
        raise MotionValueError(f"method must be 'ik' or 'optimise', got {method!r}")
    if style not in ("smooth", "pin"):
        raise MotionValueError(f"style must be 'smooth' or 'pin', got {style!r}")
    known = set(inspect.signature(smooth_foot_offsets).parameters) - {
        "feet", "contacts", "fps", "floor", "move_root"
    }  # fmt: skip
    unknown = sorted(set(options) - known)
    if unknown or (options and (method, style) != ("ik", "smooth")):
        raise MotionValueError(
            f"unknown options {unknown or sorted(options)}: only method='ik', style='smooth' "
            f"takes more, namely {sorted(known)}"
        )
    if method == "ik" and style == "smooth":
        return _cleanup_smooth(
            motion, body, move_root=move_root, floor=floor, floor_clamp=floor_clamp,
            floor_percentile=floor_percentile, **options,
        )  # fmt: skip
    if method == "ik":
        frames = max(1, round(BLEND_S * motion.fps)) if blend is None else int(blend)
        return _cleanup_ik(
            motion, body, frames, move_root=move_root, root_smooth=root_smooth_s * motion.fps
        )
    if motion.contacts is None:
        raise MotionValueError("motion has no contact labels to clean up")
    body = resolve_body(body)
    ids = list(body.foot_vertex_ids)
    R, trans, betas = body.motion_inputs(motion)
    with torch.no_grad():
        p0 = body.forward(R, trans, betas, vertex_ids=ids).vertices  # (T, 6, 3)
    c = np.asarray(motion.contacts) > 0.5
    target = p0.clone()
    active = torch.zeros(c.shape, dtype=torch.bool, device=p0.device)
    for v in range(c.shape[1]):
        for s, e in contact_runs(c[:, v]).tolist():
            if e > s:
                target[s : e + 1, v] = p0[s : e + 1, v].mean(0)
                active[s : e + 1, v] = True
    if not active.any():
        return motion.replace()
    legs = list(LEG_JOINTS)
    delta = torch.zeros(len(p0), len(legs), 3, device=R.device, dtype=R.dtype, requires_grad=True)
    opt = torch.optim.Adam([delta], lr=lr)
    for _ in range(iterations):
        opt.zero_grad()
        Rn = R.clone()
        Rn[:, legs] = R[:, legs] @ axis_angle_to_matrix(delta)
        p = body.forward(Rn, trans, betas, vertex_ids=ids).vertices
        err = ((p - target) ** 2).sum(-1)[active].mean()
        loss = (
            err
            + weight_reg * delta.pow(2).mean()
            + weight_smooth * (delta[1:] - delta[:-1]).pow(2).mean()
        )
        loss.backward()
        opt.step()
    with torch.no_grad():
        Rn = R.clone()
        Rn[:, legs] = R[:, legs] @ axis_angle_to_matrix(delta)
        poses = matrix_to_axis_angle(Rn).cpu().numpy()
    meta = dict(motion.meta, contact_cleanup={"iterations": iterations})
    return motion.replace(poses=poses, meta=meta)
