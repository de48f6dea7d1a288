"""How the feet are planted, for the foot-contact clean-up (``mrlib.sampling.cleanup``,
whose docstring explains it): one banded least-squares solve per axis for a root offset
and an ankle offset per foot (:func:`smooth_foot_offsets`, its knobs
:class:`PlantOptions`), two-bone leg IK taking each ankle by its offset
(:func:`move_ankles`)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from mrlib.errors import MotionValueError
from mrlib.representation.skeleton import NUM_JOINTS, PARENTS
from mrlib.sampling.leg_ik import LEGS, global_rotations, two_bone_ik

__all__ = [
    "PlantOptions",
    "PLANT_DEFAULTS",
    "smooth_foot_offsets",
    "move_ankles",
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


def _leg_arrays(R, joints, legs):
    """:func:`move_ankles`'s inputs as float64 arrays, or a ``MotionValueError`` with the
    shapes it got."""
    R, J, L = (np.asarray(a, np.float64) for a in (R, joints, legs))
    T = len(R)
    shapes = (R.shape, J.shape, L.shape)
    if shapes != ((T, NUM_JOINTS, 3, 3), (T, NUM_JOINTS, 3), (2, T, 3)):
        raise MotionValueError(
            f"move_ankles needs R (T, 24, 3, 3), joints (T, 24, 3) and legs (2, T, 3), got {shapes}"
        )
    return R, J, L


# -- smooth planting: one banded least-squares problem per axis ----------------------------
SMOOTH_S = 0.15  # s: time scale below which a correction may not bend (its jerk weight)
ROOT_HOLD_S = 0.5  # s: how far the root's correction may drift (its magnitude weight)
LEG_HOLD_S = 0.04  # s: the same for a leg's (ankle's) correction: the legs move last
LIFT_HOLD_S = 0.01  # s: the same for a leg's vertical correction (it bends the knee)
SLIDE = 0.1  # m/s: contact vertices still faster than this are pinned harder (reweighted)
# Re-solves with the vertices still sliding faster than SLIDE pinned harder. One took the
# cleaned skating of the preview preset's samples from 4.8 / 5.9 % to 1.6 / 2.2 % on the
# Bandai walks at the same coverage, jerk and fidelity, and from 12.3 to 5.1 % on the
# synthetic demo clips, whose raw feet slide at 0.28 m/s. Three, chosen on the `demo`
# models of the development walks (the fast walks kept 6.5-8.3 % after one) and judged on
# bench/heldout.py's other two splits: a quarter of the skating of one re-solve, the same
# coverage, jerk and fidelity, ~10 ms more per sample (bench/cleanup_natural.py;
# docs/results.md, "The clean-up's re-solves").
REWEIGHT = 3
PIN_WEIGHT = 200.0  # weight of the contact vertices' speed against the other terms
FLOOR_WEIGHT = 100.0  # 1/s^2: pull of a planted foot's lowest vertex onto the floor
STIFF = 2e5  # 1/s^2: the springs that hold the feet above the floor (a soft constraint)
FLOOR_SLACK = 3e-3  # m: how far below the floor (where planted feet rest) a vertex may go
FLOOR_MARGIN = 1e-3  # m: the floor the feet are kept above, above the estimated floor


# the size weight of a held frame (PlantOptions.hold) over a free one's: its
# correction comes out a millionth of what it would be
HELD = 1e6


@dataclass(frozen=True)
class PlantOptions:
    """The knobs of :func:`smooth_foot_offsets`, today's defaults (the module constants;
    ``bench/cleanup_natural.py`` measures other values).

    Attributes:
        smooth_s: time scale (s) below which a correction may not bend (its jerk weight).
        root_hold_s, leg_hold_s: how far the root's and a leg's ground correction may
            drift (their size weights); ``lift_hold_s`` the same for a leg's vertical one.
        pin_weight: weight of the contact vertices' speed against the other terms.
        floor_weight: pull (1/s^2) of a planted foot's lowest vertex onto the floor.
        floor_slack: how far (m) below the floor a vertex may go; ``floor_stiffness``
            (1/s^2) the springs that hold it there.
        slide: contact vertices still faster (m/s) than this are pinned harder, over
            ``reweight`` re-solves (0: one solve).
        iterations: solves of the floor's active set at most.
        hold: the first ``hold`` frames keep no correction (their size terms weigh
            ``HELD`` times more): a given prefix that the rest continues from
            (``cleanup_foot_contacts`` returns those frames as they came).
    """

    smooth_s: float = SMOOTH_S
    root_hold_s: float = ROOT_HOLD_S
    leg_hold_s: float = LEG_HOLD_S
    lift_hold_s: float = LIFT_HOLD_S
    pin_weight: float = PIN_WEIGHT
    floor_weight: float = FLOOR_WEIGHT
    floor_slack: float = FLOOR_SLACK
    floor_stiffness: float = STIFF
    slide: float = SLIDE
    reweight: int = REWEIGHT
    iterations: int = 6
    hold: int = 0


PLANT_DEFAULTS = PlantOptions()


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


def _sizes(T: int, hold: int):
    """The size terms' ``(T, T)`` diagonal: 1 per frame, ``HELD`` on the first ``hold``."""
    from scipy import sparse

    w = np.ones(T)
    w[: max(0, min(int(hold), T))] = HELD
    return sparse.diags(w)


