"""The motion's transfer onto SMPL, steps 3-6 and 8 of retargeting (``mrlib.io.retarget``).

``WorldSource`` is the source in mrlib's frame with what the fit reads of it. SMPL's
global rotations are the source's turned by the rest alignment ``C_j``
(``mrlib.io.rest_alignment``); an unmapped joint of the torso chain shares the turn
between its mapped neighbours, any other unmapped joint follows its parent
(``smpl_globals``, step 4). ``fit_rest_and_shape`` alternates the alignment and the body
fit of ``mrlib.io.bodyfit`` (betas, scale, pelvis offset) until the betas settle (steps
3, 5), within the settings ``shape_fit`` makes of the caller's ``RetargetOptions``. ``transfer_mode`` decides between positions
and rotations (step 8); by rotations ``root_by_leg_length`` scales the root. Last,
``smpl_motion`` and ``local_poses`` give SMPL's translation and axis-angle poses (step 6).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from mrlib.io.bodyfit import ShapeFit, fit_shape_scale, fit_smpl_offsets
from mrlib.io.bvh.hierarchy import BVHSkeleton
from mrlib.io.jointmap import SMPL_JOINT_MAP, JointMap
from mrlib.io.proportions import (
    LEG_NAMES,
    SourceBones,
    leg_length,
    reaches_source,
    source_leg_length,
)
from mrlib.io.rest_alignment import (
    hinge_axes,
    is_smpl_rest,
    rotation_sources,
    solve_offsets,
    source_directions,
)
from mrlib.representation.body import (
    fit_betas as betas_of_length,  # shape_fit has a fit_betas flag
)
from mrlib.representation.rotations import matrix_to_axis_angle_numpy
from mrlib.representation.skeleton import JOINT_NAMES, NUM_JOINTS, PARENTS

__all__ = [
    "RetargetOptions",
    "WorldSource",
    "world_source",
    "shape_fit",
    "smpl_globals",
    "transfer_mode",
    "fit_rest_and_shape",
    "root_by_leg_length",
    "smpl_motion",
    "local_poses",
]


@dataclass(frozen=True)
class WorldSource:
    """A source clip in mrlib's frame, as the transfer reads it (``world_source``).

    Attributes:
        src: ``(24,)`` source joint per SMPL joint (-1: unmapped).
        rot: ``(24,)`` the source joint whose rotation turns each SMPL joint.
        placed: the SMPL joints whose positions are compared with the source's.
        Rw: ``(T, Js, 3, 3)`` global rotations, source joint frame -> mrlib's world.
        Pw: ``(T, Js, 3)`` joint positions, metres, Y up.
        Q: ``(T, Js, 3)`` the joints relative to the source's hips, metres.
        sub: the frames the fit reads (it only sums over frames): at most 240.
        dirs: ``source_directions`` on those frames.
        hinges: ``hinge_axes`` on those frames (empty without the hinge twist).
    """

    src: np.ndarray
    rot: np.ndarray
    placed: np.ndarray
    Rw: np.ndarray
    Pw: np.ndarray
    Q: np.ndarray
    sub: np.ndarray
    dirs: dict
    hinges: dict


def world_source(
    src: np.ndarray,
    sk: BVHSkeleton,
    placed: np.ndarray,
    Rw: np.ndarray,
    Pw: np.ndarray,
    hinge_twist: bool,
) -> WorldSource:
    """The source ``sk`` mapped by ``src``, with global rotations ``Rw`` and positions
    ``Pw`` in mrlib's frame; ``hinge_twist``: read its knees' and elbows' hinge axes."""
    T = len(Pw)
    Q = Pw - Pw[:, src[:1]]  # (T, Js, 3) source joints relative to the hips, metres
    rot = rotation_sources(src, sk)
    # Offsets and shape are solved on at most 240 evenly spaced frames (sums over frames).
    sub = np.unique(np.linspace(0, T - 1, min(T, 240)).round().astype(np.int64))
    dirs = source_directions(src, Rw[sub], Pw[sub], rot)
    hinges = hinge_axes(src, rot, Rw[sub], Pw[sub]) if hinge_twist else {}
    return WorldSource(src, rot, placed, Rw, Pw, Q, sub, dirs, hinges)


