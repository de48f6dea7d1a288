"""Where a trained model's raw foot skating comes from.

For a label checkpoint (default: the `tutorial` model of ``bench/condition_control.py``)
prints the foot skating (share of contact vertex-frames whose feet move faster than
``SKATE_SPEED_THRESHOLD`` on the ground, and their mean speed) of:

1. every level of the training clips' pyramid beside the same level of their
   reconstructions (fixed z*, z*_i = 0 above level 1): which level the slide enters at;
2. the reconstructions with parts of the training clip swapped back in (its contact
   labels, its root path, its leg rotations): is it the labels, the path or the pose?
3. the reconstructions and random samples with their contact labels shifted by a few
   frames, and low-passed: a timing error or jitter would show there;
4. the mean rotation error of the leg joints in the reconstructions (degrees);
5. where random samples slide: inside the stance (labels shortened by two frames at both
   ends), along or across the walking direction, and with the noise of levels 2 to L
   switched off (only z_1 drawn, as in the reconstructions).

    python bench/experiments/skating_sources.py [--checkpoint ckpt.pt] [--samples 2] [--frames 400]
"""

from __future__ import annotations

import argparse
import copy
import dataclasses
import sys
from pathlib import Path

import numpy as np
import torch
from scipy.ndimage import binary_erosion, gaussian_filter1d

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # bench/: common.py

from common import add_checkpoint_arg, checkpoint_model

from mrlib.metrics.plausibility import foot_skating, motion_kinematics
from mrlib.model.pyramid import build_pyramid, level_fps
from mrlib.representation.features import features_to_motion
from mrlib.representation.rotations import (
    axis_angle_to_6d,
    axis_angle_to_matrix,
    sixd_to_axis_angle,
)
from mrlib.sampling.generation import generate, reconstruct
from mrlib.sampling.sampler import Sampler

