"""Writing motion as glTF 2.0 binary (``.glb``): the skinned body mesh with its animation,
for browser viewers, Blender (File > Import > glTF 2.0) and game engines.

The file holds one scene: SMPL's 24 joints as a node hierarchy named as in
``mrlib.representation.skeleton.JOINT_NAMES`` (rest translations ``J_k - J_parent`` for the motion's
``betas``, rotations identity at rest, so each node's animated rotation is exactly SMPL's
local rotation), the body's rest mesh for those betas skinned to them (SMPL's linear
blend skinning weights, the four largest per vertex, renormalised), and one animation
with a rotation channel per joint and a translation channel on ``pelvis``
(``J_pelvis + trans``). glTF's world is mrlib's: metres, Y up, facing +Z.

What glTF skinning cannot carry: SMPL's pose-dependent corrective blend shapes (the
mesh deforms by skinning alone, as in most game engines; the default body has none) and
the foot contact labels (they stay in the ``.npz``).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import roma
import torch

from mrlib.io.bodyfit import rest_joints_for
from mrlib.io.outputs import write_bytes
from mrlib.representation.body import fit_betas, resolve_body
from mrlib.representation.skeleton import JOINT_NAMES, NUM_JOINTS, PARENTS

__all__ = ["save_glb", "read_glb"]

INFLUENCES = 4  # joints per vertex in glTF's JOINTS_0 / WEIGHTS_0

_FLOAT, _UINT, _USHORT = 5126, 5125, 5123  # glTF componentType codes
_ARRAY_BUFFER, _ELEMENT_ARRAY_BUFFER = 34962, 34963


def _vertex_normals(v: np.ndarray, f: np.ndarray) -> np.ndarray:
    """``(V, 3)`` unit normals: area-weighted sum of the adjacent face normals."""
    fn = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])
    n = np.zeros_like(v)
    for k in range(3):
        np.add.at(n, f[:, k], fn)
    return n / np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-12)


def _top_weights(W: np.ndarray, k: int = INFLUENCES) -> tuple[np.ndarray, np.ndarray]:
    """The ``k`` largest skinning weights per vertex, renormalised: ``(V, k)`` joint
    indices and weights."""
    idx = np.argsort(-W, axis=1)[:, :k]
    w = np.take_along_axis(W, idx, axis=1)
    w = w / np.maximum(w.sum(1, keepdims=True), 1e-12)
    idx[w == 0] = 0  # unused slots point at the root with weight 0
    return idx.astype(np.uint16), w.astype(np.float32)


def save_glb(motion, path: str | Path, *, body=None, overwrite: bool = True) -> Path:
    """Write ``motion`` as a skinned, animated ``.glb`` (layout: module docstring).

    Args:
        motion: a ``mrlib.Motion``.
        path: the ``.glb`` to write.
        body: body model for the mesh, weights and rest joints (default: mrlib's).
        overwrite: replace an existing file (atomically; never through a symbolic
            link); False refuses it (``mrlib.io.outputs.OutputExistsError``).

    Returns:
        ``path``.
    """
    import pygltflib as g

    body = resolve_body(body, shared=True)
    J = rest_joints_for(body, motion.betas).astype(np.float64)  # (24, 3)
    with torch.no_grad():
        b = torch.as_tensor(fit_betas(motion.betas, body.num_betas)) if body.num_betas else None
        verts = body.rest_vertices(b).cpu().numpy().astype(np.float32)
    faces = body.faces.astype(np.uint32)
    weights = body.smpl.lbs_weights.detach().cpu().numpy()
    joints_i, weights_f = _top_weights(weights)
    normals = _vertex_normals(verts.astype(np.float64), body.faces).astype(np.float32)

    T = motion.num_frames
    times = (np.arange(T) / motion.fps).astype(np.float32)
    quats = roma.rotvec_to_unitquat(torch.as_tensor(motion.poses, dtype=torch.float64))
    quats = quats.numpy().astype(np.float32)  # (T, 24, 4) xyzw, glTF's order
    root_t = (J[0] + np.asarray(motion.trans, np.float64)).astype(np.float32)  # (T, 3)
    # inverse bind matrices: the rest pose has no rotation, so each is a translation by
    # -J_k, stored column-major
    ibm = np.tile(np.eye(4, dtype=np.float32), (NUM_JOINTS, 1, 1))
    ibm[:, :3, 3] = -J
    ibm = np.ascontiguousarray(ibm.transpose(0, 2, 1))

    blob = bytearray()
    views: list[g.BufferView] = []
    accessors: list[g.Accessor] = []

    def add(array: np.ndarray, kind: str, ctype: int, target: int | None = None, minmax=False):
        data = np.ascontiguousarray(array).tobytes()
        while len(blob) % 4:
            blob.append(0)
        views.append(
            g.BufferView(buffer=0, byteOffset=len(blob), byteLength=len(data), target=target)
        )
        blob.extend(data)
        flat = array.reshape(len(array), -1)
        acc = g.Accessor(
            bufferView=len(views) - 1, componentType=ctype, count=len(array), type=kind
        )
        if minmax:
            acc.min = flat.min(0).astype(float).tolist()
            acc.max = flat.max(0).astype(float).tolist()
        accessors.append(acc)
        return len(accessors) - 1

    a_pos = add(verts, g.VEC3, _FLOAT, _ARRAY_BUFFER, minmax=True)
    a_nrm = add(normals, g.VEC3, _FLOAT, _ARRAY_BUFFER)
    a_jnt = add(joints_i, g.VEC4, _USHORT, _ARRAY_BUFFER)
    a_wgt = add(weights_f, g.VEC4, _FLOAT, _ARRAY_BUFFER)
    a_idx = add(faces.reshape(-1), g.SCALAR, _UINT, _ELEMENT_ARRAY_BUFFER, minmax=True)
    a_ibm = add(ibm, g.MAT4, _FLOAT)
    a_time = add(times, g.SCALAR, _FLOAT, minmax=True)
    a_root = add(root_t, g.VEC3, _FLOAT)
    a_rot = [add(quats[:, j], g.VEC4, _FLOAT) for j in range(NUM_JOINTS)]

    children = {j: [c for c in range(NUM_JOINTS) if PARENTS[c] == j] for j in range(NUM_JOINTS)}
    nodes = []
    for j in range(NUM_JOINTS):
        t = J[j] if PARENTS[j] < 0 else J[j] - J[PARENTS[j]]
        nodes.append(
            g.Node(
                name=JOINT_NAMES[j],
                translation=[float(x) for x in t],
                rotation=[0.0, 0.0, 0.0, 1.0],
                children=children[j] or None,
            )
        )
    mesh_node = len(nodes)
    nodes.append(g.Node(name="body", mesh=0, skin=0))
    samplers = [g.AnimationSampler(input=a_time, output=a_root, interpolation="LINEAR")]
    channels = [
        g.AnimationChannel(sampler=0, target=g.AnimationChannelTarget(node=0, path="translation"))
    ]
    for j in range(NUM_JOINTS):
        samplers.append(g.AnimationSampler(input=a_time, output=a_rot[j], interpolation="LINEAR"))
        channels.append(
            g.AnimationChannel(
                sampler=len(samplers) - 1,
                target=g.AnimationChannelTarget(node=j, path="rotation"),
            )
        )
    prim = g.Primitive(
        attributes=g.Attributes(POSITION=a_pos, NORMAL=a_nrm, JOINTS_0=a_jnt, WEIGHTS_0=a_wgt),
        indices=a_idx,
    )
    gltf = g.GLTF2(
        asset=g.Asset(generator="mrlib", version="2.0"),
        scene=0,
        scenes=[g.Scene(name=motion.name or "motion", nodes=[0, mesh_node])],
        nodes=nodes,
        meshes=[g.Mesh(name="body", primitives=[prim])],
        skins=[
            g.Skin(
                name="smpl", joints=list(range(NUM_JOINTS)), inverseBindMatrices=a_ibm, skeleton=0
            )
        ],
        animations=[
            g.Animation(name=motion.name or "motion", samplers=samplers, channels=channels)
        ],
        accessors=accessors,
        bufferViews=views,
        buffers=[g.Buffer(byteLength=len(blob))],
        extras={
            "fps": float(motion.fps),
            "label": motion.label,
            "betas": [float(x) for x in np.asarray(motion.betas).ravel()],
        },
    )
    gltf.set_binary_blob(bytes(blob))
    # atomic, never through a symbolic link (pygltflib's save_binary opens the name)
    return write_bytes(path, b"".join(gltf.save_to_bytes()), overwrite=overwrite)


def read_glb(path: str | Path) -> dict:
    """Read back what :func:`save_glb` wrote, with nothing of mrlib's but the file.

    Returns:
        A dict: ``joint_names``, ``parents`` (index into the skin's joints, -1 for the
        root), ``rest_translation (J, 3)``, ``times (T,)``, ``rotation`` and
        ``translation`` (node name -> ``(T, 4)`` xyzw / ``(T, 3)`` keys), the mesh's
        ``vertices (V, 3)``, ``faces (F, 3)``, ``skin_joints (V, 4)``, ``skin_weights
        (V, 4)``, ``inverse_bind (J, 4, 4)`` (row-major) and the file's ``extras``.

    Used by the tests and handy to check a file before sending it on; it reads any
    ``.glb`` whose first mesh, skin and animation are laid out this way.
    """
    import pygltflib as g

    gltf = g.GLTF2().load_binary(str(path))
    blob = gltf.binary_blob()
    sizes = {g.SCALAR: 1, g.VEC3: 3, g.VEC4: 4, g.MAT4: 16}
    dtypes = {_FLOAT: np.float32, _UINT: np.uint32, _USHORT: np.uint16}

    def array(i: int) -> np.ndarray:
        acc = gltf.accessors[i]
        view = gltf.bufferViews[acc.bufferView]
        n = acc.count * sizes[acc.type]
        start = (view.byteOffset or 0) + (acc.byteOffset or 0)
        a = np.frombuffer(blob, dtypes[acc.componentType], n, start)
        return a.reshape(acc.count, -1) if sizes[acc.type] > 1 else a

    skin = gltf.skins[0]
    anim = gltf.animations[0]
    prim = gltf.meshes[0].primitives[0]
    joints = list(skin.joints)
    out = {
        "joint_names": [gltf.nodes[j].name for j in joints],
        "parents": [
            next((joints.index(p) for p in joints if j in (gltf.nodes[p].children or [])), -1)
            for j in joints
        ],
        "rest_translation": np.array([gltf.nodes[j].translation for j in joints]),
        "rotation": {},
        "translation": {},
        "vertices": array(prim.attributes.POSITION),
        "faces": array(prim.indices).reshape(-1, 3),
        "skin_joints": array(prim.attributes.JOINTS_0),
        "skin_weights": array(prim.attributes.WEIGHTS_0),
        "inverse_bind": array(skin.inverseBindMatrices).reshape(-1, 4, 4).transpose(0, 2, 1),
        "extras": gltf.extras or {},
    }
    times = None
    for ch in anim.channels:
        s = anim.samplers[ch.sampler]
        times = array(s.input)
        name = gltf.nodes[ch.target.node].name
        out[ch.target.path][name] = array(s.output)
    out["times"] = times
    return out