@dataclass(frozen=True)
class RetargetOptions:
    """How ``mrlib.io.retarget.retarget_bvh`` fits SMPL to a source: what it fits, what it
    holds fixed and the fit's knobs, one value (the defaults are mrlib's). Pass
    ``options=RetargetOptions(transfer="positions")`` to ``retarget_bvh``,
    ``mrlib.io.load_bvh`` or ``calibrate_retarget`` (which returns the options that
    reuse its fit).

    Attributes:
        fit_betas: fit SMPL's shape to the source skeleton's proportions.
        betas: use these betas instead of fitting.
        offsets: ``(24, 3, 3)`` rest alignment from an earlier call on the same skeleton.
        scale: uniform scale applied to the source after unit conversion. ``"auto"``:
            1 when betas are fitted (the capture keeps its metric size, so speeds and
            strides stay true and the body's shape takes up the difference), fitted by
            least squares otherwise; ``"fit"``: always fitted; or a number.
        pelvis_offset: fit a constant offset ``delta`` (pelvis frame) between SMPL's
            pelvis and the source hips (skeletons disagree on where the pelvis joint
            is: CMU's root sits ~10 cm above its hip joints, SMPL's level with them);
            False pins SMPL's pelvis to the hips; or a fixed ``(3,)`` offset in metres.
        shape_ridge: ridge weight of the betas fit, per mean squared joint error in m^2
            (at 1e-5 one unit of beta costs as much as 3 mm of RMS joint error).
        shape_bound: bound on each fitted beta (keeps the body plausible).
        transfer: ``"positions"`` (fit SMPL's shape to the source's joints),
            ``"rotations"`` (transfer the motion by rotations onto SMPL's mean shape,
            the root scaled by leg length) or ``"auto"``: positions unless SMPL's shape
            space cannot reach the source's proportions (step 8).
        hinge_twist: set the twist of hips, knees, shoulders and elbows by the knee and
            elbow hinge axes (step 3); False keeps the closed form there too (mrlib's
            retargeting before 2026-12: the same joint positions, the limbs' local
            rotations twisted by the clip's average).
    """

    fit_betas: bool = True
    betas: np.ndarray | None = None
    offsets: np.ndarray | None = None
    scale: float | str = "auto"
    pelvis_offset: bool | np.ndarray = True
    shape_ridge: float = 1e-5
    shape_bound: float = 3.0
    transfer: str = "auto"
    hinge_twist: bool = True


def shape_fit(
    sk: BVHSkeleton,
    jmap: JointMap,
    src: np.ndarray,
    A: np.ndarray,
    unit_m: float,
    J_tmpl: np.ndarray,
    D: np.ndarray,
    options: RetargetOptions,
) -> ShapeFit:
    """The fit's settings from ``retarget_bvh``'s ``options`` for the skeleton ``sk``
    mapped by ``jmap`` (``src``), turned into mrlib's frame by ``A``.

    An SMPL-named skeleton whose rest pose is SMPL's T-pose (mrlib's own export) is read
    exactly: its offsets are SMPL's rest joints (betas solved from them), its local
    rotations are SMPL's (``C_j = A^T``, identity when Y up), its root is the pelvis.
    """
    betas, fit_betas, offsets = options.betas, options.fit_betas, options.offsets
    scale, pelvis_offset = options.scale, options.pelvis_offset
    B = D.shape[-1]
    smpl_named = jmap is SMPL_JOINT_MAP and is_smpl_rest(sk, src, A, J_tmpl)
    if betas is not None:
        b, fit_b = betas_of_length(betas, B, np.float64), False
    elif smpl_named and fit_betas:
        b, fit_b = fit_smpl_offsets(sk, src, unit_m, J_tmpl, D, A), False
    else:
        b, fit_b = np.zeros(B), fit_betas and bool(np.any(D))
    fixed_C = None
    if offsets is not None:
        fixed_C = np.asarray(offsets, dtype=np.float64).reshape(NUM_JOINTS, 3, 3)
    elif smpl_named:
        fixed_C = np.broadcast_to(A.T, (NUM_JOINTS, 3, 3))
    if scale == "auto":
        fixed_s = 1.0 if (fit_b or smpl_named) else None
    elif scale == "fit":
        fixed_s = None
    else:
        fixed_s = float(scale)
    if isinstance(pelvis_offset, bool):
        fixed_delta = None if (pelvis_offset and not smpl_named) else np.zeros(3)
    else:
        fixed_delta = np.asarray(pelvis_offset, dtype=np.float64).reshape(3)
    return ShapeFit(
        b, fit_b, fixed_C, fixed_s, fixed_delta, options.shape_ridge, options.shape_bound
    )


