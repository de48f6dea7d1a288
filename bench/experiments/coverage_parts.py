"""What the tight coverage (eps 1) of the label presets' models misses: rotations or contacts
(docs/notes/2026-12-06-heldout.md, "What eps 1 measures").

    python bench/experiments/coverage_parts.py --split heldout --seed 0 --preset preview
    python bench/experiments/coverage_parts.py --split heldout --seed 0    # the demo preset

Per label of a ``bench/heldout.py`` model (the same cache entry: trained there first when
missing), over ``--samples`` cleaned samples of twice the clip: coverage at eps 1 with
mrlib's metric features (23 local rotations in 6D + the 6 contact labels), the same with
the rotations only, and the share of contact labels that differ from the training clip's
where the rotations match best (each clip window against its nearest sample window by
rotations), and the condition fidelity with all features and with the rotations only (the
share of the samples' windows nearest the label's clip). Then, per clip, what the frame rate alone costs: the mean per-frame feature
distance between the clip sampled at the model's rate and the same clip sampled half a
frame later (both from the 30-fps capture, contact labels from the foot vertices), with
all features and with the rotations only. Last, how much the clip repeats itself: the
median over its windows of the distance to the nearest window of the same clip that starts
30 frames or more away (a walk's next step cycle; under 1, a window another part of the
clip covers at eps 1), and the coverage at eps 1 of the clip by the model's reconstruction
of it (``mrlib.reconstruct``: its fixed noise, no sampling).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # bench/: common.py

from common import describe, set_threads
from heldout import split_model

ROT = slice(0, 23 * 6)  # metric_features: rotations first, then the 6 contact labels


def half_frame_distance(clip, fps: float, body) -> tuple[float, float]:
    """Mean per-frame distance, all features and rotations only, between ``clip`` at
    ``fps`` and the same clip half a frame later."""
    from mrlib.metrics.windows import metric_features
    from mrlib.representation.contacts import foot_contacts

    hi = clip.resample(2 * fps).replace(contacts=None)
    n = len(hi) // 2
    a, b = (hi.replace(poses=hi.poses[k : 2 * n : 2], trans=hi.trans[k : 2 * n : 2], fps=fps)
            for k in (0, 1))  # fmt: skip
    fa, fb = (metric_features(m.replace(contacts=foot_contacts(m, body))) for m in (a, b))
    d = np.linalg.norm(fa - fb, axis=1).mean()
    return float(d), float(np.linalg.norm(fa[:, ROT] - fb[:, ROT], axis=1).mean())


def repeat_distance(x: np.ndarray, w: int) -> float:
    """Median over the ``w``-frame windows of ``x (T, D)`` of the mean per-frame distance
    to the nearest window of ``x`` starting ``w`` frames or more away (inf: none)."""
    n = len(x) - w + 1
    best = np.full(n, np.inf)
    box = np.ones(w) / w
    for off in range(w, n):
        per_frame = np.linalg.norm(x[off:] - x[: len(x) - off], axis=1)
        win = np.convolve(per_frame, box, mode="valid")  # windows starting at i and i + off
        best[: n - off] = np.minimum(best[: n - off], win)
        best[off:] = np.minimum(best[off:], win)
    return float(np.median(best))


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--split", choices=["heldout", "fresh", "dev"], default="heldout")
    p.add_argument("--seed", type=int, default=0, help="training seed [0]")
    p.add_argument("--preset", choices=["demo", "preview"], default="demo")
    p.add_argument("--fps", type=float, default=None, help="the model's rate [the preset's]")
    p.add_argument("--iterations", default=None, help="per block, as bench/heldout.py")
    p.add_argument("--samples", type=int, default=10)
    p.add_argument("--threads", type=int, default=None)
    p.add_argument("--cut-contacts", action="store_true",
                   help="contact labels cut at 0.5 for every label [the model's choice]")  # fmt: skip
    a = p.parse_args(argv)
    set_threads(a.threads)
    print(describe(), flush=True)

    import mrlib
    from mrlib.metrics.coverage import condition_fidelity, coverage_profile
    from mrlib.metrics.windows import metric_features, window_nn
    from mrlib.model.presets import get_preset, training_config
    from mrlib.representation.features import features_to_motion
    from mrlib.sampling.generation import generate, reconstruct

    body = mrlib.load_body_model()
    its = None if a.iterations is None else [int(v) for v in a.iterations.split(",")]
    base = get_preset(a.preset) if its is None else training_config(a.preset, its)
    base = base if a.fps is None else base.replace(fps=a.fps)
    model, _, paths = split_model(a.split, a.seed, body, base)
    captured = [mrlib.load_motion(q) for q in paths]
    print(f"\n`{a.preset}` at {base.fps:g} fps, iterations {list(base.block_iterations)}, training "
          f"seed {a.seed}, {a.samples} cleaned samples per label, windows of 30 frames\n")  # fmt: skip
    print("| clip | coverage eps 1 % | rotations only % | contacts differing % | "
          "fidelity % (rotations only) | half-frame distance (rotations) | repeat distance | "
          "reconstruction coverage eps 1 % |\n|---|---:|---:|---:|---|---|---:|---:|")  # fmt: skip
    refs = {model.labels[model.clip_labels[k]]: metric_features(
        features_to_motion(x, model.fps, betas=model.betas)) for k, x in enumerate(model.features)}  # fmt: skip
    refs_rot = {lab: r[:, ROT] for lab, r in refs.items()}
    for k in range(len(model.features)):
        label = model.labels[model.clip_labels[k]]
        ref = refs[label]
        full, rot, differ, gens = [], [], [], []
        for s in range(a.samples):
            sampler = mrlib.Sampler(match_contact_rate=False if a.cut_contacts else None)
            g = metric_features(
                generate(model, label, length=2 * len(ref), seed=s, sampler=sampler)
            )
            gens.append(g)
            full.append(np.mean(coverage_profile(g, ref, 30) < 1.0))
            rot.append(np.mean(coverage_profile(g[:, ROT], ref[:, ROT], 30) < 1.0))
            _, start = window_nn(ref[:, ROT], g[:, ROT], 30, False)
            c_ref, c_gen = ref[:, ROT.stop :], g[:, ROT.stop :]
            differ += [np.mean(c_ref[i : i + 30] != c_gen[j : j + 30]) for i, j in enumerate(start)]
        fid = condition_fidelity([(g, label) for g in gens], refs)
        fid_rot = condition_fidelity([(g[:, ROT], label) for g in gens], refs_rot)
        d, d_rot = half_frame_distance(captured[k], model.fps, body)
        rec = metric_features(reconstruct(model, k))
        rec_cov = 100 * np.mean(coverage_profile(rec, ref, 30) < 1.0)
        print(f"| {model.clip_names[k]} | {100 * np.mean(full):.1f} | {100 * np.mean(rot):.1f} | "
              f"{100 * np.mean(differ):.1f} | {100 * fid:.1f} ({100 * fid_rot:.1f}) | "
              f"{d:.2f} ({d_rot:.2f}) | "
              f"{repeat_distance(ref, 30):.2f} | {rec_cov:.1f} |")  # fmt: skip
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
