"""The model's per-frame feature vector and its exact inverse.

Layout of one frame, ``C = 24*6 + 3 + 6 = 153`` channels (the paper's ``KQ + 3 + C``
with K=24 joints, Q=6; the paper's "219 features" does not follow from its own formula)::

    [  0:144)  6D rotation of each SMPL joint, joint-major (joint j at 6j:6j+6);
               joint 0 is the global orientation of the pelvis
    [144:147)  root displacement: ground-plane velocity vx (m/s), height y (m, SMPL's
               vertical translation), ground-plane velocity vz (m/s)
    [147:153)  foot contact labels in {0, 1}, order mrlib.representation.skeleton.CONTACT_NAMES

The root velocity is the finite difference of SMPL's translation times the frame rate,
``v[t] = (trans[t] - trans[t-1]) * fps`` for t >= 1 and ``v[0] = v[1]``. Storing a
velocity (as GANimator does) lets generated motion wander beyond the training path,
and storing it per second rather than per frame keeps the channel meaningful at every
level of the temporal pyramid (coarser levels simply have a lower frame rate).
Integration is exact: ``trans[t] = trans[0] + sum(v[1..t]) / fps``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch

from mrlib.errors import MotionValueError
from mrlib.representation.motion import Motion
from mrlib.representation.rotations import axis_angle_to_6d, sixd_to_axis_angle
from mrlib.representation.skeleton import CONTACT_NAMES, JOINT_NAMES, NUM_CONTACTS, NUM_JOINTS

__all__ = [
    "NUM_FEATURES",
    "ROT_SLICE",
    "ROOT_SLICE",
    "CONTACT_SLICE",
    "feature_layout",
    "channel_joint",
    "motion_to_features",
    "features_to_motion",
    "features_to_motions",
    "split_features",
    "root_velocity_to_trans",
    "FeatureNormalizer",
]

NUM_ROT = NUM_JOINTS * 6  # 144
ROT_SLICE = slice(0, NUM_ROT)
ROOT_SLICE = slice(NUM_ROT, NUM_ROT + 3)
CONTACT_SLICE = slice(NUM_ROT + 3, NUM_ROT + 3 + NUM_CONTACTS)
NUM_FEATURES = NUM_ROT + 3 + NUM_CONTACTS  # 153


def feature_layout() -> list[tuple[str, int, int]]:
    """``[(group name, start, stop), ...]`` describing every channel group."""
    rows = [(f"rot6d:{name}", 6 * j, 6 * j + 6) for j, name in enumerate(JOINT_NAMES)]
    rows += [("root:vx", 144, 145), ("root:y", 145, 146), ("root:vz", 146, 147)]
    rows += [(f"contact:{name}", 147 + i, 148 + i) for i, name in enumerate(CONTACT_NAMES)]
    return rows


def channel_joint() -> np.ndarray:
    """``(C,)`` int: the SMPL joint each channel belongs to (skeleton-aware convolutions
    attach root displacement to the pelvis and each contact channel to its foot joint)."""
    from mrlib.representation.skeleton import CONTACT_JOINTS

    owner = np.repeat(np.arange(NUM_JOINTS), 6)
    return np.concatenate([owner, np.zeros(3, np.int64), np.asarray(CONTACT_JOINTS)])


def motion_to_features(
    motion: Motion, body=None, *, contact_threshold: float | None = None
) -> torch.Tensor:
    """Motion -> ``(T, 153)`` float32 feature tensor (layout in the module docstring).

    Contact labels come from ``motion.contacts`` when present; otherwise they are
    computed from foot-vertex velocities on ``body`` (the default body when None) with
    ``mrlib.representation.contacts.foot_contacts``.
    """
    if not isinstance(motion, Motion):
        raise MotionValueError(
            f"motion_to_features expects a mrlib.Motion, got {type(motion).__name__}"
        )
    T = motion.num_frames
    if T < 2:
        raise MotionValueError(f"need at least 2 frames to compute root velocity, got {T}")
    rot = axis_angle_to_6d(torch.from_numpy(motion.poses).double()).reshape(T, NUM_ROT)  # (T, 144)
    trans = torch.from_numpy(motion.trans).double()
    vel = torch.empty(T, 2, dtype=torch.float64)
    vel[1:] = (trans[1:, [0, 2]] - trans[:-1, [0, 2]]) * motion.fps
    vel[0] = vel[1]
    root = torch.stack([vel[:, 0], trans[:, 1], vel[:, 1]], dim=-1)  # (T, 3)
    contacts = motion.contacts
    if contacts is None:
        from mrlib.representation.contacts import foot_contacts

        kw = {} if contact_threshold is None else {"threshold": contact_threshold}
        contacts = foot_contacts(motion, body, **kw)
    c = torch.as_tensor(np.asarray(contacts), dtype=torch.float64)
    return torch.cat([rot, root, c], dim=-1).float()


def split_features(x: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """``(..., T, 153)`` -> rot6d ``(..., T, 24, 6)``, root ``(..., T, 3)``, contacts ``(..., T, 6)``."""
    if x.shape[-1] != NUM_FEATURES:
        raise MotionValueError(
            f"features must have {NUM_FEATURES} channels, got shape {tuple(x.shape)}"
        )
    rot = x[..., ROT_SLICE].reshape(*x.shape[:-1], NUM_JOINTS, 6)
    return rot, x[..., ROOT_SLICE], x[..., CONTACT_SLICE]


def root_velocity_to_trans(
    root: torch.Tensor, fps: float, origin: torch.Tensor | None = None
) -> torch.Tensor:
    """Integrate root channels ``(..., T, 3)`` = (vx, y, vz) into translation ``(..., T, 3)``.

    Differentiable. ``origin`` ``(..., 2)`` is the ground-plane start (x0, z0), zero by
    default. ``v[0]`` is ignored (it is a copy of ``v[1]`` by construction).
    """
    v = root[..., [0, 2]] / fps
    steps = torch.cat([torch.zeros_like(v[..., :1, :]), v[..., 1:, :]], dim=-2)
    xz = torch.cumsum(steps, dim=-2)
    if origin is not None:
        xz = xz + origin.unsqueeze(-2)
    return torch.stack([xz[..., 0], root[..., 1], xz[..., 1]], dim=-1)


def features_to_motion(
    x: torch.Tensor | np.ndarray, fps: float, *, name: str | None = None, **options
) -> Motion:
    """``(T, 153)`` features -> ``Motion`` (the exact inverse of ``motion_to_features``).

    ``options``: those of :func:`features_to_motions` (``betas``, ``origin``,
    ``normalizer``, ``contact_cutoff``, ``label``). Rotations go through Gram-Schmidt, so
    any 6-vector gives a valid rotation; contacts are thresholded at ``contact_cutoff``;
    translation is integrated from ``origin`` (x0, z0). ``normalizer`` undoes
    normalisation first when given.
    """
    x = torch.as_tensor(np.asarray(x) if not isinstance(x, torch.Tensor) else x)
    if x.ndim != 2 or x.shape[-1] != NUM_FEATURES:
        raise MotionValueError(
            f"features must have shape (T, {NUM_FEATURES}), got {tuple(x.shape)}"
        )
    names = None if name is None else [name]
    return features_to_motions(x[None], fps, names=names, **options)[0]


def features_to_motions(
    x: torch.Tensor,
    fps: float,
    *,
    betas: np.ndarray | None = None,
    origin: tuple[float, float] | np.ndarray | None = None,
    normalizer: FeatureNormalizer | None = None,
    contact_cutoff: float = 0.5,
    label: str | None = None,
    names: list[str] | None = None,
) -> list[Motion]:
    """``(B, T, 153)`` features -> B Motions: :func:`features_to_motion` of every row,
    computed in one pass (each Motion is the same as converting its row alone)."""
    x = torch.as_tensor(x).detach().cpu()
    if x.ndim != 3 or x.shape[-1] != NUM_FEATURES:
        raise MotionValueError(
            f"features must have shape (B, T, {NUM_FEATURES}), got {tuple(x.shape)}"
        )
    if not torch.isfinite(x).all():
        raise MotionValueError("features contain NaN or inf values")
    if names is not None and len(names) != len(x):
        raise MotionValueError(f"{len(x)} clips but {len(names)} names")
    if normalizer is not None:
        x = normalizer.denormalize(x)
    x = x.double()
    rot, root, c = split_features(x)
    poses = sixd_to_axis_angle(rot).numpy()  # (B, T, 24, 3)
    o = None if origin is None else torch.as_tensor(np.asarray(origin, np.float64))
    trans = root_velocity_to_trans(root, fps, o).numpy()  # (B, T, 3)
    contacts = (c > contact_cutoff).float().numpy()
    kw = {} if betas is None else {"betas": betas}
    return [
        Motion(
            poses=poses[b],
            trans=trans[b],
            fps=fps,
            contacts=contacts[b],
            label=label,
            name=None if names is None else names[b],
            **kw,
        )
        for b in range(len(x))
    ]


@dataclass
class FeatureNormalizer:
    """Per-channel affine normalisation ``(x - mean) / std`` fitted on training features.

    By default only the root channels are normalised: 6D rotation entries already lie
    in [-1, 1], and contact labels must stay in {0, 1} for the contact loss (which reads
    them through a sigmoid). Statistics are plain tensors, saved with every checkpoint.
    """

    mean: torch.Tensor  # (C,)
    std: torch.Tensor  # (C,)

    @classmethod
    def fit(
        cls,
        features: list[torch.Tensor] | torch.Tensor,
        channels: slice | None = ROOT_SLICE,
        min_std: float = 1e-2,
    ) -> FeatureNormalizer:
        """Statistics over all frames of all clips; ``channels`` selects what is
        normalised (None: every channel); ``min_std`` floors near-constant channels."""
        xs = features if isinstance(features, (list, tuple)) else [features]
        allx = torch.cat([torch.as_tensor(f).reshape(-1, NUM_FEATURES) for f in xs]).double()
        mean = torch.zeros(NUM_FEATURES, dtype=torch.float64)
        std = torch.ones(NUM_FEATURES, dtype=torch.float64)
        sel = slice(None) if channels is None else channels
        mean[sel] = allx[:, sel].mean(0)
        std[sel] = allx[:, sel].std(0).clamp_min(min_std)
        return cls(mean.float(), std.float())

    @classmethod
    def identity(cls) -> FeatureNormalizer:
        return cls(torch.zeros(NUM_FEATURES), torch.ones(NUM_FEATURES))

    def normalize(self, x: torch.Tensor) -> torch.Tensor:
        return (x - self.mean.to(x)) / self.std.to(x)

    def denormalize(self, x: torch.Tensor) -> torch.Tensor:
        return x * self.std.to(x) + self.mean.to(x)

    def state_dict(self) -> dict[str, torch.Tensor]:
        return {"mean": self.mean.clone(), "std": self.std.clone()}

    @classmethod
    def from_state_dict(cls, d: dict[str, torch.Tensor]) -> FeatureNormalizer:
        return cls(torch.as_tensor(d["mean"]).float(), torch.as_tensor(d["std"]).float())