# SMPL's torso chain, pelvis to head: an unmapped joint on it takes a share of the turn
# between its mapped neighbours (a source spine with fewer joints than SMPL's)
_TORSO_CHAIN = tuple(
    JOINT_NAMES.index(n) for n in ("pelvis", "spine1", "spine2", "spine3", "neck", "head")
)


def _spread(Ga: np.ndarray, Gb: np.ndarray, n: int) -> list[np.ndarray]:
    """Global rotations of ``n`` joints between ``Ga`` and ``Gb`` ``(T, 3, 3)`` that share
    the turn ``Ga^T Gb`` evenly: ``Ga exp(k / (n + 1) log(Ga^T Gb))``, k = 1..n."""
    rel = matrix_to_axis_angle_numpy(np.swapaxes(Ga, -1, -2) @ Gb)  # (T, 3)
    angle = np.linalg.norm(rel, axis=-1, keepdims=True)
    axis = rel / np.maximum(angle, 1e-12)
    out = []
    for k in range(1, n + 1):
        th = angle[:, 0] * k / (n + 1)
        K = np.zeros(rel.shape[:-1] + (3, 3))
        K[:, 0, 1], K[:, 0, 2], K[:, 1, 2] = -axis[:, 2], axis[:, 1], -axis[:, 0]
        K = K - np.swapaxes(K, -1, -2)
        s, c = np.sin(th)[:, None, None], np.cos(th)[:, None, None]
        out.append(Ga @ (np.eye(3) + s * K + (1 - c) * K @ K))  # Rodrigues
    return out


def smpl_globals(
    C: np.ndarray,
    src: np.ndarray,
    Rw: np.ndarray,
    spread: bool = True,
    rot: np.ndarray | None = None,
) -> np.ndarray:
    """SMPL global rotations ``(T, 24, 3, 3)``: ``R'_rot(j) C_j`` where mapped (``rot``
    defaults to ``src``); an unmapped joint of the torso chain between two mapped ones
    shares the turn between them (``spread``), any other unmapped joint keeps its
    parent's (identity local rotation)."""
    rot = src if rot is None else rot
    T = len(Rw)
    G = np.empty((T, NUM_JOINTS, 3, 3))
    done = np.zeros(NUM_JOINTS, bool)
    for j in range(NUM_JOINTS):
        if src[j] >= 0:
            G[:, j] = Rw[:, rot[j]] @ C[j]
            done[j] = True
    if spread:
        chain = _TORSO_CHAIN
        k = 0
        while k < len(chain):
            if src[chain[k]] >= 0:
                k += 1
                continue
            first = k
            while k < len(chain) and src[chain[k]] < 0:
                k += 1
            if first == 0 or k == len(chain):
                continue  # no mapped joint on one side: identity below
            run = chain[first:k]
            for j, Gj in zip(
                run, _spread(G[:, chain[first - 1]], G[:, chain[k]], len(run)), strict=True
            ):
                G[:, j] = Gj
                done[j] = True
    for j in range(NUM_JOINTS):
        if not done[j]:
            G[:, j] = np.eye(3) if PARENTS[j] < 0 else G[:, PARENTS[j]]
    return G


def transfer_mode(
    transfer: str,
    source: WorldSource,
    bones: SourceBones,
    unit_m: float,
    J_tmpl: np.ndarray,
    D: np.ndarray,
    fit: ShapeFit,
) -> tuple[str, float]:
    """Step 8: ``"positions"`` or ``"rotations"`` for ``transfer`` (``"auto"``: by
    rotations when the betas would be fitted at scale 1 but SMPL's shape space cannot
    reach the source's size or proportions - decided on the source alone, so that a wrong
    map, whose fit fails, stays in positions and is reported), and the source's leg
    length (metres, unscaled)."""
    if transfer not in ("auto", "positions", "rotations"):
        raise ValueError(f"transfer must be 'auto', 'positions' or 'rotations', got {transfer!r}")
    leg_src = source_leg_length(source.Pw, source.src, bones, unit_m, J_tmpl)
    human = reaches_source(source.Pw, source.src, leg_src, J_tmpl, D, fit.bound)
    auto = transfer == "auto" and fit.fit_betas and fit.scale == 1.0 and not human
    return ("rotations" if transfer == "rotations" or auto else "positions"), leg_src


