"""Restyle that keeps the path: how far a restyled clip's root leaves the input's.

Run from the repository root::

    python bench/restyle_path.py                  # both preview models, levels 2 and L-2
    python bench/restyle_path.py --levels 1,4,6   # other levels k
    python bench/restyle_path.py --json out.json  # also write the rows

Models (``mrlib.training.trainer.train_cached``: reused from mrlib's model cache, trained
there first when missing, 5-30 min on two busy cores): the ``preview`` preset (8 levels at
15 fps) trained on the four synthetic clips of ``data_samples/`` (the ``mrlib demo``
model), and, where the Bandai Namco clips are found (``$MRLIB_DATA_DIR`` or the shared
mirror), on ``walk_{normal,happy,sad,angry}_001`` (``bench/restyle.py``'s model).
``--iterations 10`` trains smoke-test models instead (``mrlib.model.presets.quick``):
their numbers test the plumbing, not a trained model.

Inputs: the ``data_samples/`` clips resampled from 30 to 24 fps (another frame rate than
the model's, not a multiple of it), and the Bandai second takes ``walk_<style>_002``
(takes neither model saw; four styles no model has a label for) at their own 30 fps, one
also at the model's 15 fps. Each input is restyled towards every label of the model at
each level ``k`` (seed 0), without the foot clean-up (``Sampler(fix_contacts=False)``)
and with it (the default sampler), and the restyled root is compared with the input's
by time: output frame ``i`` (at ``i / fps_model`` s) against the input's root ground
position at that time (linear between its frames). The table gives, in cm, the mean
over frames, the worst frame, the first and the last frame; the last line per model
the worst of each column and how many rows meet the bounds of the acceptance (mean
<= 5, worst <= 15, first and last <= 5).

The figures before the re-laid path (``mrlib.sampling.restyling.relay_root_path``) and
the clean-up that keeps it come from the same script run on the earlier code.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np
from common import ROOT, add_iterations_arg, set_threads, write_json

SAMPLE_FPS = 24.0  # the data_samples clips (30 fps) are restyled from this rate
BANDAI_INPUTS = ("walk_sad_002", "walk_angry_002", "walk_happy_002", "walk_proud_002",
                 "walk_old_002")  # fmt: skip
AT_MODEL_RATE = "walk_sad_002"  # also given at the model's frame rate
TRAIN = tuple(f"walk_{s}_001" for s in ("normal", "happy", "sad", "angry"))
BOUNDS = {"mean": 5.0, "worst": 15.0, "first": 5.0, "last": 5.0}  # cm, the acceptance


def path_distances(restyled, source) -> np.ndarray:
    """``(T,)`` ground distance (cm) of ``restyled``'s root from ``source``'s at the same
    times: frame ``i`` of ``restyled`` against ``source`` at ``i / restyled.fps`` s."""
    t = np.arange(restyled.num_frames) * (source.fps / restyled.fps)
    ref = source.at_frames(t).trans[:, [0, 2]]
    return 100 * np.linalg.norm(restyled.trans[:, [0, 2]] - ref, axis=1)


def summary(d: np.ndarray) -> dict:
    return {"mean": float(d.mean()), "worst": float(d.max()), "first": float(d[0]),
            "last": float(d[-1])}  # fmt: skip


def holds(s: dict) -> bool:
    return all(s[k] <= b for k, b in BOUNDS.items())


def models(iterations, body) -> dict:
    """``{name: model}``: the preview preset on the synthetic samples, and on the Bandai
    walks when they are found."""
    import mrlib
    from mrlib.datasets.bandai import tutorial_clips
    from mrlib.model.presets import get_preset, quick
    from mrlib.training.data import TrainingSet
    from mrlib.training.trainer import train_cached

    cfg = get_preset("preview")
    if iterations is not None:
        cfg = quick(cfg, iterations if len(iterations) > 1 else iterations[0])
    sets = {"synthetic": [mrlib.load_motion(p, fps=cfg.fps)
                          for p in sorted((ROOT / "data_samples").glob("*.npz"))]}  # fmt: skip
    source = tutorial_clips(list(TRAIN), fetch=False)
    if not source.synthetic:
        sets["bandai"] = [mrlib.load_motion(p, fps=cfg.fps) for p in source.paths]
    out = {}
    for name, clips in sets.items():
        t = time.perf_counter()
        model, rec = train_cached(TrainingSet.from_motions(clips, body=body), cfg, body=body,
                                  progress=False)  # fmt: skip
        how = "reused" if rec.reused else f"trained in {time.perf_counter() - t:.0f} s"
        print(f"model {name}: {cfg.block_iterations} iterations per block, {how} "
              f"({rec.checkpoint})", flush=True)  # fmt: skip
        out[name] = model
    return out


def inputs(model_fps: float) -> dict:
    """``{name: Motion}``: the samples at ``SAMPLE_FPS``, the Bandai takes (if found) at
    their own rate and one at ``model_fps``."""
    import mrlib
    from mrlib.datasets.bandai import tutorial_clips

    out = {}
    for p in sorted((ROOT / "data_samples").glob("*.npz")):
        out[f"{p.stem}@{SAMPLE_FPS:g}"] = mrlib.load_motion(p, fps=SAMPLE_FPS)
    source = tutorial_clips(list(BANDAI_INPUTS), fetch=False)
    if not source.synthetic:
        for n, p in zip(BANDAI_INPUTS, source.paths, strict=True):
            clip = mrlib.load_motion(p)
            out[f"{n}@{clip.fps:g}"] = clip
            if n == AT_MODEL_RATE:
                out[f"{n}@{model_fps:g}"] = clip.resample(model_fps)
    else:
        print(f"Bandai inputs skipped: {source.note}")
    return out


def sweep(model, clips: dict, levels, body) -> list[dict]:
    """One row per (input, label, level): the path distances raw and cleaned."""
    import mrlib
    from mrlib.errors import ClipTooShortError
    from mrlib.sampling.restyling import restyle, restyle_lengths

    raw, cleaned = mrlib.Sampler(fix_contacts=False), mrlib.Sampler()
    rows = []
    for name, clip in clips.items():
        try:
            restyle_lengths(model, clip.resampled_frames(model.fps), name)
        except ClipTooShortError as e:
            print(f"refused: {e}")
            continue
        for k in levels:
            for lab in model.labels:
                row = {"input": name, "label": lab, "level": k}
                for key, sampler in (("raw", raw), ("clean", cleaned)):
                    m = restyle(model, clip, lab, k, seed=0, sampler=sampler, body=body)
                    row[key] = summary(path_distances(m, clip))
                rows.append(row)
    return rows


def table(rows_by_model: dict) -> str:
    cols = list(BOUNDS)
    out = ["| model | input | label | k | " + " | ".join(f"raw {c}" for c in cols) + " | "
           + " | ".join(f"clean {c}" for c in cols) + " |",
           "|" + "---|" * (4 + 2 * len(cols))]  # fmt: skip
    for model, rows in rows_by_model.items():
        for r in rows:
            cells = [f"{r[key][c]:.1f}" for key in ("raw", "clean") for c in cols]
            out.append(f"| {model} | {r['input']} | {r['label']} | {r['level']} | "
                       + " | ".join(cells) + " |")  # fmt: skip
        worst = [f"**{max(r[key][c] for r in rows):.1f}**" for key in ("raw", "clean")
                 for c in cols]  # fmt: skip
        ok = {key: sum(holds(r[key]) for r in rows) for key in ("raw", "clean")}
        out.append(f"| {model} | worst of {len(rows)} rows (within bounds: raw {ok['raw']}, "
                   f"clean {ok['clean']}) | | | " + " | ".join(worst) + " |")  # fmt: skip
    return "\n".join(out)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--levels", default="2,d",
                   help="levels k, comma-separated; d: the model's default L-2 [2,d]")  # fmt: skip
    add_iterations_arg(p, "train smoke-test models of this budget (presets.quick) instead")
    p.add_argument("--threads", type=int, default=1, help="torch intra-op threads [1]")
    p.add_argument("--json", type=Path, default=None, help="also write the rows here")
    a = p.parse_args(argv)
    set_threads(a.threads)

    import mrlib
    from mrlib.sampling.restyling import restyle_level

    body = mrlib.load_body_model()
    found = models(a.iterations, body)
    clips = inputs(next(iter(found.values())).fps)
    rows_by_model = {}
    t = time.perf_counter()
    for name, model in found.items():
        d = restyle_level(model, None)
        levels = sorted({d if v.strip() == "d" else int(v) for v in a.levels.split(",")})
        rows_by_model[name] = sweep(model, clips, levels, body)
    print(f"\nroot path of the restyled clip against the input's, by time (cm); "
          f"{time.perf_counter() - t:.0f} s\n")  # fmt: skip
    print(table(rows_by_model))
    if a.json is not None:
        write_json("restyle_path", {"bounds_cm": BOUNDS, "rows": rows_by_model}, a.json)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
