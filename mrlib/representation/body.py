"""The SMPL body model, through ``smplx``, with a fast differentiable forward.

``load_body_model()`` returns a :class:`BodyModel`. Without arguments it uses the
embedded default body (``mrlib/assets/default_body.npz``: a MakeHuman-derived, CC0 mesh
rigged on SMPL's 24 joints, see ``mrlib/assets/README.md``), so everything in mrlib works
out of the box. With a real SMPL model file (``SMPL_NEUTRAL.pkl``, ...) — passed as a
path or through the environment variable ``MRLIB_SMPL_PATH`` — the same code runs on
SMPL. Both are built with ``smplx.SMPL(..., data_struct=...)``; real SMPL ``.pkl`` files
are read *without* chumpy, by a restricted unpickler that only accepts numpy arrays,
sparse matrices and chumpy arrays (turned into numpy) and refuses anything else.

``BodyModel.forward`` takes rotation matrices ``(..., 24, 3, 3)`` and skins only the
vertices asked for, so the training loss can follow the six foot vertices of a batch of
sequences cheaply; it matches ``smplx.SMPL.forward`` (tested).

Shapes use mrlib's letters: ``...`` any leading batch dims (e.g. ``(B, T)``),
J = 24 joints, V vertices, K selected vertices, NB = ``num_betas``. Units: metres.
"""

from __future__ import annotations

import contextlib
import functools
import io
import os
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import smplx
import torch

from mrlib.errors import (
    ArgumentError,
    BodyModelError,
    check_args,
    check_number,
    check_optional_path,
    check_text,
    shown,
)
from mrlib.representation.chain import rigid_transforms
from mrlib.representation.skeleton import JOINT_NAMES, NUM_JOINTS, SMPL_FOOT_VERTEX_IDS
from mrlib.representation.smpl_files import (
    OFFICIAL_NAMES,
    REQUIRED_KEYS,
    find_model_file,
    read_smpl_arrays,
    validate_smpl_arrays,
)

__all__ = [
    "BodyModel",
    "BodyOutput",
    "load_body_model",
    "resolve_body",
    "check_body",
    "fit_betas",
    "default_body_path",
    "SMPL_PATH_ENV",
]

SMPL_PATH_ENV = "MRLIB_SMPL_PATH"
SMPL_LICENSE = (
    "SMPL Model License (non-commercial scientific use; "
    "see https://smpl.is.tue.mpg.de/modellicense.html)"
)


def default_body_path() -> Path:
    """Path of the embedded default body (``mrlib/assets/default_body.npz``)."""
    return Path(__file__).resolve().parents[1] / "assets" / "default_body.npz"


def _text(arrays: dict[str, Any], key: str, default: str) -> str:
    v = arrays.get(key)
    return default if v is None else str(np.asarray(v).item() if np.ndim(v) == 0 else v)


# -- the model ----------------------------------------------------------------------------
@dataclass
class BodyOutput:
    """Result of :meth:`BodyModel.forward`.

    Attributes:
        joints: ``(..., 24, 3)`` posed, translated joint positions (metres).
        vertices: ``(..., K, 3)`` posed, translated vertices: all of them or the ones
            asked for; ``None`` when no vertices were asked for.
    """

    joints: torch.Tensor
    vertices: torch.Tensor | None = None


