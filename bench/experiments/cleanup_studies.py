"""Reference code of the foot-contact clean-ups that ``mrlib.sampling.cleanup`` had
before its one method (``cleanup_foot_contacts``: the smooth solve), kept for the
benchmarks that measured them against it:

* :func:`cleanup_pinned`, ``style="pin"``, the default before 2026-12-05: each contact
  run pinned to its mean position and eased in and out (``bench/cleanup_natural.py``
  ``old``, ``bench/cleanup_quality.py``). It plants harder but steps the feet's velocity
  at the blends (jerk), changes the leg angles more (coverage) and leaves feet under the
  floor;
* :func:`cleanup_optimised`, ``method="optimise"``: the per-frame optimisation of the leg
  joints, as GANimator does it (``bench/sample_speed.py``, ``bench/time_to_quality.py
  --fix-contacts optimise``): about 50x slower than the analytic IK.

Their figures: ``docs/notes/2026-12-06-study-options.md``. Not maintained as claims: the
benchmarks import it (``from experiments.cleanup_studies import ...``, with ``bench/`` on
the path as when a benchmark runs).
"""

from __future__ import annotations

import numpy as np
import torch
from scipy.ndimage import gaussian_filter1d

from mrlib.errors import MotionValueError
from mrlib.representation.body import resolve_body
from mrlib.representation.motion import Motion
from mrlib.representation.rotations import axis_angle_to_matrix, matrix_to_axis_angle
from mrlib.representation.skeleton import PARENTS
from mrlib.sampling.leg_ik import LEGS, contact_runs, global_rotations, two_bone_ik

__all__ = ["cleanup_pinned", "cleanup_optimised", "plant_feet", "BLEND_S", "ROOT_SMOOTH_S"]

BLEND_S = 2 / 15  # seconds over which a planted foot eases in and out (4 frames at 30 fps)
ROOT_SMOOTH_S = 0.1  # Gaussian sigma (s) of the root's share of the correction
LEG_JOINTS = (1, 2, 4, 5, 7, 8, 10, 11)  # hips, knees, ankles, feet


def cleanup_pinned(
    motion: Motion, body=None, *, blend: int | None = None, move_root: bool = True,
    root_smooth_s: float = ROOT_SMOOTH_S,
) -> Motion:  # fmt: skip
    """The clean-up of ``cleanup_foot_contacts(..., style="pin")``, the default before
    2026-12-05: every contact vertex pinned to its mean position over each contact run,
    eased in and out over ``blend`` frames (default ``BLEND_S`` seconds); the root takes
    the planted feet's common correction, low-passed over ``root_smooth_s`` seconds
    (``move_root``), and two-bone leg IK the rest, the foot turning as a rigid body so
    that all its planted vertices hold (:func:`plant_feet`, two passes)."""
    blend = max(1, round(BLEND_S * motion.fps)) if blend is None else int(blend)
    root_smooth = root_smooth_s * motion.fps
    passes = 2
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


def cleanup_optimised(
    motion: Motion, body=None, iterations: int = 150, lr: float = 0.02,
    weight_reg: float = 1e-2, weight_smooth: float = 1.0,
) -> Motion:  # fmt: skip
    """The clean-up of ``cleanup_foot_contacts(..., method="optimise")``, as GANimator
    does it: for every contact vertex and every run of frames labelled in contact, the
    target is the vertex's mean position over the run; axis-angle offsets of the leg
    joints (hips, knees, ankles, feet) are then optimised with Adam (``iterations``,
    ``lr``) to reach the targets, with a small penalty on the offsets (``weight_reg``) and
    on their frame-to-frame change (``weight_smooth``). The root path is kept."""
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
    R, J, F = (np.asarray(a, np.float64) for a in (R, joints, feet))
    c = np.asarray(contacts) > 0.5
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
