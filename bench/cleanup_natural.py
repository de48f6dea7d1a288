"""Does the foot-contact clean-up leave motion natural? Issue #37, part 3.

Trains (or reuses, ``outputs/cleanup_natural/demo_seed<S>/``) the ``preview`` preset on the
four Bandai walks at the preset's frame rate (``preview().fps``, 15 fps), draws
``--samples`` raw samples per walk of twice the clip's length (seeds 0..n-1), and scores
them raw, after the clean-up with its defaults and after each ``--method`` with
``mrlib.evaluation.evaluate.score_motions`` (the evaluation's own code: coverage at
``--eps``, skating share above 0.15 m/s of the generator's contact labels, mean joint
jerk over the training clip's, mean depth of the lowest foot vertex below the training
clip's ground, condition fidelity: the share of windows whose nearest training window
is the label's). The training clip played twice is the last row, the real-capture level.

    python bench/cleanup_natural.py [--seed 0] [--samples 5] [--method old,new,'smooth_s=0.2;pin_weight=100']
    python bench/cleanup_natural.py --split heldout --seed 1 --method reweight=1,new --per-walk

``--split``: the ``demo`` model of ``bench/heldout.py --split SPLIT`` instead (30 fps, from
mrlib's model cache; trained there when missing); ``--checkpoint``: any model.

Methods (``methods()``): ``raw``, ``old`` (the previous default clean-up, pinned runs
blended over ``BLEND_S``, the root low-passed over ``ROOT_SMOOTH_S``:
``experiments/cleanup_studies.py``'s ``cleanup_pinned``), ``new``
(``cleanup_foot_contacts()``, the smooth solve) and ablations of it; any other name
``key=value;key=value`` is the clean-up with those options (its keywords, or fields of
``mrlib.sampling.planting.PlantOptions``). Prints a Markdown table per walk and the
mean, and appends the means as a JSON row to ``bench/results/cleanup_natural.jsonl``.
"""

from __future__ import annotations

import argparse
import sys
import time

from common import ROOT, TUTORIAL_CLIPS, bandai_clips, describe, set_threads, write_json

RUNS = ROOT / "outputs" / "cleanup_natural"
COLUMNS = (("coverage_pct", "cov ε=1 %", "{:.1f}"), ("global_div", "global div.", "{:.2f}"),
           ("skate_pct", "skating %", "{:.1f}"),
           ("jerk_ratio", "jerk ratio", "{:.2f}"), ("penetration_cm", "pen. cm", "{:.2f}"),
           ("float_cm", "float cm", "{:.2f}"), ("cond_fidelity_pct", "fid. %", "{:.1f}"),
           ("ms_per_sample", "ms/sample", "{:.0f}"))  # fmt: skip


def float_cm(motions, ref_feet, body) -> float:
    """Mean height (cm) above the reference's ground (``estimate_ground``) of the lowest
    vertex labelled in contact, over the frames with one: 0 for feet planted on it."""
    import numpy as np

    from mrlib.metrics.plausibility import estimate_ground, motion_kinematics

    ground = estimate_ground(ref_feet)
    h = []
    for m in motions:
        y = motion_kinematics(m, body)[1][..., 1]
        c = np.asarray(m.contacts) > 0.5
        low = np.where(c, y, np.inf).min(1)
        h.append(low[c.any(1)] - ground)
    return 100 * float(np.concatenate(h).mean())


def methods():
    """name -> ``fn(motion, body, floor) -> Motion`` (None: the raw sample); ``floor`` is
    the training clip's (``generation.training_floor``), as ``generate`` passes it."""
    from experiments.cleanup_studies import cleanup_pinned

    from mrlib.sampling.cleanup import cleanup_foot_contacts as clean
    from mrlib.sampling.planting import PlantOptions

    return {
        "raw": None,
        "old": lambda m, body, floor: cleanup_pinned(m, body),  # the previous default
        "new": lambda m, body, floor: clean(m, body, floor=floor),
        "new, floor from the sample": lambda m, body, floor: clean(m, body),
        "new, no floor clamp": lambda m, body, floor: clean(m, body, floor_clamp=False),
        "new, root kept": lambda m, body, floor: clean(m, body, floor=floor, move_root=False),
        "new, no jitter filter": lambda m, body, floor: clean(m, body, floor=floor, jitter=0),
        "new, solved once (reweight=0)": lambda m, body, floor: clean(
            m, body, floor=floor, options=PlantOptions(reweight=0)
        ),
        "new, one re-solve (reweight=1)": lambda m, body, floor: clean(
            m, body, floor=floor, options=PlantOptions(reweight=1)
        ),
    }