class BodyModel(torch.nn.Module):
    """SMPL (or the default body) with a forward on rotation matrices that skins only
    the vertices asked for.

    Attributes:
        name: ``"default"`` (the embedded body) or ``"smpl"``.
        smpl: the wrapped ``smplx.SMPL`` module (its buffers are the model).
        faces: ``(F, 3)`` int64 triangle indices.
        foot_vertex_ids: the 6 contact vertices, in ``mrlib.representation.skeleton.CONTACT_NAMES`` order.
        parents: ``(24,)`` parent of each joint (-1 for the root).
        joint_names: SMPL's 24 joint names.
        license, source: where the model comes from and its terms.
        path: the file it was read from.
    """

    def __init__(
        self,
        smpl: smplx.SMPL,
        *,
        name: str,
        foot_vertex_ids: Sequence[int],
        license: str,
        source: str = "",
        path: str | Path | None = None,
        beta_names: Sequence[str] | None = None,
    ) -> None:
        super().__init__()
        self.smpl = smpl
        self.name = name
        self.license = license
        self.source = source
        self.path = None if path is None else Path(path)
        self.faces = np.asarray(smpl.faces, dtype=np.int64)
        self.foot_vertex_ids = tuple(int(i) for i in foot_vertex_ids)
        self.parents = tuple(int(p) for p in smpl.parents.tolist())
        self.joint_names = JOINT_NAMES
        self.beta_names = tuple(beta_names) if beta_names is not None else None
        # Joints depend linearly on betas: J = J_template + J_shapedirs . betas.
        jr = smpl.J_regressor
        self.register_buffer("J_template", jr @ smpl.v_template, persistent=False)  # (J, 3)
        self.register_buffer(
            "J_shapedirs", torch.einsum("jv,vcl->jcl", jr, smpl.shapedirs), persistent=False
        )  # (J, 3, NB)
        # The default body has no pose correctives; skipping them saves a large matmul.
        self.has_pose_blendshapes = bool(smpl.posedirs.abs().max() > 0)

    # -- properties ---------------------------------------------------------------------
    @property
    def num_vertices(self) -> int:
        return int(self.smpl.v_template.shape[0])

    @property
    def num_betas(self) -> int:
        return int(self.smpl.num_betas)

    @property
    def device(self) -> torch.device:
        return self.smpl.v_template.device

    @property
    def dtype(self) -> torch.dtype:
        return self.smpl.v_template.dtype

    def extra_repr(self) -> str:
        return f"name={self.name!r}, vertices={self.num_vertices}, num_betas={self.num_betas}"

    # -- shape --------------------------------------------------------------------------
    def _betas(self, betas: Any, lead: tuple[int, ...] | None = None) -> torch.Tensor:
        """``betas`` as a float tensor ``(NB,)`` or ``(..., NB)``, zero-padded."""
        if betas is None:
            return torch.zeros(self.num_betas, device=self.device, dtype=self.dtype)
        b = torch.as_tensor(betas, device=self.device, dtype=self.dtype)
        if b.ndim == 0 or b.shape[-1] > self.num_betas:
            raise BodyModelError(
                f"betas must have shape (num_betas,) or (..., num_betas) with num_betas <= "
                f"{self.num_betas} for this {self.name} body, got {tuple(b.shape)}"
            )
        if b.shape[-1] < self.num_betas:
            b = torch.nn.functional.pad(b, (0, self.num_betas - b.shape[-1]))
        if lead is not None and b.ndim > 1:
            try:
                torch.broadcast_shapes(b.shape[:-1], lead)
            except RuntimeError:
                raise BodyModelError(
                    f"betas with batch shape {tuple(b.shape[:-1])} do not broadcast to the "
                    f"poses' batch shape {lead} (numpy rules, trailing dims first); for one "
                    "shape per sequence of (B, T) poses pass betas[:, None, :]"
                ) from None
        return b

    def rest_joints(self, betas: Any = None) -> torch.Tensor:
        """Rest-pose (T-pose) joint positions for shape ``betas``.

        Args:
            betas: ``(NB,)`` or ``(..., NB)``; None for the mean shape.
        Returns:
            ``(24, 3)`` or ``(..., 24, 3)`` tensor.
        """
        b = self._betas(betas)
        # J = J_template + sum_l b[..., l] J_shapedirs[j, c, l], as one matmul
        offs = b @ self.J_shapedirs.reshape(NUM_JOINTS * 3, -1).T  # (..., J*3)
        return self.J_template + offs.reshape(*b.shape[:-1], NUM_JOINTS, 3)

    def rest_vertices(self, betas: Any = None) -> torch.Tensor:
        """Rest-pose template ``(V, 3)`` (or ``(..., V, 3)``) for shape ``betas``."""
        b = self._betas(betas)
        offs = b @ self.smpl.shapedirs.reshape(-1, self.num_betas).T  # (..., V*3)
        return self.smpl.v_template + offs.reshape(*b.shape[:-1], -1, 3)

    # -- forward --------------------------------------------------------------------------
    def forward(
        self,
        rotmat: torch.Tensor,
        trans: torch.Tensor | None = None,
        betas: Any = None,
        vertex_ids: Sequence[int] | np.ndarray | torch.Tensor | str | None = None,
    ) -> BodyOutput:
        """Pose the body.

        Args:
            rotmat: ``(..., 24, 3, 3)`` local joint rotations; ``rotmat[..., 0, :, :]`` is
                the global orientation.
            trans: ``(..., 3)`` root translation (SMPL's ``transl``), or None.
            betas: ``(NB,)`` shared, or ``(..., NB)`` broadcastable to the poses' batch
                shape (one shape per sequence of ``(B, T)`` poses: ``(B, 1, NB)``); fewer
                than NB values are zero-padded; None = mean shape.
            vertex_ids: None (joints only), ``"all"``, or K vertex indices.
        Returns:
            :class:`BodyOutput` with ``joints (..., 24, 3)`` and ``vertices (..., K, 3)``.
        """
        if rotmat.ndim < 3 or tuple(rotmat.shape[-3:]) != (NUM_JOINTS, 3, 3):
            raise BodyModelError(
                f"rotmat must have shape (..., 24, 3, 3), got {tuple(rotmat.shape)}"
            )
        lead = tuple(rotmat.shape[:-3])
        N = int(np.prod(lead)) if lead else 1
        R = rotmat.to(self.dtype).reshape(N, NUM_JOINTS, 3, 3)
        b = self._betas(betas, lead)

        # 1. Rest joints for the shape: (N or 1, J, 3)
        if b.ndim == 1:
            J = self.rest_joints(b)[None]
            bN = b.expand(N, -1)
        else:
            bN = b.expand(*lead, b.shape[-1]).reshape(N, -1)
            J = self.rest_joints(bN)
        # 2. Forward kinematics: posed joints and the skinning transforms x -> G x + g
        joints, G, g = rigid_transforms(R, J, self.parents)  # (N, J, 3), (N, J, 3, 3), (N, J, 3)
        if trans is not None:
            t = torch.as_tensor(trans, device=self.device, dtype=self.dtype)
            if tuple(t.shape[-1:]) != (3,):
                raise BodyModelError(f"trans must have shape (..., 3), got {tuple(t.shape)}")
            t = t.expand(*lead, 3).reshape(N, 1, 3)
            joints = joints + t
        out_joints = joints.reshape(*lead, NUM_JOINTS, 3)
        if vertex_ids is None:
            return BodyOutput(joints=out_joints)

        # 3. Shaped template of the selected vertices: (N or 1, K, 3)
        smpl = self.smpl
        if isinstance(vertex_ids, str):
            if vertex_ids != "all":
                raise BodyModelError(
                    f"vertex_ids must be None, 'all' or indices, got {vertex_ids!r}"
                )
            ids = None
            v_t, dirs, W = smpl.v_template, smpl.shapedirs, smpl.lbs_weights
            posedirs = smpl.posedirs
        else:
            ids = torch.as_tensor(
                np.asarray(vertex_ids), device=self.device, dtype=torch.long
            ).reshape(-1)
            if len(ids) and (ids.min() < 0 or ids.max() >= self.num_vertices):
                raise BodyModelError(
                    f"vertex_ids must be in [0, {self.num_vertices}), got {ids.tolist()[:8]}..."
                )
            v_t, dirs, W = smpl.v_template[ids], smpl.shapedirs[ids], smpl.lbs_weights[ids]
            posedirs = None
        # v[n, k, c] = v_t[k, c] + sum_l b[n, l] dirs[k, c, l]  (matmuls: einsum is slow here)
        dirs = dirs.reshape(-1, dirs.shape[-1])  # (K*3, NB)
        if b.ndim == 1:
            v = (v_t + (dirs @ b).reshape(-1, 3))[None]  # (1, K, 3)
        else:
            v = v_t + (bN @ dirs.T).reshape(N, -1, 3)  # (N, K, 3)
        # 4. Pose blend shapes: (R_j - I) for the 23 non-root joints, against posedirs
        if self.has_pose_blendshapes:
            feat = (R[:, 1:] - torch.eye(3, dtype=self.dtype, device=self.device)).reshape(N, -1)
            if posedirs is None:  # posedirs is (207, V*3); take the selected columns
                cols = (ids[:, None] * 3 + torch.arange(3, device=self.device)).reshape(-1)
                posedirs = smpl.posedirs[:, cols]
            v = v + (feat @ posedirs).reshape(N, -1, 3)
        # 5. Linear blend skinning: v' = (sum_j W[k, j] G_j) v + sum_j W[k, j] g_j
        # (as single matrix products over the joints: a batched W @ G loops over N here)
        K = W.shape[0]
        Gk = (W @ G.transpose(0, 1).reshape(NUM_JOINTS, -1)).reshape(K, N, 3, 3).transpose(0, 1)
        gk = (W @ g.transpose(0, 1).reshape(NUM_JOINTS, -1)).reshape(K, N, 3).transpose(0, 1)
        verts = (Gk * v.unsqueeze(-2)).sum(-1) + gk  # (N, K, 3)
        if trans is not None:
            verts = verts + t
        return BodyOutput(joints=out_joints, vertices=verts.reshape(*lead, -1, 3))

    # -- conveniences on Motion -----------------------------------------------------------
    def motion_inputs(
        self, motion: Any, frames: Any = None
    ) -> tuple[torch.Tensor, torch.Tensor, np.ndarray]:
        """What :meth:`forward` takes for ``motion`` (a ``mrlib.Motion``) at ``frames``
        (default all): rotation matrices ``(T', 24, 3, 3)`` and translation ``(T', 3)`` on
        this body's device and dtype, and betas ``(num_betas,)`` float32 (:func:`fit_betas`:
        betas beyond this body's ``num_betas`` are dropped)."""
        from mrlib.representation.rotations import axis_angle_to_matrix

        poses = np.asarray(motion.poses, np.float32)
        trans = np.asarray(motion.trans, np.float32)
        if frames is not None:
            idx = np.asarray(frames, dtype=np.int64).reshape(-1)
            if len(idx) and (idx.min() < -len(poses) or idx.max() >= len(poses)):
                raise BodyModelError(f"frames {idx.tolist()} out of range for {len(poses)} frames")
            poses, trans = poses[idx], trans[idx]
        betas = fit_betas(motion.betas, self.num_betas)
        R = axis_angle_to_matrix(torch.from_numpy(poses).to(self.device, self.dtype))
        return R, torch.from_numpy(trans).to(self.device, self.dtype), betas

    @torch.no_grad()
    def motion_vertices(self, motion: Any, frames: Any = None) -> np.ndarray:
        """All vertices of ``motion`` (a ``mrlib.Motion``) at ``frames`` (default all):
        ``(T', V, 3)`` float32 numpy. Betas beyond ``num_betas`` are dropped."""
        R, t, b = self.motion_inputs(motion, frames)
        return self.forward(R, t, b, vertex_ids="all").vertices.cpu().numpy().astype(np.float32)

    @torch.no_grad()
    def motion_joints(self, motion: Any) -> np.ndarray:
        """Joint positions of ``motion``: ``(T, 24, 3)`` float32 numpy."""
        R, t, b = self.motion_inputs(motion)
        return self.forward(R, t, b).joints.cpu().numpy().astype(np.float32)


