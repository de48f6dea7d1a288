"""The body's side of retargeting: SMPL's rest joints as a linear function of the betas,
and the least-squares fit of betas, scale and pelvis offset to a source skeleton.

For fixed global rotations SMPL's joints are linear in its rest joints, which are linear
in the betas (``J(b) = J_0 + D b``): ``fit_shape_scale`` solves for betas, a uniform
scale of the source and a constant pelvis offset by bounded linear least squares
(``mrlib.io.retarget``, step 5), within the settings of a ``ShapeFit`` (what it starts
from, holds fixed and fits). Only the body model's public API is used
(``rest_joints``, or its ``J_template`` / ``J_shapedirs`` buffers when it has them).
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from functools import lru_cache

import numpy as np
import torch
from scipy.optimize import lsq_linear

from mrlib.representation.body import fit_betas as betas_of_length
from mrlib.representation.skeleton import NUM_JOINTS, PARENTS

__all__ = [
    "default_body",
    "joint_shape_basis",
    "rest_joints_for",
    "rest_pelvis",
    "smpl_forward_joints",
    "ShapeFit",
    "fit_shape_scale",
    "fit_smpl_offsets",
]


def default_body():
    """The default body model, loaded once per process (``resolve_body(shared=True)``);
    read it, do not move or change it."""
    from mrlib.representation.body import resolve_body

    return resolve_body(shared=True)


def _num_betas(body) -> int:
    for attr in ("num_betas", "n_betas"):
        n = getattr(body, attr, None)
        if isinstance(n, int):
            return n
    return 10


def _rest_joints(body, betas: np.ndarray | None) -> np.ndarray:
    b = None if betas is None else torch.as_tensor(np.asarray(betas, np.float32))
    J = body.rest_joints(b)
    return np.asarray(J.detach().cpu().numpy() if torch.is_tensor(J) else J, dtype=np.float64)


@lru_cache(maxsize=8)
def joint_shape_basis(body) -> tuple[np.ndarray, np.ndarray]:
    """``J_0 (24, 3)`` and ``D (24, 3, B)`` with ``rest_joints(b) = J_0 + D b``.

    Uses the body's ``J_template``/``J_shapedirs`` buffers when it has them, otherwise
    reads the basis off the public ``rest_joints`` (it is linear in betas)."""
    if hasattr(body, "J_template") and hasattr(body, "J_shapedirs"):
        J0 = body.J_template.detach().cpu().double().numpy()
        D = body.J_shapedirs.detach().cpu().double().numpy()
        return J0, D
    B = _num_betas(body)
    J0 = _rest_joints(body, np.zeros(B))
    D = np.stack([_rest_joints(body, np.eye(B)[i]) - J0 for i in range(B)], axis=-1)
    return J0, D


def rest_joints_for(body, betas: np.ndarray | None) -> np.ndarray:
    """``(24, 3)`` rest joints of ``body`` for ``betas`` (padded or cut to the body's)."""
    J0, D = joint_shape_basis(body)
    return J0 + D @ betas_of_length(betas, D.shape[-1], np.float64)


def rest_pelvis(body, betas: np.ndarray | None) -> np.ndarray:
    """``(3,)`` rest position of the pelvis for ``betas`` (padded/truncated to the body)."""
    return rest_joints_for(body, betas)[0]


def smpl_forward_joints(G: np.ndarray, J: np.ndarray, trans: np.ndarray) -> np.ndarray:
    """SMPL joint positions ``(T, 24, 3)`` from global rotations ``(T, 24, 3, 3)``, rest
    joints ``(24, 3)`` and translation ``(T, 3)`` (what SMPL's forward does to joints)."""
    pos = np.empty(G.shape[:2] + (3,))
    pos[:, 0] = J[0] + trans
    for k in range(1, NUM_JOINTS):
        p = PARENTS[k]
        pos[:, k] = pos[:, p] + G[:, p] @ (J[k] - J[p])
    return pos


@dataclass(frozen=True)
class ShapeFit:
    """What the fit of steps 3-5 starts from, holds fixed and fits
    (``mrlib.io.transfer.shape_fit`` makes it from ``retarget_bvh``'s options).

    Attributes:
        betas: ``(B,)`` the betas it starts from (or keeps, when not ``fit_betas``).
        fit_betas: whether the betas are fitted.
        offsets: ``(24, 3, 3)`` a fixed rest alignment, or None: solved.
        scale: a fixed scale of the source, or None: fitted.
        pelvis_offset: ``(3,)`` a fixed pelvis offset, or None: fitted.
        ridge, bound: the betas fit's ridge weight and bound on each beta.
    """

    betas: np.ndarray
    fit_betas: bool
    offsets: np.ndarray | None
    scale: float | None
    pelvis_offset: np.ndarray | None
    ridge: float
    bound: float

    def at_bound(self, b: np.ndarray) -> tuple[int, ...]:
        """The indices of the fitted betas ``b`` that reached the bound."""
        hit = self.fit_betas & (np.abs(b) >= self.bound * 0.999)
        return tuple(int(i) for i in np.flatnonzero(hit))

    def by_rotations(self, keep_betas: bool) -> ShapeFit:
        """These settings for a transfer by rotations: no betas fitted, SMPL's mean shape
        unless ``keep_betas`` (betas were given)."""
        b = self.betas if keep_betas else np.zeros(len(self.betas))
        return replace(self, betas=b, fit_betas=False)


def fit_shape_scale(
    G: np.ndarray,
    J0: np.ndarray,
    D: np.ndarray,
    Q: np.ndarray,
    src: np.ndarray,
    mapped: np.ndarray,
    fit: ShapeFit,
) -> tuple[np.ndarray, float, np.ndarray]:
    """Betas ``b``, scale ``s`` and pelvis offset ``delta`` minimising
    ``mean_{t,k} |x_k(t) + G_pelvis(t) delta - s Q_k(t)|^2 + ridge |b|^2``.

    For fixed global rotations ``G (T, 24, 3, 3)``, SMPL's pelvis-relative joints are
    linear in the rest joints and so in the betas:
    ``x_k(t) = sum_{c on the path to k} G_parent(c)(t) (J_c - J_parent(c))(b)``.
    ``Q (T, Js, 3)`` are the source joints relative to the hips, ``mapped`` the SMPL
    joints compared; ``delta`` (pelvis frame) moves SMPL's pelvis off the source hips.
    Bounded linear least squares (``|b_i| <= fit.bound``, ``s > 0``, ridge
    ``fit.ridge``). What ``fit`` holds fixed (``fit_betas=False``: its ``betas``;
    ``scale`` or ``pelvis_offset`` not None) stays as it is; its ``offsets`` play no
    part here.
    """
    b, fit_betas, scale, delta = fit.betas, fit.fit_betas, fit.scale, fit.pelvis_offset
    ridge, bound = fit.ridge, fit.bound
    T = len(G)
    B = D.shape[-1]
    par = np.array(PARENTS[1:])
    dJ0 = np.concatenate([np.zeros((1, 3)), J0[1:] - J0[par]])  # (24, 3) rest bone vectors
    dD = np.concatenate([np.zeros((1, 3, B)), D[1:] - D[par]])  # (24, 3, B)
    W = np.zeros((T, NUM_JOINTS, 3, B))  # d x_k / d b
    Y = np.zeros((T, NUM_JOINTS, 3))  # x_k at b = 0
    for k in range(1, NUM_JOINTS):
        p = PARENTS[k]
        W[:, k] = W[:, p] + G[:, p] @ dD[k]
        Y[:, k] = Y[:, p] + G[:, p] @ dJ0[k]
    ks = mapped  # the pelvis included: its residual is G_pelvis delta
    Qk = Q[:, src[ks]]  # (T, K, 3)
    G0 = np.broadcast_to(G[:, None, 0], (T, len(ks), 3, 3))
    # Columns [b | s | delta]; the fixed ones go to the right-hand side.
    cols, rhs = [], -Y[:, ks]
    if fit_betas:
        cols.append(W[:, ks])
    else:
        rhs = rhs - W[:, ks] @ b
    if scale is None:
        cols.append(-Qk[..., None])
    else:
        rhs = rhs + scale * Qk
    if delta is None:
        cols.append(G0)
    else:
        rhs = rhs - G0 @ delta
    nb = B if fit_betas else 0
    if not cols:
        return b, float(scale), np.asarray(delta, dtype=np.float64)
    A = np.concatenate(cols, axis=-1).reshape(T * len(ks) * 3, -1)
    y = rhs.reshape(-1)
    nx = A.shape[1]
    # Reduce to the (nx, nx) triangular system first: the bounded solver is then cheap.
    n = T * len(ks)  # residual vectors; the ridge is per mean squared error
    L = np.linalg.cholesky(A.T @ A + 1e-12 * np.eye(nx))  # A^T A = L L^T
    z = np.linalg.solve(L, A.T @ y)  # min |A x - y| <=> min |L^T x - z|
    A = np.concatenate([L.T, np.sqrt(ridge * n) * np.eye(nb, nx)])
    y = np.concatenate([z, np.zeros(nb)])
    lo = np.full(nx, -np.inf)
    hi = np.full(nx, np.inf)
    lo[:nb], hi[:nb] = -bound, bound
    if scale is None:
        lo[nb] = 1e-6
    x = lsq_linear(A, y, bounds=(lo, hi)).x
    b_out = x[:nb] if fit_betas else b
    s_out = float(x[nb]) if scale is None else float(scale)
    d_out = x[-3:] if delta is None else np.asarray(delta, dtype=np.float64)
    return b_out, s_out, d_out


def fit_smpl_offsets(sk, src, unit_m, J_tmpl, D, A) -> np.ndarray:
    """Betas whose rest joints reproduce an SMPL-named BVH's offsets (linear least squares)."""
    rows, rhs = [], []
    for j in range(1, NUM_JOINTS):
        p = PARENTS[j]
        rows.append(D[j] - D[p])
        rhs.append(A @ (unit_m * sk.offsets[src[j]]) - (J_tmpl[j] - J_tmpl[p]))
    Mx, y = np.concatenate(rows), np.concatenate(rhs)
    if Mx.size == 0 or not np.any(Mx):
        return np.zeros(D.shape[-1])
    return np.linalg.lstsq(Mx, y, rcond=None)[0]
