"""Best of n by the model's own critics: does ranking a label's samples with the trained
conditional critics pick the ones whose body parts keep the label?

A route to body-part composition (``mrlib.sampling.constraints.generate_parts``, splice): each part
comes from a sample of its own label, so a part keeps its label as often as unmixed
samples keep it on that part. Drawing n samples and keeping the one the critics like best
is discriminator rejection sampling (Azadi et al., ICLR 2019) in its simplest form. The
`tutorial` critics are projection critics (``mrlib.model.critic.PatchCritic``):
``D(x, c)_t = w * h(x)_t + <P c_t, g(x)_t>``, and ``g``'s channels belong to joints
(skeleton-aware convolutions), so the label term splits by body part. Scores, each summed
over the eight levels' critics on the sample's level outputs and averaged over frames:

* ``part margin``: the label term of the sample's own label minus its mean over the other
  labels, on the part's channels of ``g`` only;
* ``whole margin``: the same on every channel;
* ``critic score``: ``D(x, c)`` with the sample's own label (realism and label together).

Per label and part: the part's fidelity (``mrlib.sampling.constraints.part_fidelity``, the measure
of ``bench/constraints.py --only parts``) of all ``--samples`` samples, the correlation of
each score with it over the samples, and the fidelity of the best-scored sample of each
group of n (n = 2, 4, 8). Samples are twice the longest clip, as in
``bench/constraints.py``; seed 0; one torch thread.

    python bench/experiments/critic_ranking.py [--checkpoint ckpt.pt] [--samples 32]
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np
import torch

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # bench/: common.py

from common import add_checkpoint_arg, set_threads

from mrlib.model.checkpoint import load_checkpoint
from mrlib.model.critic import build_critics
from mrlib.model.pyramid import PackedLevels
from mrlib.model.skeleton_conv import hidden_channel_joint
from mrlib.model.trained import model_from_state
from mrlib.representation.features import features_to_motions
from mrlib.sampling.conditions import Condition
from mrlib.sampling.constraints import PARTS, part_fidelity
from mrlib.sampling.generation import label_inputs, sample_features
from mrlib.sampling.sampler import Sampler

GROUPS = (2, 4, 8)


def critic_terms(critic, x: torch.Tensor, k: int):
    """``x (B, C, T)`` one level's outputs -> per sample ``(B, F, K)`` the label term's
    mean per feature channel and label, and ``(B,)`` the mean of ``D(x, e_k)``."""
    B, _, T = x.shape
    lay = PackedLevels.from_table(torch.full((B, 1), T), gap=2 * critic.body.pad + 2)
    score, g = critic.split(lay.pack(list(x), 0), lay.pad_index(0, critic.body.pad))
    P = critic.project.weight  # (F, K)
    terms = torch.stack([gb.mean(1)[:, None] * P for gb in lay.unpack(g, 0)])
    own = score + (P[:, k, None] * g).sum(1)  # D(x, e_k) per frame
    total = torch.stack([s.mean() for s in lay.unpack(own[:, None], 0)])
    return terms, total


def margin(z: torch.Tensor, k: int) -> np.ndarray:
    """``z (B, K)`` -> own label's term minus the mean of the others'."""
    others = torch.cat([z[:, :k], z[:, k + 1 :]], 1)
    return (z[:, k] - others.mean(1)).numpy()


def best_of(fid: np.ndarray, score: np.ndarray, n: int) -> float:
    m = len(fid) // n * n
    f, s = fid[:m].reshape(-1, n), score[:m].reshape(-1, n)
    return float(f[np.arange(len(f)), s.argmax(1)].mean())


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    add_checkpoint_arg(ap)
    ap.add_argument("--samples", type=int, default=32, help="samples per label [32]")
    a = ap.parse_args()
    if not a.checkpoint.is_file():
        ap.error(f"{a.checkpoint} not found: run bench/condition_control.py first")
    set_threads(1)
    state = load_checkpoint(a.checkpoint)
    model = model_from_state(state)
    if not model.config.model.critic_condition:
        ap.error("this model's critics are unconditional: they carry no label term to rank by")
    critics = build_critics(model.config.model, int(state["cond_dim"]))
    critics.load_state_dict(state["critics"])
    critics.eval().requires_grad_(False)
    L, N = model.num_levels, a.samples
    length = 2 * int(model.lengths[:, -1].max())
    print(f"{a.checkpoint}: {N} samples per label of {length} frames, seed 0\n")
    print(
        "| label | part | all samples | score | r | "
        + " | ".join(f"best of {n}" for n in GROUPS)
        + " |"
    )
    print("|---|---|---:|---|---:|" + "---:|" * len(GROUPS))
    picked: dict[str, list[float]] = {}
    t_sample = t_score = 0.0
    for k, lab in enumerate(model.labels):
        t0 = time.perf_counter()
        lens, amp, conds = label_inputs(
            model, Condition.label(lab).weights(model), length, Sampler()
        )
        outs = sample_features(model, conds, lens, amp, seed=0, num_samples=N, keep=True)
        t1 = time.perf_counter()
        with torch.inference_mode():
            terms, totals = zip(
                *(critic_terms(critics[i], outs[i], k) for i in range(L)), strict=True
            )
        t_sample += t1 - t0
        t_score += time.perf_counter() - t1
        names = [f"{lab}_{b}" for b in range(N)]
        ms = features_to_motions(outs[-1].transpose(1, 2), model.fps, betas=model.betas,
                                 normalizer=model.normalizer, label=lab, names=names)  # fmt: skip
        joints = hidden_channel_joint(terms[0].shape[1])
        for part in ("upper", "lower"):
            fid = np.array([part_fidelity([m], model, {part: lab})[part] for m in ms])
            on = torch.from_numpy(np.isin(joints, PARTS[part]))
            scores = {
                "part margin": margin(sum(t[:, on].sum(1) for t in terms), k),
                "whole margin": margin(sum(t.sum(1) for t in terms), k),
                "critic score": sum(totals).numpy(),
            }
            picked.setdefault(f"{part}/all samples", []).append(float(fid.mean()))
            for name, s in scores.items():
                r = np.corrcoef(s, fid)[0, 1] if fid.std() > 0 else float("nan")
                best = [best_of(fid, s, n) for n in GROUPS]
                picked.setdefault(f"{part}/{name}", []).append(best[-1])
                print(f"| {lab} | {part} | {100 * fid.mean():.1f} % | {name} | {r:+.2f} | "
                      + " | ".join(f"{100 * b:.1f} %" for b in best) + " |", flush=True)  # fmt: skip
    print(f"\nbest of {GROUPS[-1]}, per part over the labels (worst part, parts >= 90 %):")
    for name in ("all samples", "part margin", "whole margin", "critic score"):
        f = np.array(picked[f"upper/{name}"] + picked[f"lower/{name}"])
        print(f"  {name}: mean {100 * f.mean():.1f} %, worst {100 * f.min():.1f} %, "
              f"{int((f >= 0.9).sum())} of {len(f)} parts >= 90 %")  # fmt: skip
    print(f"\nsampling {t_sample:.1f} s, critic scores {t_score:.1f} s "
          f"({len(model.labels) * N} samples, one thread)")  # fmt: skip
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