def fit_betas(betas: Any, num_betas: int, dtype: Any = np.float32) -> np.ndarray:
    """Shape coefficients ``betas`` (any length, or None) cut or zero-padded to
    ``(num_betas,)``: a motion's betas for a body with another number of them."""
    out = np.zeros(int(num_betas), dtype)
    if betas is not None:
        b = np.asarray(betas, dtype).reshape(-1)[: int(num_betas)]
        out[: len(b)] = b
    return out


# -- loading ------------------------------------------------------------------------------
def check_body(name: str, value: Any) -> BodyModel | None:
    """``value`` if it is None or a :class:`BodyModel`, else an ``ArgumentError`` (a
    file path: load it first with :func:`load_body_model`)."""
    if value is None or isinstance(value, BodyModel):
        return value
    hint = ""
    if isinstance(value, str) or hasattr(value, "__fspath__"):
        hint = f" (a file: body=mrlib.load_body_model({str(value)!r}))"
    raise ArgumentError(
        f"{name} must be a body model (mrlib.load_body_model()) or None{hint}, got {shown(value)}"
    )


def _check_device(name: str, value: Any) -> Any:
    if isinstance(value, (str, torch.device)):
        return value
    raise ArgumentError(
        f"{name} must be a device ('cpu', 'cuda', a torch.device), got {shown(value)}"
    )