def custom(spec: str):
    """``key=value;key=value``: ``cleanup_foot_contacts(m, body, key=value, ...)``, a key
    that is a field of ``PlantOptions`` in its ``options``."""
    from dataclasses import fields

    from mrlib.sampling.cleanup import cleanup_foot_contacts as clean
    from mrlib.sampling.planting import PlantOptions

    kw, opts = {}, {}
    for item in filter(None, spec.split(";")):
        k, v = item.split("=")
        try:
            value = float(v)
        except ValueError:
            value = v
        (opts if k in {f.name for f in fields(PlantOptions)} else kw)[k] = value
    for k in ("floor_clamp", "move_root"):
        if k in kw:
            kw[k] = bool(kw[k])
    for k in ("reweight", "iterations"):
        if k in opts:
            opts[k] = int(opts[k])
    options = PlantOptions(**opts)
    return lambda m, body, floor: clean(m, body, **{"floor": floor, **kw, "options": options})


def train_model(seed: int, body):
    import mrlib
    from mrlib.model.presets import preview
    from mrlib.training.data import TrainingSet
    from mrlib.training.trainer import train_or_reuse

    fps = preview().fps
    cfg = mrlib.get_preset("preview").replace(seed=seed)
    clips = [mrlib.load_motion(p, fps=fps) for p in bandai_clips(TUTORIAL_CLIPS)]
    data = TrainingSet.from_motions(clips, body=body)
    t0 = time.perf_counter()
    model, record = train_or_reuse(data, cfg, RUNS / f"demo_seed{seed}", body=body, progress=False)
    print(f"model: {record.checkpoint} ({'reused' if record.reused else 'trained'}, "
          f"{time.perf_counter() - t0:.0f} s)", flush=True)  # fmt: skip
    return model