def _vertical(
    y: np.ndarray, c: np.ndarray, floor: float, J3, fps: float, o: PlantOptions,
    move_root: bool = True, hold: int = 0,
) -> tuple[np.ndarray, np.ndarray]:  # fmt: skip
    """Vertical offsets of the root ``(T,)`` and of each foot ``(2, T)``, the smoothest
    (least jerk, weighted by the joints each moves, and least size: ``o.root_hold_s``,
    ``o.lift_hold_s``) that set each foot's lowest vertex labelled in contact on
    ``floor`` (springs of stiffness ``o.floor_weight`` on the frames with one) and keep
    every vertex of ``y (T, 6)`` above it, less ``o.floor_slack`` (springs of
    ``o.floor_stiffness`` on the frames that would be below, an active set grown over
    ``o.iterations`` solves). The root, cheap in size but dear in jerk (it moves all 24
    joints), takes the slow part; a leg, dear in size, the brief dips of its foot."""
    from scipy import sparse
    from scipy.sparse.linalg import spsolve

    root_hold_s, leg_hold_s, floor_weight = o.root_hold_s, o.lift_hold_s, o.floor_weight
    slack, stiffness = o.floor_slack, o.floor_stiffness
    T = len(y)
    dt = 1.0 / fps
    level = floor + FLOOR_MARGIN
    I = _sizes(T, hold)
    rest_w, rest, need = [], [], []
    for f in range(2):
        yf, cf = y[:, 3 * f : 3 * f + 3], c[:, 3 * f : 3 * f + 3]
        touching = cf.any(1)
        rest_w.append(touching * (floor_weight * dt))
        rest.append(np.where(touching, level - np.where(cf, yf, np.inf).min(1), 0.0))
        need.append(level - slack - yf.min(1))  # the lift each frame needs
    active = [np.zeros(T, bool), np.zeros(T, bool)]
    for _ in range(max(1, o.iterations)):
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
    move_root: bool = True,
    ground_root: bool = True,
    options: PlantOptions = PLANT_DEFAULTS,
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
        ground_root: False keeps the root's ground position (x, z) where it is, the
            legs taking the ground corrections, while the root may still move
            vertically (with ``move_root``): the root's ground path is kept exactly.
        options: the energy's weights and the solves (:class:`PlantOptions`; ``reweight``:
            how many times to re-solve with the contact vertices still faster than
            ``slide`` weighted up, 0 solves once; ``hold``: frames kept as they are).
    Returns:
        ``(root offset (T, 3), leg offsets (2, T, 3))``.
    """
    from scipy import sparse
    from scipy.sparse.linalg import splu

    o = options
    smooth_s, root_hold_s, leg_hold_s = o.smooth_s, o.root_hold_s, o.leg_hold_s
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
        root[:, 1], legs[:, :, 1] = _vertical(F[..., 1], c, floor, J3, fps, o, move_root, o.hold)
    if not c.any():
        return root, legs
    move_root = move_root and ground_root  # from here on: the ground plane
    D1 = _central_diff(T) * fps  # m/s
    I = _sizes(T, o.hold).tocsr()
    P = F[..., [0, 2]]  # (T, 6, 2) ground positions
    weight = c * (dt * o.pin_weight)  # (T, 6)
    reweight, slide = int(o.reweight), o.slide
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


def move_ankles(R: np.ndarray, joints: np.ndarray, legs: np.ndarray) -> np.ndarray:
    """Local rotations ``R (T, 24, 3, 3)`` (``R[:, 0]`` the global orientation; ``joints
    (T, 24, 3)`` their positions) with two-bone IK taking each ankle by its leg's offset
    ``legs (2, T, 3)`` (:func:`smooth_foot_offsets`), the foot keeping its global
    orientation (so its vertices move with the ankle)."""
    R, J, legs = _leg_arrays(R, joints, legs)
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
    return out