def resolve_body(body: BodyModel | None = None, *, shared: bool = False) -> BodyModel:
    """``body``, or the default body model (:func:`load_body_model`) when None: every
    function of mrlib that takes an optional ``body`` falls back through here.

    ``shared=True`` returns one instance loaded once per process, for callers that only
    read it (file readers called in loops); a body that may be moved to another device
    or changed must be a fresh one (the default)."""
    if body is not None:
        return body
    return _shared_body() if shared else load_body_model()


@functools.lru_cache(maxsize=1)
def _shared_body() -> BodyModel:
    return load_body_model()


def _resolve(path: str | Path | None, gender: str) -> tuple[Path, bool]:
    """(model file, is the embedded default)."""
    if path is None:
        env = os.environ.get(SMPL_PATH_ENV)
        if env:
            path = env
        else:
            return default_body_path(), True
    p = Path(path).expanduser()
    if p.is_dir():
        p = find_model_file(p, gender)
    elif not p.exists():
        hint = f" (from ${SMPL_PATH_ENV})" if str(path) == os.environ.get(SMPL_PATH_ENV) else ""
        raise BodyModelError(
            f"{p}{hint}: no such file or folder; pass a SMPL .pkl/.npz file or a folder "
            f"with SMPL_{gender.upper()}.pkl, or unset {SMPL_PATH_ENV} to use the default body"
        )
    return p, p.resolve() == default_body_path()