LEGS = (1, 2, 4, 5, 7, 8, 10, 11)  # hips, knees, ankles, feet
LEGS_AND_PELVIS = (0, *LEGS)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    add_checkpoint_arg(ap)
    ap.add_argument("--samples", type=int, default=2, help="random samples per label [2]")
    ap.add_argument("--frames", type=int, default=400, help="frames per random sample [400]")
    a = ap.parse_args()
    model, body = checkpoint_model(ap, a.checkpoint)
    fps, L = model.fps, model.num_levels

    def skate(m) -> np.ndarray:
        _, feet = motion_kinematics(m, body)
        speed, share = foot_skating(feet, m.contacts, m.fps)
        return np.array([100 * share, speed])

    def row(name, values) -> None:
        v = np.mean(values, 0)
        print(f"| {name} | {v[0]:.1f} | {v[1]:.3f} |")

    train = [features_to_motion(x, fps, betas=model.betas) for x in model.features]
    recs = [reconstruct(model, k, levels=True) for k in range(len(train))]
    print(f"{a.checkpoint}: {len(train)} clips at {fps:g} fps, {L} levels\n")

    print("## 1. Per level: training pyramid and reconstructions\n")
    print("| level | fps | data % | data m/s | reconstruction % | reconstruction m/s |")
    print("|---|---:|---:|---:|---:|---:|")
    for i in range(L):
        d, r, f = [], [], 0.0
        for k, x in enumerate(model.features):
            lengths = model.lengths[k].tolist()
            f = level_fps(fps, lengths)[i]
            level = build_pyramid(x.T.float(), lengths)[i]
            d.append(skate(features_to_motion(level.T, f, betas=model.betas)))
            r.append(skate(recs[k][1][i]))
        d, r = np.mean(d, 0), np.mean(r, 0)
        print(f"| {i + 1} | {f:.1f} | {d[0]:.1f} | {d[1]:.3f} | {r[0]:.1f} | {r[1]:.3f} |")

    print("\n## 2. Reconstructions with parts of the training clip swapped in\n")
    print("| motion | skating % | contact-foot speed m/s |\n|---|---:|---:|")
    cases: dict[str, list] = {
        k: []
        for k in (
            "training clips",
            "reconstructions",
            "reconstructions, the clip's contact labels",
            "reconstructions, the clip's root path",
            "reconstructions, the clip's leg rotations",
            "reconstructions, the clip's leg and pelvis rotations",
        )
    }
    errors = []
    for t, (r, _) in zip(train, recs, strict=True):
        n = min(t.num_frames, r.num_frames)
        t = dataclasses.replace(t, poses=t.poses[:n], trans=t.trans[:n], contacts=t.contacts[:n])
        r = dataclasses.replace(r, poses=r.poses[:n], trans=r.trans[:n], contacts=r.contacts[:n])
        rc = dataclasses.replace(r, contacts=t.contacts)
        cases["training clips"].append(skate(t))
        cases["reconstructions"].append(skate(r))
        cases["reconstructions, the clip's contact labels"].append(skate(rc))
        path = t.trans - t.trans[0] + r.trans[0]
        cases["reconstructions, the clip's root path"].append(
            skate(dataclasses.replace(rc, trans=path))
        )
        for name, joints in (("leg", LEGS), ("leg and pelvis", LEGS_AND_PELVIS)):
            p = r.poses.copy()
            p[:, list(joints)] = t.poses[:, list(joints)]
            key = f"reconstructions, the clip's {name} rotations"
            cases[key].append(skate(dataclasses.replace(rc, poses=p)))
        Rt = axis_angle_to_matrix(torch.from_numpy(t.poses[:, list(LEGS)]))
        Rr = axis_angle_to_matrix(torch.from_numpy(r.poses[:, list(LEGS)]))
        cos = ((Rt.transpose(-1, -2) @ Rr).diagonal(dim1=-2, dim2=-1).sum(-1) - 1) / 2
        errors.append(np.degrees(np.arccos(cos.clamp(-1, 1).numpy())).mean(0))
    for name, v in cases.items():
        row(name, v)
    err = np.mean(errors, 0)
    print(
        "\nmean rotation error of the reconstructions' leg joints (degrees; hips, knees, "
        "ankles, feet; left, right): " + ", ".join(f"{e:.1f}" for e in err)
    )

    print("\n## 3. Timing and jitter\n")
    n = max(2, round(a.frames * fps / 30))
    raw = [
        generate(model, lab, length=n, seed=s, sampler=Sampler(fix_contacts=False))
        for lab in model.labels
        for s in range(a.samples)
    ]
    print(f"random samples: {len(raw)} of {n} frames, raw\n")
    print("| motion | labels shifted by (frames) | skating % |\n|---|---|---|")
    for name, ms in (("training clips", train), ("reconstructions", [r for r, _ in recs]),
                     ("random samples", raw)):  # fmt: skip
        shares = []
        for k in (-2, -1, 0, 1, 2):
            shares.append(np.mean([
                skate(dataclasses.replace(m, contacts=np.roll(m.contacts, k, axis=0)))[0]
                for m in ms
            ]))  # fmt: skip
        print(
            f"| {name} | -2 / -1 / 0 / +1 / +2 | " + " / ".join(f"{s:.1f}" for s in shares) + " |"
        )

    def low_pass(m):  # in the 6D form, which has no wrap-around
        six = axis_angle_to_6d(torch.from_numpy(m.poses)).numpy()
        six = torch.from_numpy(gaussian_filter1d(six, 1.0, axis=0))
        return dataclasses.replace(
            m, poses=sixd_to_axis_angle(six).numpy(), trans=gaussian_filter1d(m.trans, 1.0, axis=0)
        )

    print("\n| motion | skating % | low-passed (Gaussian, sigma 1 frame) % |\n|---|---:|---:|")
    for name, ms in (("training clips", train), ("random samples", raw)):
        smooth = [low_pass(m) for m in ms]
        print(
            f"| {name} | {np.mean([skate(m)[0] for m in ms]):.1f} | "
            f"{np.mean([skate(m)[0] for m in smooth]):.1f} |"
        )

    print("\n## 4. Where random samples slide\n")
    quiet = copy.copy(model)
    quiet.sigma = model.sigma.clone()
    quiet.sigma[:, 1:] = 0
    still = [
        generate(quiet, lab, length=n, seed=s, sampler=Sampler(fix_contacts=False))
        for lab in model.labels
        for s in range(a.samples)
    ]
    print("| motion | skating % | stance only % | contact-foot speed along / across the walk m/s |")
    print("|---|---:|---:|---|")
    for name, ms in (("training clips", train), ("random samples", raw),
                     ("random samples, noise of levels 2-L off", still)):  # fmt: skip
        share, inner, along, across = [], [], [], []
        for m in ms:
            c = np.asarray(m.contacts) > 0.5
            share.append(skate(m)[0])
            core = np.stack([binary_erosion(c[:, k], iterations=2) for k in range(c.shape[1])], 1)
            inner.append(skate(dataclasses.replace(m, contacts=core.astype(m.contacts.dtype)))[0])
            v = np.gradient(motion_kinematics(m, body)[1][..., [0, 2]], axis=0) * m.fps
            root = np.gradient(m.trans[:, [0, 2]], axis=0)
            d = root / (np.linalg.norm(root, axis=1, keepdims=True) + 1e-12)  # (T, 2)
            along.append((v * d[:, None]).sum(-1)[c])
            across.append(np.abs(v[..., 1] * d[:, None, 0] - v[..., 0] * d[:, None, 1])[c])
        print(
            f"| {name} | {np.mean(share):.1f} | {np.mean(inner):.1f} | "
            f"{np.concatenate(along).mean():+.3f} / {np.concatenate(across).mean():.3f} |"
        )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