def split_model(split: str, seed: int, body):
    """The cached ``demo`` model of ``bench/heldout.py --split SPLIT`` (its clips, its
    training seed; trained here when missing, as there)."""
    from heldout import split_model as heldout_model

    model, reused, _ = heldout_model(split, seed, body)
    print(f"model: the demo model of bench/heldout.py --split {split}, seed {seed} "
          f"({'reused' if reused else 'trained'})", flush=True)  # fmt: skip
    return model


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seed", type=int, default=0, help="training seed [0]")
    ap.add_argument("--samples", type=int, default=5, help="samples per walk [5]")
    ap.add_argument("--eps", type=float, default=1.0, help="coverage threshold [1]")
    ap.add_argument(
        "--method",
        default=None,
        help="comma-separated methods [all], or "
        "'key=value;key=value' options of cleanup_foot_contacts",
    )
    ap.add_argument("--threads", type=int, default=1)
    ap.add_argument("--train-only", action="store_true")
    ap.add_argument("--checkpoint", default=None, help="score this model instead of the preset's")
    ap.add_argument("--split", choices=["dev", "heldout", "fresh"], default=None,
                    help="score the demo model of bench/heldout.py --split SPLIT instead")  # fmt: skip
    ap.add_argument("--per-walk", action="store_true", help="also print every walk's row")
    a = ap.parse_args(argv)
    set_threads(a.threads)
    import numpy as np

    import mrlib
    from mrlib.evaluation.calibration import play_twice
    from mrlib.evaluation.evaluate import _ReferenceCache, model_references, score_motions
    from mrlib.evaluation.results import EvaluationSettings
    from mrlib.sampling.generation import generate, training_floor
    from mrlib.sampling.sampler import Sampler

    body = mrlib.load_body_model()
    if a.split is not None:
        model = split_model(a.split, a.seed, body)
    elif a.checkpoint is not None:
        model = mrlib.load_model(a.checkpoint)
    else:
        model = train_model(a.seed, body)
    if a.train_only:
        return 0
    table = methods()
    names = a.method.split(",") if a.method else list(table)
    for name in names:
        if name not in table:
            table[name] = custom(name)
    if "raw" not in names:
        names.insert(0, "raw")
    settings = EvaluationSettings(num_samples=a.samples, eps=a.eps)
    cache = _ReferenceCache(body, settings.feature_kind, settings.contact_features)
    refs = model_references(model)
    print(describe())
    which = a.checkpoint or f"training seed {a.seed}"
    print(f"{which}, {a.samples} samples per walk, 2x the clip's length, "
          f"{model.fps:g} fps, coverage eps {a.eps:g}\n", flush=True)  # fmt: skip
    rows: dict[str, dict[str, dict]] = {n: {} for n in names + ["training clip x2"]}
    for label, ref in refs.items():
        n = round(2 * ref.num_frames)
        floor = training_floor(model, [model.labels.index(label)], body)
        # the clean-ups compared on the same raw draws, one per sample (no critic ranking)
        raw = [generate(model, label, length=n, seed=s, body=body,
                        sampler=Sampler(fix_contacts=False, candidates=1))
               for s in range(a.samples)]  # fmt: skip
        for name in names:
            fn = table[name]
            t0 = time.perf_counter()
            ms = raw if fn is None else [fn(m, body, floor) for m in raw]
            dt = (time.perf_counter() - t0) / len(raw)
            r = score_motions(ms, ref, settings=settings, body=body, _cache=cache, label=label,
                              all_references=refs)  # fmt: skip
            r["ms_per_sample"] = 1000 * dt if fn is not None else 0.0
            r["float_cm"] = float_cm(ms, cache(ref).kinematics[1], body)
            rows[name][label] = r
        r = score_motions([play_twice(ref)], ref, settings=settings, body=body, _cache=cache,
                          label=label, all_references=refs)  # fmt: skip
        r["ms_per_sample"] = 0.0
        r["float_cm"] = float_cm([cache(ref).motion], cache(ref).kinematics[1], body)
        rows["training clip x2"][label] = r
    head = "| method | walk | " + " | ".join(h for _, h, _ in COLUMNS) + " |"
    lines = [head, "|---|---|" + "---:|" * len(COLUMNS)]
    means = {}
    for name, per in rows.items():
        if a.per_walk:
            for label, r in per.items():
                vals = " | ".join(f.format(r[k]) for k, _, f in COLUMNS)
                lines.append(f"| {name} | {label.removeprefix('walk_')} | {vals} |")
        mean = {k: float(np.mean([r[k] for r in per.values()])) for k, _, _ in COLUMNS}
        jr = [per[lab]["jerk_ratio"] for lab in per]
        fid = [per[lab]["cond_fidelity_pct"] for lab in per]
        means[name] = {**mean, "jerk_min": min(jr), "jerk_max": max(jr), "fid_min": min(fid)}
        vals = " | ".join(f.format(mean[k]) for k, _, f in COLUMNS)
        lines.append(f"| **{name}** | mean | {vals} |")
    print("\n".join(lines))
    train_skate = means["training clip x2"]["skate_pct"]
    raw_cov = means["raw"]["coverage_pct"]
    print(f"\ntargets: skating <= {train_skate + 2:.1f} %, jerk <= 1.2, pen <= 0.1 cm, "
          f"coverage >= {raw_cov - 2:.1f} %")  # fmt: skip
    for name in names[1:]:
        m = means[name]
        ok = {"skating": m["skate_pct"] <= train_skate + 2, "jerk": m["jerk_ratio"] <= 1.2,
              "pen": m["penetration_cm"] <= 0.1, "coverage": m["coverage_pct"] >= raw_cov - 2,
              "fidelity (every walk >= 90 %)": m["fid_min"] >= 90}  # fmt: skip
        print(f"  {name}: " + ", ".join(f"{k} {'ok' if v else 'MISS'}" for k, v in ok.items())
              + f"  (jerk per walk {m['jerk_min']:.2f}-{m['jerk_max']:.2f}, "
              f"lowest fidelity {m['fid_min']:.1f} %)")  # fmt: skip
    write_json("cleanup_natural", {"seed": a.seed, "samples": a.samples, "eps": a.eps,
                                   "means": means}, append=True)  # fmt: skip
    return 0


if __name__ == "__main__":
    sys.exit(main())
