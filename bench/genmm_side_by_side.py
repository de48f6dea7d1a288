"""mrlib beside GenMM on the same walks, every row scored by the same scorer at the
clips' own frame rate.

Run from the repository root (the Bandai Namco clips where mrlib finds them; ~6 min on
two cores to train, 20 s with the model in mrlib's cache)::

    python bench/genmm_side_by_side.py                    # the four development walks
    python bench/genmm_side_by_side.py --split heldout    # the five held-out styles
    python bench/genmm_side_by_side.py --preset preview   # both at 15 fps
    python bench/genmm_side_by_side.py --features paper   # the paper's distance

mrlib: the ``demo`` preset (``--preset``) trained as ``bench/heldout.py`` trains it (the
same cached model), its samples raw and cleaned. GenMM: ``bench/genmm.py`` (training-free
patch matching, its public defaults) on each walk alone, at the preset's frame rate.
Every row: ``--samples`` clips per walk of twice the walk's length, seeds 0.., scored by
``mrlib.evaluation.evaluate`` against the walk (coverage at eps 2 and 1, global
diversity, skating, jerk ratio, penetration, condition fidelity among the walks), with
the walk played twice as the calibration row. ``--features paper``: every window and PNN
distance on the paper's features (local rotation matrices, no contact labels: the scale of
the paper's diversity figures; the eps of coverage then sit on another scale, the same
for every row). Printed: one line per method (means over
the walks) and per walk, and the seconds per sample of each method.
"""

from __future__ import annotations

import argparse
import dataclasses
import time

import numpy as np
from common import describe, set_threads
from genmm import GenMMSettings, genmm_sample_fn
from heldout import split_model

KEYS = ("coverage_pct", "coverage_tight_pct", "global_div", "skate_pct", "jerk_ratio",
        "penetration_cm", "cond_fidelity_pct")  # fmt: skip
HEAD = ("| row | coverage eps 2 | coverage eps 1 | global div. | skating % | jerk ratio | "
        "penetration cm | fidelity | s/sample |")  # fmt: skip


def _fmt(k: str, v: float) -> str:
    if not np.isfinite(v):
        return "-"
    return f"{v:.2f}" if k in ("global_div", "jerk_ratio", "penetration_cm") else f"{v:.1f}"


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--split", choices=["dev", "heldout"], default="dev",
                   help="the development walks or the held-out styles [dev]")  # fmt: skip
    p.add_argument("--seed", type=int, default=0, help="mrlib's training seed [0]")
    p.add_argument("--preset", choices=["demo", "preview"], default="demo",
                   help="mrlib's label preset, and the rate every row is scored at [demo]")  # fmt: skip
    p.add_argument("--samples", type=int, default=10, help="samples per walk [10]")
    p.add_argument("--features", choices=["mrlib", "paper"], default="mrlib",
                   help="distances on mrlib's features or the paper's (rotation matrices, "
                        "no contact labels) [mrlib]")  # fmt: skip
    p.add_argument("--threads", type=int, default=None, help="torch threads [mrlib's default]")
    a = p.parse_args(argv)
    set_threads(a.threads)
    print(describe(), flush=True)

    import mrlib
    from mrlib.evaluation import EvaluationSettings
    from mrlib.evaluation.calibration import OTHER_TAKE, PLAYED_TWICE
    from mrlib.evaluation.evaluate import evaluate, model_references, model_sample_fn
    from mrlib.evaluation.results import CALIB_PREFIX, FEATURE_SETS
    from mrlib.model.presets import get_preset

    body = mrlib.load_body_model()
    cfg = get_preset(a.preset)
    t = time.perf_counter()
    model, reused, paths = split_model(a.split, a.seed, body, cfg)
    native = {round(float(mrlib.load_motion(p).fps), 3) for p in paths}
    how = "reused" if reused else f"trained in {time.perf_counter() - t:.0f} s"
    print(f"\nmrlib: {a.preset} preset at {cfg.fps:g} fps (the clips' own rate: {sorted(native)}), "
          f"seed {a.seed}, on {', '.join(model.clip_names)} ({how})", flush=True)  # fmt: skip

    settings = EvaluationSettings(num_samples=a.samples, seed=0, **FEATURE_SETS[a.features])
    print(f"features: {a.features}'s", flush=True)
    refs = model_references(model)
    spent: dict[str, float] = {}

    def timed(name, fn):
        def sample(key, length, seed):
            t = time.perf_counter()
            out = fn(key, length, seed)
            spent[name] = spent.get(name, 0.0) + time.perf_counter() - t
            return out

        return sample

    sampler = {clean: mrlib.Sampler(settings.fine_noise, settings.guidance, fix_contacts=clean)
               for clean in (False, True)}  # fmt: skip
    methods = {
        "GenMM": timed("GenMM", genmm_sample_fn(refs, GenMMSettings())),
        "ours (raw)": timed("ours (raw)", model_sample_fn(model, sampler[False])),
        "ours": timed("ours", model_sample_fn(model, sampler[True])),
        "ours, one draw": timed(
            "ours, one draw",
            model_sample_fn(model, dataclasses.replace(sampler[True], candidates=1)),
        ),
    }
    result = evaluate(methods, refs, settings, body=body, progress=False)
    rows = result.rows
    n = a.samples * len(refs)
    speed = {k: v / n for k, v in spent.items()}
    take = CALIB_PREFIX + OTHER_TAKE
    order = [CALIB_PREFIX + PLAYED_TWICE, take, "GenMM", "ours (raw)", "ours", "ours, one draw"]
    order = [m for m in order if any(r["method"] == m for r in rows)]
    label = {CALIB_PREFIX + PLAYED_TWICE: "clip played twice",
             take: "the walk's second take (real, `_002`)", "ours (raw)": "mrlib raw",
             "ours": "mrlib cleaned",
             "ours, one draw": "mrlib cleaned, one draw per sample (`candidates=1`)"}  # fmt: skip
    print(f"\n{a.samples} samples per walk of twice its length, scored at {model.fps:g} fps; "
          "means over the walks\n")  # fmt: skip
    print(HEAD + "\n|---|" + "---:|" * 8)
    for m in order:
        rs = [r for r in rows if r["method"] == m]
        mean = {k: float(np.nanmean([r[k] for r in rs])) for k in KEYS}
        s = f"{speed[m]:.2f}" if m in speed else "-"
        print(f"| {label.get(m, m)} | " + " | ".join(_fmt(k, mean[k]) for k in KEYS) + f" | {s} |")
    shown = [m for m in (take, "GenMM", "ours") if m in order]
    print(f"\nper walk: coverage eps 1 % ({' / '.join(label.get(m, m) for m in shown)}), "
          "global diversity (same)")  # fmt: skip
    for key in refs:
        got = [next((r for r in rows if r["method"] == m and r["sequence"] == key), None)
               for m in shown]  # fmt: skip
        cov = " / ".join("-" if r is None else f"{r['coverage_tight_pct']:.1f}" for r in got)
        div = " / ".join("-" if r is None else f"{r['global_div']:.2f}" for r in got)
        print(f"  {key}: {cov}, {div}")
    print("(s/sample: drawing one sample, one thread as set above; mrlib cleaned includes "
          "its raw draw)")  # fmt: skip
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
