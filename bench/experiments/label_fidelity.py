"""Why one label lost its fidelity at the demo budget (docs/notes/2026-12-02-condition-control.md).

Each subcommand prints one table of that note:

    python bench/experiments/label_fidelity.py diagnose --seed S    # length, guidance, fine noise, reconstruction
    python bench/experiments/label_fidelity.py probe --seed S       # happy at levels 1..k, normal above
    python bench/experiments/label_fidelity.py variant NAME --seed S  # demo + one change, fidelity per label
    python bench/experiments/label_fidelity.py capture              # the jitter filter on the Bandai clips
    python bench/experiments/label_fidelity.py synthetic --seed S --mismatch W  # the demo clips

``diagnose`` and ``probe`` score a model of ``bench/cleanup_natural.py --train-only``
(``outputs/cleanup_natural/demo_seed<S>/``, or ``--checkpoint``). ``variant`` trains
(or reuses, ``outputs/label_fidelity/<NAME>_seed<S>/``) on the four Bandai walks the
``preview`` preset as it was before the mismatch term (``base``) or with one change:
``band_full`` (``critic_band="full"``) or ``mismatchW`` (``LossWeights.mismatch = W``;
``mismatch2`` is today's preset). Fidelity: the share of 30-frame windows of
10 raw samples per label whose nearest training window is the label's.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # bench/: common.py

from common import ROOT, TUTORIAL_CLIPS, bandai_clips, set_threads

RUNS = ROOT / "outputs" / "label_fidelity"


def _fidelity(model, length_of, **settings):
    from mrlib.metrics.coverage import condition_fidelity
    from mrlib.metrics.windows import metric_features, model_references
    from mrlib.sampling.generation import generate
    from mrlib.sampling.sampler import Sampler

    _, labels, feats = model_references(model)
    refs = dict(zip(labels, feats, strict=True))
    out = {}
    for i, lab in enumerate(labels):
        ms = generate(model, lab, length=length_of(i), seed=0, num=10,
                      sampler=Sampler(fix_contacts=False, **settings))  # fmt: skip
        out[lab] = 100 * condition_fidelity([(metric_features(m), lab) for m in ms], refs)
    return out


def _model(a):
    import mrlib

    path = (
        a.checkpoint
        or ROOT / "outputs" / "cleanup_natural" / f"demo_seed{a.seed}" / "checkpoint.pt"
    )
    return mrlib.load_model(path)


def diagnose(a) -> None:
    from mrlib.metrics.coverage import condition_fidelity
    from mrlib.metrics.windows import metric_features, model_references
    from mrlib.sampling.generation import reconstruct

    model = _model(a)
    _, labels, feats = model_references(model)
    refs = dict(zip(labels, feats, strict=True))
    own = {i: int(model.lengths[i, -1]) for i in range(len(labels))}
    from mrlib.evaluation.fidelity import condition_fidelity_of_model

    pooled = condition_fidelity_of_model(model, num_samples=10, seed=0).per_label
    cols = {"2x the longest clip (pooled)": {k: 100 * v for k, v in pooled.items()},
            "1x its clip": _fidelity(model, lambda i: own[i]),
            "2x": _fidelity(model, lambda i: 2 * own[i])}  # fmt: skip
    for g in (0.25, 0.5):
        cols[f"guidance {g}"] = _fidelity(model, lambda i: 2 * own[i], guidance=g)
    cols["fine_noise 0"] = _fidelity(model, lambda i: 2 * own[i], fine_noise=0.0)
    cols["reconstruction"] = {
        lab: 100 * condition_fidelity([(metric_features(reconstruct(model, i)), lab)], refs)
        for i, lab in enumerate(labels)
    }
    print("| label | " + " | ".join(cols) + " |\n|---|" + "---:|" * len(cols))
    for lab in labels:
        print(f"| {lab} | " + " | ".join(f"{c[lab]:.1f}" for c in cols.values()) + " |")


def probe(a) -> None:
    from mrlib.metrics.coverage import condition_fidelity
    from mrlib.metrics.windows import metric_features, model_references
    from mrlib.sampling.conditions import Condition
    from mrlib.sampling.generation import generate
    from mrlib.sampling.sampler import Sampler

    model = _model(a)
    _, labels, feats = model_references(model)
    refs = dict(zip(labels, feats, strict=True))
    L, n = model.num_levels, 2 * int(model.lengths[labels.index("walk_happy"), -1])
    for k in range(1, L):
        cond = Condition.crossover("walk_happy", "walk_normal", k)
        ms = generate(model, cond, length=n, seed=0, num=10, sampler=Sampler(fix_contacts=False))
        f = [metric_features(m) for m in ms]
        share = {lab: 100 * condition_fidelity([(x, lab) for x in f], refs) for lab in labels}
        print(f"happy at levels 1-{k}, normal above: "
              + ", ".join(f"{lab} {v:.0f} %" for lab, v in share.items()))  # fmt: skip


def variant(a) -> None:
    import mrlib
    from mrlib.model.presets import preview
    from mrlib.training.data import TrainingSet
    from mrlib.training.trainer import train_or_reuse

    cfg = mrlib.get_preset("preview").replace(seed=a.seed)
    cfg = cfg.replace(loss=dataclasses.replace(cfg.loss, mismatch=0.0))  # as it was
    if a.name == "band_full":
        cfg = cfg.replace(model=dataclasses.replace(cfg.model, critic_band="full"))
    elif a.name.startswith("mismatch"):
        cfg = cfg.replace(loss=dataclasses.replace(cfg.loss, mismatch=float(a.name[8:])))
    elif a.name != "base":
        sys.exit(f"unknown variant {a.name!r}: base, band_full or mismatchW")
    body = mrlib.load_body_model()
    fps = preview().fps
    data = TrainingSet.from_motions(
        [mrlib.load_motion(p, fps=fps) for p in bandai_clips(TUTORIAL_CLIPS)], body=body
    )
    model, rec = train_or_reuse(data, cfg, RUNS / f"{a.name}_seed{a.seed}", body=body,
                                progress=False)  # fmt: skip
    fid = _fidelity(model, lambda i: 2 * int(model.lengths[i, -1]))
    print(json.dumps({"variant": a.name, "seed": a.seed, "train_s": round(rec.wall_time_s),
                      **{k: round(v, 1) for k, v in fid.items()}}))  # fmt: skip


def capture(a) -> None:
    import mrlib
    from mrlib.evaluation.evaluate import score_motions
    from mrlib.sampling.cleanup import cleanup_foot_contacts

    body = mrlib.load_body_model()
    for fps in (15, 30):
        for p in bandai_clips(TUTORIAL_CLIPS):
            c = mrlib.load_motion(p, fps=fps)
            c = c.replace(contacts=mrlib.representation.foot_contacts(c, body))
            cells = []
            for j in (0.0, 0.5):
                r = score_motions([cleanup_foot_contacts(c, body, jitter=j)], c, body=body)
                cells.append(
                    f"jitter {j}: jerk x{r['jerk_ratio']:.3f}, coverage {r['coverage_pct']:.0f} %"
                )
            print(f"{fps} fps {p.stem}: " + "; ".join(cells))


def synthetic(a) -> None:
    import mrlib
    from mrlib.app.demo import DATA_SAMPLES, DEMO_FPS
    from mrlib.evaluation.evaluate import EvaluationSettings, evaluate_model
    from mrlib.training.data import TrainingSet
    from mrlib.training.trainer import train_or_reuse

    body = mrlib.load_body_model()
    clips = [mrlib.load_motion(p, fps=DEMO_FPS) for p in sorted(DATA_SAMPLES.glob("*.npz"))]
    clips = [c.replace(contacts=mrlib.representation.foot_contacts(c, body)) for c in clips]
    cfg = mrlib.get_preset("preview").replace(seed=a.seed)
    cfg = cfg.replace(loss=dataclasses.replace(cfg.loss, mismatch=a.mismatch))
    out = RUNS / f"synthetic_mismatch{a.mismatch:g}_seed{a.seed}"
    model, _ = train_or_reuse(TrainingSet.from_motions(clips, body=body), cfg, out, body=body,
                              progress=False)  # fmt: skip
    settings = EvaluationSettings(num_samples=10, seed=0)
    r = evaluate_model(model, settings=settings, body=body, contacts="both", progress=False)
    for d in r.summary():
        if d["method"].startswith("ours"):
            print(f"{d['method']}: fidelity {d['cond_fidelity_pct_mean']:.1f} %, skating "
                  f"{d['skate_pct_mean']:.1f} %, {d['skate_speed_mean']:.3f} m/s")  # fmt: skip


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("what", choices=["diagnose", "probe", "variant", "capture", "synthetic"])
    ap.add_argument("name", nargs="?", default="base", help="variant: base, band_full, mismatchW")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--mismatch", type=float, default=2.0, help="synthetic: the term's weight")
    ap.add_argument("--checkpoint", default=None, help="diagnose/probe: this model")
    a = ap.parse_args()
    set_threads(1)
    {"diagnose": diagnose, "probe": probe, "variant": variant, "capture": capture,
     "synthetic": synthetic}[a.what](a)  # fmt: skip
    return 0


if __name__ == "__main__":
    sys.exit(main())
