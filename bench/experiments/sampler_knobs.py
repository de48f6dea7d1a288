"""Sampling knobs of a trained label model against coverage, fidelity and diversity: the
coarsest level's noise scale, label guidance on a range of levels, and critic-ranked
candidates (``mrlib.Sampler.candidates``). No training: the ``demo`` models of
``bench/heldout.py`` are taken from mrlib's model cache (trained there when missing).

Run from the repository root::

    python bench/experiments/sampler_knobs.py --split dev --seed 0 \\
        --configs 1,8,1:coarse=0.5,8:coarse=0.5,1:guide=0.5@1-1

A config is ``K[:coarse=S][:guide=G@A-B][:anchor=A@STYLE][:margin=M]``: K candidates per sample, the
coarsest level's noise times S, guidance G on levels A..B (1-based), and for the label of
``STYLE`` the coarsest noise ``A z* + sqrt(1 - A^2) z``: anchored to the clip's own
reconstruction noise z* (tiled to the sample's length; A = 1 with the finer levels' noise
at 0 is the reconstruction). Printed per config: mean and lowest coverage at eps 1,
lowest condition fidelity, mean global diversity, cleaned skating and jerk, and per label
``coverage eps 1 / coverage eps 2 / fidelity / diversity``.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np
import torch

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from common import describe, set_threads  # noqa: E402
from heldout import split_model  # noqa: E402


def parse(config: str) -> dict:
    head, *rest = config.split(":")
    out = {"candidates": int(head), "coarse": 1.0, "guide": 0.0, "levels": None, "anchor": None,
           "margin": 0.0}  # fmt: skip
    for part in rest:
        key, value = part.split("=")
        if key == "margin":
            out["margin"] = float(value)
        elif key == "anchor":
            a, style = value.split("@")
            out["anchor"] = (float(a), style)
        elif key == "coarse":
            out["coarse"] = float(value)
        elif key == "guide":
            g, lv = value.split("@")
            a, b = (int(v) for v in lv.split("-"))
            out["guide"], out["levels"] = float(g), (a - 1, b)
        else:
            raise SystemExit(f"unknown knob {key!r} in {config!r}")
    return out


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--split", choices=["heldout", "fresh", "dev"], default="dev")
    p.add_argument("--seed", type=int, default=0, help="training seed [0]")
    p.add_argument("--samples", type=int, default=20, help="samples per label [20]")
    p.add_argument("--configs", default="1,8", help="comma-separated configs [1,8]")
    p.add_argument("--threads", type=int, default=1, help="torch threads [1]")
    a = p.parse_args(argv)
    set_threads(a.threads)
    print(describe(), flush=True)

    import mrlib
    import mrlib.sampling.generation as generation
    from mrlib.evaluation import EvaluationSettings, evaluate_model

    body = mrlib.load_body_model()
    model, reused, _ = split_model(a.split, a.seed, body)
    print(f"demo model, seed {a.seed}, on {', '.join(model.clip_names)} "
          f"({'reused' if reused else 'trained'})\n", flush=True)  # fmt: skip

    plain_amp, plain_guided = generation.noise_amplitude, generation.guided_weights
    plain_inputs, plain_noise = generation.label_inputs, generation.draw_noise
    plain_scores, plain_best = generation.critic_scores, generation.best_candidates
    drawing: dict = {}  # the label being drawn (label_inputs sees it, draw_noise does not)

    def inputs(model, W, length, sampler):
        drawing["label"] = int(W[0].argmax())
        return plain_inputs(model, W, length, sampler)

    def noise(lengths, amp, seed, num, device="cpu"):
        z = plain_noise(lengths, amp, seed, num, device)
        a, style = drawing.get("anchor") or (0.0, "")
        label = drawing.get("label", -1)
        if a > 0 and model.labels[label] == f"walk_{style}":
            clips = [k for k, c in enumerate(model.clip_labels) if c == label]
            for r in range(num):  # candidate r: clip r mod (the label's clips)
                zs = model.zstar[clips[r % len(clips)]][0]
                tiled = zs.repeat(-(-lengths[0] // len(zs)))[: lengths[0]]
                z[0][r, 0] = a * tiled + (1 - a * a) ** 0.5 * z[0][r, 0]
        return z

    for text in a.configs.split(","):
        c = parse(text)

        def amp(model, W, sampler, c=c):
            out = plain_amp(model, W, sampler).clone()
            out[0] = out[0] * c["coarse"]
            return out

        def guided(W, sampler, c=c):
            if c["levels"] is None:
                return plain_guided(W, sampler)
            i, j = c["levels"]
            out = W.clone()
            out[i:j] = W[i:j] + c["guide"] * (W[i:j] - 1.0 / W.shape[-1])
            return out

        def scores(model, outs, conds, c=c):
            rows = plain_scores(model, outs, conds)
            if c["margin"] == 0:
                return rows
            margins = []
            for i in range(len(rows)):
                critic, x = model.critics[i], outs[i]
                cond = conds[i].expand(x.shape[0], x.shape[-1], -1)
                want = cond.mean(1).argmax(-1)  # (N,) the requested label
                per = []
                for k in range(cond.shape[-1]):
                    e = torch.zeros_like(cond)
                    e[..., k] = 1.0
                    per.append(critic(x, None, e).mean(1))
                per = torch.stack(per, -1)  # (N, labels)
                own = per.gather(1, want[:, None])[:, 0]
                other = per.scatter(1, want[:, None], float("-inf")).max(1).values
                margins.append(own - other)
            return torch.cat([rows, torch.stack(margins)])

        def best(s, K, c=c):
            if c["margin"] == 0:
                return plain_best(s, K)
            L, n = s.shape[0] // 2, s.shape[1]
            s = s.reshape(2 * L, n // K, K)
            z = (s - s.mean(-1, keepdim=True)) / (s.std(-1, keepdim=True) + 1e-6)
            total = z[:L].sum(0) + c["margin"] * z[L:].sum(0)
            return total.argmax(-1) + torch.arange(n // K) * K

        generation.critic_scores, generation.best_candidates = scores, best
        generation.noise_amplitude, generation.guided_weights = amp, guided
        generation.label_inputs, generation.draw_noise = inputs, noise
        drawing["anchor"] = c["anchor"]
        try:
            t = time.perf_counter()
            settings = EvaluationSettings(
                num_samples=a.samples, seed=a.seed, candidates=c["candidates"]
            )
            result = evaluate_model(model, settings=settings, body=body, progress=False)
        finally:
            generation.noise_amplitude, generation.guided_weights = plain_amp, plain_guided
            generation.label_inputs, generation.draw_noise = plain_inputs, plain_noise
            generation.critic_scores, generation.best_candidates = plain_scores, plain_best
        rows = [r for r in result.rows if r["method"] == "ours"]

        def mean(k, rows=rows):
            return float(np.mean([r[k] for r in rows]))

        cells = " ".join(
            f"{r['sequence'].removeprefix('walk_')}:{r['coverage_tight_pct']:.0f}/"
            f"{r['coverage_pct']:.0f}/"
            f"{r['cond_fidelity_pct']:.0f}/{r['global_div']:.2f}"
            for r in rows
        )
        print(
            f"{text}: coverage eps 1 {mean('coverage_tight_pct'):.1f} "
            f"(lowest {min(r['coverage_tight_pct'] for r in rows):.1f}), lowest fidelity "
            f"{min(r['cond_fidelity_pct'] for r in rows):.1f}, global div. "
            f"{mean('global_div'):.3f}, skating {mean('skate_pct'):.1f} %, jerk "
            f"{mean('jerk_ratio'):.2f} | {cells} ({time.perf_counter() - t:.0f} s)",
            flush=True,
        )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
