"""How the feet are planted, for the foot-contact clean-up (``mrlib.sampling.cleanup``,
whose docstring explains both): ``style="smooth"``, one banded least-squares solve per
axis for a root offset and an ankle offset per foot (:func:`plant_feet_smooth`), and
``style="pin"``, every contact run pinned to its mean position and eased in and out
(:func:`plant_feet`)."""

from __future__ import annotations

import numpy as np
from scipy.ndimage import gaussian_filter1d

from mrlib.errors import MotionValueError
from mrlib.representation.skeleton import NUM_JOINTS, PARENTS
from mrlib.sampling.leg_ik import (
    LEGS,
    contact_runs,
    foot_transform,
    global_rotations,
    pin_corrections,
    two_bone_ik,
)

__all__ = [
    "plant_feet",
    "smooth_foot_offsets",
    "plant_feet_smooth",
    "SMOOTH_S",
    "ROOT_HOLD_S",
    "LEG_HOLD_S",
    "LIFT_HOLD_S",
    "SLIDE",
    "PIN_WEIGHT",
    "FLOOR_WEIGHT",
    "STIFF",
    "FLOOR_SLACK",
    "FLOOR_MARGIN",
]


def _leg_arrays(name: str, R, joints, feet, contacts):
    """The planting functions' inputs as float64 arrays and boolean contacts, or a
    ``MotionValueError`` naming ``name`` and the shapes it got."""
    R = np.asarray(R, np.float64)
    J = np.asarray(joints, np.float64)
    F = np.asarray(feet, np.float64)
    c = np.asarray(contacts) > 0.5
    T = len(R)
    shapes = (R.shape, J.shape, F.shape, c.shape)
    if shapes != ((T, NUM_JOINTS, 3, 3), (T, NUM_JOINTS, 3), (T, 6, 3), (T, 6)):
        raise MotionValueError(
            f"{name} needs R (T, 24, 3, 3), joints (T, 24, 3), feet (T, 6, 3) and "
            f"contacts (T, 6), got {shapes}"
        )
    return R, J, F, c


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
    R, J, F, c = _leg_arrays("plant_feet", R, joints, feet, contacts)
    T = len(R)
    G = global_rotations(R)
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
# Re-solves with the vertices still sliding faster than SLIDE pinned harder. One took the
# cleaned skating of the demo preset's samples from 4.8 / 5.9 % to 1.6 / 2.2 % on the
# Bandai walks at the same coverage, jerk and fidelity, and from 12.3 to 5.1 % on the
# synthetic demo clips, whose raw feet slide at 0.28 m/s (bench/cleanup_natural.py).
REWEIGHT = 1
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
    reweight: int = REWEIGHT,
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
        reweight: how many times to re-solve with the contact vertices still faster than
            ``slide`` weighted up (``REWEIGHT``; 0 solves once).
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
    R, J, F, c = _leg_arrays("plant_feet_smooth", R, joints, feet, contacts)
    offset, legs = smooth_foot_offsets(F, c, fps, floor=floor, move_root=move_root, **kw)
    G = global_rotations(R)
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