@check_args(
    path=check_optional_path,
    gender=check_text,  # its value: a BodyModelError below, as for a missing file
    num_betas=lambda n, v: check_number(n, v, low=1, integer=True),
    device=_check_device,
)
def load_body_model(
    path: str | Path | None = None,
    *,
    gender: str = "neutral",
    num_betas: int = 10,
    device: str | torch.device = "cpu",
) -> BodyModel:
    """Load a body model.

    Resolution: ``path`` if given, else ``$MRLIB_SMPL_PATH``, else the embedded default
    body. A path may be an SMPL ``.pkl`` (e.g. ``SMPL_NEUTRAL.pkl``,
    ``basicModel_neutral_lbs_10_207_0_v1.0.0.pkl``), an ``.npz`` with the same keys, or
    a folder holding ``SMPL_{GENDER}.pkl``/``.npz`` (also in a ``smpl/`` subfolder).

    Args:
        gender: ``"neutral"``, ``"female"`` or ``"male"`` (picks the file in a folder).
        num_betas: shape coefficients to use (capped by what the model has).
        device: where the buffers live.
    Raises:
        BodyModelError: missing file, unreadable file, or not a 24-joint SMPL model.
    """
    gender = gender.lower()
    if gender not in OFFICIAL_NAMES:
        raise BodyModelError(f"gender must be 'neutral', 'female' or 'male', got {gender!r}")
    if not (isinstance(num_betas, int) and num_betas >= 1):
        raise BodyModelError(f"num_betas must be a positive int, got {num_betas!r}")
    file, is_default = _resolve(path, gender)
    arrays = validate_smpl_arrays(read_smpl_arrays(file), file)
    V = arrays["v_template"].shape[0]

    if "vertex_ids" in arrays:
        foot_ids = [int(i) for i in np.asarray(arrays["vertex_ids"]).reshape(-1)]
    elif V == 6890:
        foot_ids = list(SMPL_FOOT_VERTEX_IDS)
    else:
        raise BodyModelError(
            f"{file}: {V} vertices is not SMPL's 6890 and the file has no 'vertex_ids' "
            "(the 6 foot contact vertices); add them to the npz"
        )
    if len(foot_ids) != 6 or min(foot_ids) < 0 or max(foot_ids) >= V:
        raise BodyModelError(
            f"{file}: vertex_ids must be 6 vertex indices in [0, {V}), got {foot_ids}"
        )

    # smplx appends keypoints picked from SMPL-topology vertex ids (nose, ears, toes,
    # fingertips) to its joints; mrlib only uses the first 24, but the ids must exist on
    # this mesh. For other topologies point the face keypoints at the top-most vertex and
    # the foot keypoints at our contact vertices, and leave out the fingertips.
    kwargs: dict[str, Any] = {}
    if V != 6890:
        top = int(np.argmax(arrays["v_template"][:, 1]))
        vid = dict(zip(("nose", "reye", "leye", "rear", "lear"), [top] * 5, strict=True))
        vid.update(
            zip(
                ("LBigToe", "LSmallToe", "LHeel", "RBigToe", "RSmallToe", "RHeel"),
                foot_ids,
                strict=True,
            )
        )
        kwargs = dict(vertex_ids=vid, use_hands=False, use_feet_keypoints=True)
    struct = smplx.utils.Struct(**{k: arrays[k] for k in REQUIRED_KEYS})
    try:
        with contextlib.redirect_stdout(io.StringIO()):  # smplx prints a warning for 10 betas
            smpl = smplx.SMPL(
                str(file), data_struct=struct, num_betas=num_betas, gender=gender,
                create_betas=False, create_global_orient=False, create_body_pose=False,
                create_transl=False, **kwargs,
            )  # fmt: skip
    except Exception as e:
        raise BodyModelError(
            f"{file}: smplx could not build the model ({type(e).__name__}: {e})"
        ) from e

    beta_names = [str(s) for s in arrays["beta_names"]] if "beta_names" in arrays else None
    model = BodyModel(
        smpl,
        name="default" if is_default else "smpl",
        foot_vertex_ids=foot_ids,
        license=_text(arrays, "license", SMPL_LICENSE),
        source=_text(arrays, "source", str(file)),
        path=file,
        beta_names=beta_names,
    )
    return model.to(device)