def fit_rest_and_shape(
    source: WorldSource, J_tmpl: np.ndarray, D: np.ndarray, fit: ShapeFit, mode: str
) -> tuple[np.ndarray, np.ndarray, float, np.ndarray]:
    """Steps 3 and 5: the rest alignment ``C (24, 3, 3)`` and, by positions, the betas,
    scale and pelvis offset that ``fit`` leaves free, alternating until the betas settle
    (the alignment depends on SMPL's rest bone directions; for fixed rotations SMPL's
    joints are linear in the betas, the scale and the offset).

    Returns:
        ``(betas (B,), C (24, 3, 3), scale, pelvis offset (3,))``.
    """
    s = source
    b, fit_b = fit.betas, fit.fit_betas
    fixed_C, fixed_s, fixed_delta = fit.offsets, fit.scale, fit.pelvis_offset
    s_fit, delta = (fixed_s or 1.0), (np.zeros(3) if fixed_delta is None else fixed_delta)
    # The hinge axes set the limbs' twist once the shape is known: a joint's position
    # does not depend on the twist of the bone above it, so the fit takes the closed form
    for _ in range(4 if fit_b else 1):
        J = J_tmpl + D @ b  # (24, 3) rest joints for these betas
        C_all = (
            fixed_C if fixed_C is not None else solve_offsets(J, s.src, s.Rw[s.sub], s.dirs, s.rot)
        )
        if mode == "rotations" or not (fit_b or fixed_s is None or fixed_delta is None):
            break
        G = smpl_globals(C_all, s.src, s.Rw[s.sub], rot=s.rot)
        b_new, s_fit, delta = fit_shape_scale(
            G, J_tmpl, D, s.Q[s.sub], s.src, s.placed, replace(fit, betas=b)
        )
        change = np.abs(b_new - b).max(initial=0.0)
        b = b_new
        if change < 1e-4:
            break
    J = J_tmpl + D @ b
    if fixed_C is None:
        C_all = solve_offsets(J, s.src, s.Rw[s.sub], s.dirs, s.rot, s.hinges)
    return b, C_all, s_fit, delta


def root_by_leg_length(
    source: WorldSource,
    J_tmpl: np.ndarray,
    D: np.ndarray,
    b: np.ndarray,
    C_all: np.ndarray,
    leg_src: float,
    fit: ShapeFit,
) -> tuple[float, np.ndarray]:
    """Step 8, by rotations: the root travels as the source's, scaled by leg length (the
    feet keep their contacts; ``b``: SMPL's betas, ``leg_src``: the source's leg length);
    SMPL's pelvis offset is fitted to the legs alone.

    Returns:
        ``(scale, pelvis offset (3,))``.
    """
    s = source
    J = J_tmpl + D @ b
    k = leg_length(J[None], None) / leg_src
    G_sub = smpl_globals(C_all, s.src, s.Rw[s.sub], rot=s.rot)
    legs = np.array([j for j in s.placed if j == 0 or JOINT_NAMES[j] in LEG_NAMES])
    held = replace(fit, betas=b, fit_betas=False, scale=k)  # the pelvis offset alone
    _, _, delta = fit_shape_scale(G_sub, J_tmpl, D, s.Q[s.sub], s.src, legs, held)
    return k, delta


def smpl_motion(
    source: WorldSource, J: np.ndarray, C_all: np.ndarray, scale: float, delta: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """SMPL's global rotations ``(T, 24, 3, 3)`` and translation ``(T, 3)`` (rest joints
    ``J``): the pelvis at the source's hips scaled by ``scale``, plus ``G_pelvis delta``."""
    G = smpl_globals(C_all, source.src, source.Rw, rot=source.rot)
    trans = scale * source.Pw[:, source.src[0]] + G[:, 0] @ delta - J[0]
    return G, trans


def local_poses(G: np.ndarray) -> np.ndarray:
    """Step 6: ``(T, 24, 3)`` axis-angle local rotations ``L_j = G_parent^T G_j`` of the
    global rotations ``G (T, 24, 3, 3)``."""
    L = G.copy()
    for j in range(1, NUM_JOINTS):
        L[:, j] = np.swapaxes(G[:, PARENTS[j]], -1, -2) @ G[:, j]
    return matrix_to_axis_angle_numpy(L)
