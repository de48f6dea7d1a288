"""The add-on's helper, run by mrlib's own Python in a child process, never inside Blender:
``python bridge.py COMMAND ...``. It imports mrlib (and with it torch where a command needs
it); Blender only reads what it writes.

Commands:

``onto-rig RIG.bvh MOTION.npz --out OUT.json [--bvh OUT.bvh] [--joint-map MAP]``
    Put a motion mrlib wrote (SMPL parameters: ``mrlib sample`` / ``mrlib restyle``'s
    ``.npz``) onto the rig of ``RIG.bvh``, a clip of that rig as Blender's BVH exporter
    writes it. mrlib reads a rig by a joint map and a rest alignment (``mrlib.io.retarget``:
    SMPL's global rotation of joint ``j`` is ``G_j = A R_src(j) C_j``, ``A`` the rig's
    up-axis turn, ``C_j`` a constant per joint); this inverts that reading with the very
    calibration mrlib fits to ``RIG.bvh`` when it reads it (so, for a clip the model was
    trained on, the one training used):

    * mapped bones: ``R_src(j) = A^T G_j C_j^T`` (their world rotations are exactly the ones
      that mrlib reads back as ``G_j``);
    * bones between a SMPL joint's position and its rotation (Character Creator's Hip
      above Pelvis, a neck or limb twist bone mrlib turns the joint with) turn with the
      rotation's bone, at the rotation relative to it they have on average in ``RIG.bvh``
      (the next mapped joints sit where mrlib's reading puts them only then);
    * bones no SMPL joint drives (fingers, twist and helper bones, a root above the hips)
      keep the rotation relative to their parent they have on average in ``RIG.bvh``
      (their rest one when it holds the rest pose), as mrlib's reading ignores them;
    * the root moves so that the hips are where mrlib's pelvis puts them:
      ``P_hips = A^T (trans + J_pelvis - G_pelvis delta) / (s unit)``, with ``J_pelvis``
      of the body mrlib fitted to the rig, its pelvis offset ``delta`` and scale ``s``.

    ``OUT.json`` holds each bone's rotation relative to its parent in the armature's axes
    (what Blender's BVH exporter writes) as quaternions and the root's positions;
    ``OUT.bvh`` (optional) is the same motion as a BVH of the rig.

``read RIG.bvh --out MOTION.npz [--joint-map MAP]``
    A clip of the rig as mrlib reads it (``mrlib.load_motion``), as SMPL parameters: what
    ``mrlib sample --continue`` continues.

``keyframes RIG.bvh CHECKPOINT --frames I,... --times S,... --out KF.npz [--joint-map MAP]``
    The poses (and the root) of frames ``I`` of a clip of the rig, as mrlib reads them, held
    ``S`` seconds into the motion to generate: a keyframe file of ``mrlib sample
    --keyframes``, its frames at the rate that command writes (the training clips', else
    the model's; two keys on one frame there: the later one is kept, with a warning).

``labels CHECKPOINT --out OUT.json``
    The model's labels, levels and frame rate (loading it needs torch).

Errors print one line, ``error: <problem>``, and exit 1, like mrlib's command line.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path

import numpy as np

RIG_MOTION_FORMAT = "mrlib-rig-motion"


def _aa_to_matrix(aa: np.ndarray) -> np.ndarray:
    """Rodrigues: ``(..., 3)`` axis-angle -> ``(..., 3, 3)``."""
    theta = np.linalg.norm(aa, axis=-1, keepdims=True)
    axis = aa / np.maximum(theta, 1e-12)
    x, y, z = axis[..., 0], axis[..., 1], axis[..., 2]
    zero = np.zeros_like(x)
    K = np.stack([zero, -z, y, z, zero, -x, -y, x, zero], -1).reshape(aa.shape[:-1] + (3, 3))
    s, c = np.sin(theta)[..., None], np.cos(theta)[..., None]
    return np.eye(3) + s * K + (1 - c) * (K @ K)


def _matrix_to_quat(R: np.ndarray) -> np.ndarray:
    """``(..., 3, 3)`` rotations -> ``(..., 4)`` unit quaternions (w, x, y, z), w >= 0."""
    m = R.reshape(-1, 3, 3)
    q = np.empty((len(m), 4))
    tr = np.trace(m, axis1=1, axis2=2)
    for i, (M, t) in enumerate(zip(m, tr, strict=True)):
        if t > 0:
            s = np.sqrt(t + 1.0) * 2
            q[i] = [0.25 * s, (M[2, 1] - M[1, 2]) / s, (M[0, 2] - M[2, 0]) / s, (M[1, 0] - M[0, 1]) / s]  # fmt: skip
        elif M[0, 0] > M[1, 1] and M[0, 0] > M[2, 2]:
            s = np.sqrt(1.0 + M[0, 0] - M[1, 1] - M[2, 2]) * 2
            q[i] = [(M[2, 1] - M[1, 2]) / s, 0.25 * s, (M[0, 1] + M[1, 0]) / s, (M[0, 2] + M[2, 0]) / s]  # fmt: skip
        elif M[1, 1] > M[2, 2]:
            s = np.sqrt(1.0 + M[1, 1] - M[0, 0] - M[2, 2]) * 2
            q[i] = [(M[0, 2] - M[2, 0]) / s, (M[0, 1] + M[1, 0]) / s, 0.25 * s, (M[1, 2] + M[2, 1]) / s]  # fmt: skip
        else:
            s = np.sqrt(1.0 + M[2, 2] - M[0, 0] - M[1, 1]) * 2
            q[i] = [(M[1, 0] - M[0, 1]) / s, (M[0, 2] + M[2, 0]) / s, (M[1, 2] + M[2, 1]) / s, 0.25 * s]  # fmt: skip
    q /= np.linalg.norm(q, axis=-1, keepdims=True)
    q *= np.where(q[:, :1] < 0, -1.0, 1.0)
    return q.reshape(R.shape[:-2] + (4,))


def _mean_relative(Ra: np.ndarray, Rb: np.ndarray) -> np.ndarray:
    """The rotation ``M`` closest to ``Ra^T Rb`` on average over frames (``(T, 3, 3)``
    each, or ``Ra`` one ``(3, 3)``): the projection of their mean onto the rotations."""
    m = (np.swapaxes(Ra, -1, -2) @ Rb).reshape(-1, 3, 3).mean(0)
    u, _, vt = np.linalg.svd(m)
    d = np.sign(np.linalg.det(u @ vt))
    return u @ np.diag([1.0, 1.0, d]) @ vt


def onto_rig(rig_bvh: str | Path, motion_path: str | Path, joint_map: str | None = None) -> dict:
    """The rig motion (see the module docstring) and the BVH of the rig, as
    ``{"json": dict, "bvh": mrlib.io.bvh.BVH}``."""
    from mrlib.io import load_motion
    from mrlib.io.axes import up_axis_rotation
    from mrlib.io.bodyfit import default_body, rest_joints_for
    from mrlib.io.bvh import BVH, read_bvh
    from mrlib.io.bvh.kinematics import bvh_forward_kinematics, forward_kinematics, matrix_to_euler
    from mrlib.io.jointmap import validate_map
    from mrlib.io.rest_alignment import rotation_sources
    from mrlib.io.retarget import retarget_bvh
    from mrlib.representation.skeleton import JOINT_NAMES, NUM_JOINTS, PARENTS

    bvh = read_bvh(rig_bvh)
    sk = bvh.skeleton
    # the calibration mrlib fits when it reads this clip (mrlib.io.load_bvh's defaults)
    r = retarget_bvh(bvh, joint_map, warn=False)
    motion = load_motion(motion_path)
    src = validate_map(r.joint_map, sk.names, sk.parents, bvh.source)
    rot = rotation_sources(src, sk)
    A = up_axis_rotation(r.up_axis)
    C = np.asarray(r.offsets, dtype=np.float64)
    T, Js = motion.num_frames, sk.num_joints

    # SMPL's global rotations of the motion
    L_smpl = _aa_to_matrix(np.asarray(motion.poses, dtype=np.float64).reshape(T, NUM_JOINTS, 3))
    G = np.empty_like(L_smpl)
    for j in range(NUM_JOINTS):
        G[:, j] = L_smpl[:, j] if PARENTS[j] < 0 else G[:, PARENTS[j]] @ L_smpl[:, j]

    # the rig's global rotations (file axes): mapped bones inverted; the others keep their
    # rotation relative to the bone they turn with that they have on average in RIG.bvh
    Rg = np.empty((T, Js, 3, 3))
    known = np.zeros(Js, bool)
    for j in range(NUM_JOINTS):
        if src[j] >= 0:
            Rg[:, rot[j]] = A.T @ G[:, j] @ C[j].T
            known[rot[j]] = True
    R_clip, _ = bvh_forward_kinematics(bvh)
    # a SMPL joint whose position and rotation come from different bones (Character
    # Creator's Hip above Pelvis, a neck twist bone): the bones from the one down to the
    # other turn with the rotation's bone, as mrlib's reading has it
    for j in range(NUM_JOINTS):
        way = [int(rot[j])] if src[j] >= 0 else []
        while way and way[-1] != src[j]:  # up from the rotation's bone to the position's
            way = way + [sk.parents[way[-1]]] if sk.parents[way[-1]] >= 0 else []
        for k in way[1:]:
            if not known[k]:
                Rg[:, k] = Rg[:, rot[j]] @ _mean_relative(R_clip[:, rot[j]], R_clip[:, k])
                known[k] = True
    for k in range(Js):  # parents precede children in a BVH
        if not known[k]:
            p = sk.parents[k]
            if p < 0:
                Rg[:, k] = _mean_relative(np.eye(3), R_clip[:, k])
            else:
                Rg[:, k] = Rg[:, p] @ _mean_relative(R_clip[:, p], R_clip[:, k])
    L = Rg.copy()
    for k in range(Js):
        p = sk.parents[k]
        if p >= 0:
            L[:, k] = np.swapaxes(Rg[:, p], -1, -2) @ Rg[:, k]

    # the hips where mrlib's pelvis puts them; the topmost joint above them with position
    # channels (the root) carries the translation
    # the rig's own body (the betas mrlib fitted to it), as in mrlib's reading
    J = rest_joints_for(default_body(), r.betas)
    delta = np.asarray(r.pelvis_offset, dtype=np.float64).reshape(3)
    hips_world = (np.asarray(motion.trans, np.float64) + J[0] - G[:, 0] @ delta) / r.scale
    hips_file = hips_world @ A / r.unit  # A^T x for each row
    hips = int(src[0])
    chain = [hips]
    while sk.parents[chain[-1]] >= 0:
        chain.append(sk.parents[chain[-1]])
    chain.reverse()  # root ... hips
    has_pos = [any(c.endswith("position") for c in sk.channels[k]) for k in range(Js)]
    mover = next((k for k in chain if has_pos[k]), None)
    if mover is None:
        raise ValueError(f"{rig_bvh}: no joint above the hips has position channels")
    trans = np.broadcast_to(np.asarray(sk.offsets, np.float64), (T, Js, 3)).copy()
    _, P0 = forward_kinematics(sk.parents, L, trans)
    shift = hips_file - P0[:, hips]  # world (file) displacement of the mover
    pm = sk.parents[mover]
    Rp = np.broadcast_to(np.eye(3), (T, 3, 3)) if pm < 0 else Rg[:, pm]
    trans[:, mover] += np.einsum("tba,tb->ta", Rp, shift)  # into the parent's frame
    _, P = forward_kinematics(sk.parents, L, trans)
    root_positions = P[:, mover]

    # the BVH of the rig: its channels, in their order
    values = []
    for k, chans in enumerate(sk.channels):
        order = "".join(c[0] for c in chans if c.endswith("rotation"))
        eul = matrix_to_euler(L[:, k], order) if order else np.zeros((T, 0))
        ri = 0
        for c in chans:
            if c.endswith("position"):
                values.append(trans[:, k, "XYZ".index(c[0])])
            else:
                values.append(eul[:, ri])
                ri += 1
    out_bvh = BVH(sk, np.stack(values, 1) if values else np.zeros((T, 0)), 1.0 / motion.fps)

    quats = _matrix_to_quat(L)  # (T, Js, 4)
    mapped = {JOINT_NAMES[j]: sk.names[int(src[j])] for j in range(NUM_JOINTS) if src[j] >= 0}
    data = {
        "format": RIG_MOTION_FORMAT,
        "version": 1,
        "fps": float(motion.fps),
        "frames": int(T),
        "bones": list(sk.names),
        "parents": [int(p) for p in sk.parents],
        "mover": sk.names[mover],
        "positions": np.round(root_positions, 7).tolist(),
        "rotations": {n: np.round(quats[:, k], 8).tolist() for k, n in enumerate(sk.names)},
        "mapped": mapped,
        "joint_map": r.joint_map.name,
        "up_axis": r.up_axis,
        "unit_m": float(r.unit),
        "scale": float(r.scale),
        "transfer": r.mode,
        "retarget_error_cm": float(r.error_mean_cm),
        "label": motion.label,
        "motion": str(motion_path),
        "rig": str(rig_bvh),
    }
    return {"json": data, "bvh": out_bvh}


def rig_axes(rig_bvh: str | Path, joint_map: str | None = None) -> dict:
    """``{"up_axis": ...}``: the up axis mrlib detects reading ``rig_bvh`` (the clip that
    calibrates the transfer), so that another clip of the same rig is read alike."""
    from mrlib.io.bvh import read_bvh
    from mrlib.io.retarget import retarget_bvh

    return {"up_axis": retarget_bvh(read_bvh(rig_bvh), joint_map, warn=False).up_axis}


def read_rig(rig_bvh: str | Path, out: str | Path, joint_map: str | None = None):
    from mrlib.io import load_motion, save_motion

    motion = load_motion(rig_bvh, joint_map=joint_map)
    save_motion(motion, out)
    return motion


def rig_keyframes(
    rig_bvh: str | Path,
    checkpoint: str | Path,
    frames: list[int],
    times: list[float],
    out: str | Path,
    joint_map: str | None = None,
) -> list:
    """The keyframes (``mrlib.sampling.constraints.Keyframe``) written to ``out``."""
    from mrlib import load_model
    from mrlib.io import load_motion
    from mrlib.sampling.constraints import Keyframe, save_keyframes

    if len(frames) != len(times) or not frames:
        raise ValueError(f"{len(frames)} frames and {len(times)} times: give one time per frame")
    motion = load_motion(rig_bvh, joint_map=joint_map)
    model = load_model(checkpoint)
    fps = float(model.source_fps or model.fps)  # the rate `mrlib sample` writes, its frames
    held: dict[int, object] = {}
    for i, t in zip(frames, times, strict=True):
        if not 0 <= i < motion.num_frames:
            raise ValueError(f"{rig_bvh}: frame {i} is outside its {motion.num_frames} frames")
        k = int(round(t * fps))
        if k in held:
            print(f"warning: two keys on the output's frame {k} ({fps:g} fps): the later one is held",
                  file=sys.stderr)  # fmt: skip
        held[k] = Keyframe.from_motion(motion, i, k)
    keys = [held[k] for k in sorted(held)]
    save_keyframes(out, keys)
    return keys


def checkpoint_labels(checkpoint: str | Path) -> dict:
    from mrlib import load_model

    model = load_model(checkpoint)
    return {
        "labels": list(model.labels),
        "num_levels": int(model.num_levels),
        "fps": float(model.config.fps) if getattr(model.config, "fps", None) else None,
    }


def _write_json(path: str | Path, data: dict) -> None:
    path = Path(path)
    tmp = path.with_name(path.name + ".part")
    tmp.write_text(json.dumps(data), encoding="utf-8")
    tmp.replace(path)


def _ints(text: str) -> list[int]:
    try:
        return [int(v) for v in text.split(",")]
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"not whole numbers separated by commas: {text!r}"
        ) from None


def _floats(text: str) -> list[float]:
    try:
        values = [float(v) for v in text.split(",")]
    except ValueError:
        values = []
    if not values or not all(math.isfinite(v) and v >= 0 for v in values):
        raise argparse.ArgumentTypeError(f"not seconds >= 0 separated by commas: {text!r}")
    return values


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="bridge.py", description=__doc__.split("\n\n")[0])
    sub = parser.add_subparsers(dest="command", required=True)
    p = sub.add_parser("onto-rig", help="a motion mrlib wrote, onto a rig")
    p.add_argument("rig")
    p.add_argument("motion")
    p.add_argument("--out", required=True)
    p.add_argument("--bvh")
    p.add_argument("--joint-map")
    p = sub.add_parser("read", help="a clip of a rig as SMPL parameters")
    p.add_argument("rig")
    p.add_argument("--out", required=True)
    p.add_argument("--joint-map")
    p = sub.add_parser("keyframes", help="poses of a clip of a rig as a keyframe file")
    p.add_argument("rig")
    p.add_argument("checkpoint")
    p.add_argument("--frames", required=True, type=_ints)
    p.add_argument("--times", required=True, type=_floats)
    p.add_argument("--out", required=True)
    p.add_argument("--joint-map")
    p = sub.add_parser("axes", help="the up axis mrlib reads a clip of a rig in")
    p.add_argument("rig")
    p.add_argument("--out", required=True)
    p.add_argument("--joint-map")
    p = sub.add_parser("labels", help="a checkpoint's labels and levels")
    p.add_argument("checkpoint")
    p.add_argument("--out", required=True)
    args = parser.parse_args(argv)
    try:
        if args.command == "onto-rig":
            res = onto_rig(args.rig, args.motion, args.joint_map)
            if args.bvh:
                from mrlib.io.bvh import write_bvh

                write_bvh(args.bvh, res["bvh"])
            _write_json(args.out, res["json"])
            d = res["json"]
            print(f"wrote {args.out}: {d['frames']} frames of {len(d['bones'])} bones ({len(d['mapped'])} mapped)")  # fmt: skip
        elif args.command == "read":
            m = read_rig(args.rig, args.out, args.joint_map)
            print(f"wrote {args.out}: {m.num_frames} frames at {m.fps:g} fps")
        elif args.command == "keyframes":
            keys = rig_keyframes(args.rig, args.checkpoint, args.frames, args.times, args.out,
                                 args.joint_map)  # fmt: skip
            print(f"wrote {args.out}: {len(keys)} keyframes")
        elif args.command == "axes":
            _write_json(args.out, rig_axes(args.rig, args.joint_map))
            print(f"wrote {args.out}")
        else:
            _write_json(args.out, checkpoint_labels(args.checkpoint))
            print(f"wrote {args.out}")
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return 130
    except Exception as e:  # one line, as mrlib's command line prints its errors
        try:
            from mrlib.app.cli.common import describe

            text = describe(e)
        except Exception:
            text = " ".join(str(e).split()) or type(e).__name__
        print(f"error: {text}", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
