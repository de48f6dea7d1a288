"""Global diversity against coverage at eps 1, sample by sample, at the ``demo`` budget and
at a multiple of it (docs/notes/2026-12-07-diversity.md).

    python bench/experiments/diversity_budget.py --split dev --seed 0
    python bench/experiments/diversity_budget.py --split dev --seed 0 --budget 2
    python bench/experiments/diversity_budget.py --configs 1,8,1:coarse=0.75

The model: ``bench/heldout.py``'s ``demo`` model of the split (from mrlib's model cache,
trained there first when missing), with every block's iterations times ``--budget``.
A config is ``K[:coarse=S]``: K draws per sample ranked by the critics (the sampler's
``candidates``) and the coarsest level's noise times S. Per config, over ``--samples``
cleaned samples per label of twice the clip, each scored alone against its label's clip
(``mrlib.evaluation.evaluate.score_motions``, mrlib's features): the mean coverage at
eps 1 and global diversity, as ``mrlib evaluate`` reports them; the share of samples that
cover every window of the clip at eps 1, that reach a global diversity of 1.0, and that do
both; and per label the share that do both and the highest diversity among the samples
that cover every window.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # bench/: common.py

from common import describe, set_threads
from heldout import split_model

FULL = 100.0 - 1e-9  # every window covered
DIVERSE = 1.0  # the paper's level of global diversity


def parse(config: str) -> tuple[int, float]:
    """``K[:coarse=S]`` -> (candidates, coarsest noise scale)."""
    head, *rest = config.split(":")
    coarse = 1.0
    for part in rest:
        key, _, value = part.partition("=")
        if key != "coarse":
            raise SystemExit(f"unknown knob {key!r} in {config!r}")
        coarse = float(value)
    return int(head), coarse


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--split", choices=["heldout", "fresh", "dev"], default="dev")
    p.add_argument("--seed", type=int, default=0, help="training seed [0]")
    p.add_argument("--budget", type=float, default=1.0,
                   help="the demo preset's iterations per block times this [1]")  # fmt: skip
    p.add_argument("--samples", type=int, default=20, help="samples per label [20]")
    p.add_argument("--configs", default="1,8", help="comma-separated configs [1,8]")
    p.add_argument("--threads", type=int, default=1, help="torch threads [1]")
    a = p.parse_args(argv)
    set_threads(a.threads)
    print(describe(), flush=True)

    import mrlib
    import mrlib.sampling.generation as generation
    from mrlib.evaluation import EvaluationSettings
    from mrlib.evaluation.evaluate import model_references, score_motions
    from mrlib.model.presets import get_preset

    body = mrlib.load_body_model()
    base = get_preset("demo")
    its = tuple(max(1, round(n * a.budget)) for n in base.block_iterations)
    base = base.replace(block_iterations=its)
    t = time.perf_counter()
    model, reused, _ = split_model(a.split, a.seed, body, base)
    how = "reused" if reused else f"trained in {time.perf_counter() - t:.0f} s"
    print(f"demo model x{a.budget:g} (iterations {list(its)}), seed {a.seed}, on "
          f"{', '.join(model.clip_names)} ({how})\n", flush=True)  # fmt: skip
    refs = model_references(model)
    settings = EvaluationSettings()
    plain = generation.noise_amplitude
    print("| config | coverage eps 1 % | global div. | samples covering every window % | "
          "div. >= 1.0 % | both % | per label: both % (highest div. of a sample covering every window) |")  # fmt: skip
    print("|---|---:|---:|---:|---:|---:|---|")
    for text in a.configs.split(","):
        k, coarse = parse(text)

        def amp(model, W, sampler, coarse=coarse):
            out = plain(model, W, sampler).clone()
            out[0] = out[0] * coarse
            return out

        generation.noise_amplitude = amp
        try:
            rows = []
            for label, ref in refs.items():
                for seed in range(a.samples):
                    m = mrlib.generate(model, label, length=2 * len(ref), seed=seed,
                                       sampler=mrlib.Sampler(candidates=k))  # fmt: skip
                    r = score_motions([m], ref, settings=settings, body=body)
                    rows.append((label, r["coverage_tight_pct"], r["global_div"]))
        finally:
            generation.noise_amplitude = plain
        cov = np.array([r[1] for r in rows])
        div = np.array([r[2] for r in rows])
        full, diverse = cov >= FULL, div >= DIVERSE
        best = []
        for label in refs:
            mine = [r for r in rows if r[0] == label]
            d = [r[2] for r in mine if r[1] >= FULL]
            both = 100 * np.mean([r[1] >= FULL and r[2] >= DIVERSE for r in mine])
            top = f"{max(d):.2f}" if d else "-"
            best.append(f"{label.removeprefix('walk_')} {both:.0f} % ({top})")
        print(f"| `{text}` | {cov.mean():.1f} | {div.mean():.2f} | {100 * full.mean():.0f} | "
              f"{100 * diverse.mean():.0f} | {100 * (full & diverse).mean():.0f} | "
              f"{', '.join(best)} |", flush=True)  # fmt: skip
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
