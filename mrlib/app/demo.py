"""The end-to-end demo behind ``make demo`` / ``mrlib demo``.

Runs on the synthetic clips in ``data_samples/`` (nothing to download), in six stages:

1. **load** the labelled clips, compute foot contacts, render them;
2. **retarget** one Bandai Namco BVH onto SMPL, if the dataset is found
   (``MRLIB_DATA_DIR``), and render it next to its contact labels;
3. **train** the multi-resolution GAN on the four clips: the ``preview`` preset
   (``mrlib.model.presets.preview``, minutes on two CPU cores) by default, any label
   preset (``demo``, ``tutorial``, ``paper``) with ``preset=``;
4. **sample** every label (feet planted by the contact clean-up, ``mrlib.sampling.cleanup``),
   export SMPL ``.npz`` and ``.bvh``, render each, and write an animated preview
   (``sample.gif``);
5. **crossover**: one label's coarse levels with another label's fine levels, rendered
   between the two pure labels with the same noise (``crossover.png``, ``crossover.gif``);
6. **evaluate** against the training clips: coverage, condition fidelity and foot
   skating of the model (cleaned, and raw beside it) next to the calibration rows (the
   training clip played twice, a frozen first frame), and the full table.

Everything goes to one output folder; ``summary.md`` there lists what was made. The
files are written in one ``mrlib.io.transaction.output_transaction`` (the model trains in a
scratch folder beside its own): all of them, or (a full disk, an error, Ctrl-C) none,
the folder as it was before.
"""

from __future__ import annotations

import dataclasses
import functools
import time
from pathlib import Path

import numpy as np

from mrlib.io.outputs import write_text
from mrlib.io.transaction import make_folders, output_transaction, when_written
from mrlib.model.presets import preview
from mrlib.progress import bar as progress_bar

__all__ = ["run_demo", "DATA_SAMPLES", "DEMO_FPS"]

DATA_SAMPLES = Path(__file__).resolve().parents[2] / "data_samples"
DEMO_FPS = preview().fps  # the default preset trains on the samples resampled to this rate
STAGES = ("load", "retarget", "train", "sample", "crossover", "evaluate")


class _Stages:
    """Prints ``[k/6] stage: ...`` lines with the time each stage took."""

    def __init__(self) -> None:
        self.t0 = time.perf_counter()
        self.times: dict[str, float] = {}
        self._name: str | None = None
        self._start = 0.0

    def start(self, name: str, what: str) -> None:
        self.end()
        self._name, self._start = name, time.perf_counter()
        print(f"[{STAGES.index(name) + 1}/{len(STAGES)}] {name}: {what}", flush=True)

    def end(self) -> None:
        if self._name is not None:
            self.times[self._name] = time.perf_counter() - self._start
            self._name = None

    @property
    def total(self) -> float:
        return time.perf_counter() - self.t0


def _bar(iterable, desc: str, total: int | None = None, unit: str = "it", enabled: bool = True):
    return progress_bar(
        iterable, desc=f"  {desc}", total=total, unit=unit, leave=False, enabled=enabled
    )


def _train_with_eta(data, cfg, out: Path, body, progress: bool = True):
    """``mrlib.training.trainer.train`` with one progress bar over all blocks: the ETA weighs each
    block's iterations by the frames its levels generate (the finer blocks cost more)."""
    from mrlib.model.pyramid import pyramid_lengths
    from mrlib.training.trainer import train

    L = cfg.model.num_levels
    lengths = np.array([pyramid_lengths(t, L, cfg.model.scale_factor) for t in data.lengths])
    cost = [float(lengths[:, levels].sum()) for levels in cfg.blocks]
    unit = [c / max(cost) for c in cost]
    total = sum(n * u for n, u in zip(cfg.block_iterations, unit, strict=True))
    bar = progress_bar(
        total=total, desc="  training", unit="", bar_format=_TRAIN_BAR, leave=False,
        enabled=progress,
    )  # fmt: skip
    done = {"work": 0.0}

    def callback(trainer, _last) -> None:
        b = trainer.block
        work = sum(n * u for n, u in zip(cfg.block_iterations[:b], unit[:b], strict=True))
        work += trainer.iteration * unit[b] if b < len(unit) else 0.0
        bar.update(work - done["work"])
        done["work"] = work
        bar.set_postfix_str(f"block {min(b + 1, len(unit))}/{len(unit)}", refresh=False)

    try:
        # the demo's own folder: a rerun replaces the model it trained before
        return train(data, cfg, out, body=body, progress=False, callback=callback, overwrite=True)
    finally:
        bar.close()


_TRAIN_BAR = "{desc}: {percentage:3.0f}%|{bar}| {elapsed}<{remaining}{postfix}"


def _all_or_none(fn):
    """Run ``fn`` in one output transaction: its files all written, or none."""

    @functools.wraps(fn)
    def wrapper(*args, **kwargs):
        with output_transaction():
            return fn(*args, **kwargs)

    return wrapper


def _publish_model(scratch: Path, model_dir: Path) -> None:
    """Stage the run trained in ``scratch`` as ``model_dir``'s files (published with the
    demo's other files; an earlier demo's model there is replaced only then)."""
    from mrlib.io.transaction import current_transaction
    from mrlib.training.run import stage_run

    stage_run(current_transaction(), scratch, model_dir, overwrite=True)


@_all_or_none
def run_demo(
    out: str | Path = "outputs",
    *,
    preset: str = "preview",
    quick: bool = False,
    iterations: int | None = None,
    samples: int = 10,
    seed: int = 0,
    overwrite: bool = False,
    progress: bool = True,
) -> Path:
    """Run the demo, writing into ``out``; returns the path of ``summary.md``.

    Args:
        preset: ``"preview"`` (default; the clips at ``DEMO_FPS``), ``"demo"`` (30 fps),
            ``"tutorial"`` or ``"paper"`` (the clips at their own 30 fps).
        quick: a smoke-test budget (seconds; the results mean nothing).
        iterations: per-block iteration count, overriding the preset's.
        samples: evaluation samples per label.
        seed: training and sampling seed.
        overwrite: replace the files of an earlier demo run in ``out``; without it such
            a folder is refused before any work (``OutputExistsError``).
        progress: show progress (``mrlib.progress.bar``: a live bar on a terminal, one
            line per stage in a log).
    """
    import mrlib
    from mrlib.datasets.bandai import bandai_dir
    from mrlib.evaluation.evaluate import EvaluationSettings, evaluate_model
    from mrlib.model.presets import get_preset
    from mrlib.model.trained import load_model
    from mrlib.sampling.conditions import Condition
    from mrlib.sampling.generation import generate
    from mrlib.training.data import TrainingSet
    from mrlib.viz.meshes import evenly_spaced_frames, render_mesh_animation, render_meshes
    from mrlib.viz.plots import plot_evaluation, save_titled_image

    cfg = get_preset(preset)
    its = 10 if quick else iterations
    if its is not None:
        cfg = cfg.replace(block_iterations=(its,) * cfg.num_blocks, checkpoint_every=0)
    cfg = dataclasses.replace(cfg, seed=seed)
    fps = cfg.fps  # the preset's rate; None: the clips' own
    n_eval = 2 if quick else samples

    out = Path(out)
    check_demo_folder(out, overwrite=overwrite)
    make_folders(out)
    stages = _Stages()
    lines = ["# mrlib demo", ""]
    body = mrlib.load_body_model()

    # 1. the labelled training clips
    files = sorted(DATA_SAMPLES.glob("*.npz"))
    stages.start("load", f"{len(files)} synthetic training clips from {DATA_SAMPLES.name}/")
    clips = []
    for p in _bar(files, "loading and rendering", unit="clip", enabled=progress):
        c = mrlib.load_motion(p, fps=fps)
        c = c.replace(contacts=mrlib.representation.foot_contacts(c, body))
        img = render_meshes(c, body, frames=evenly_spaced_frames(len(c), 5))
        save_titled_image(
            img,
            f"training clip '{c.label}' (synthetic, contacts in red)",
            out / f"train_{c.label}.png",
        )
        clips.append(c)
    lines += ["## Training clips (synthetic, `data_samples/`)", ""]
    lines += [
        f"- `{c.label}`: {c.num_frames} frames @ {c.fps:g} fps -> `train_{c.label}.png`"
        for c in clips
    ]

    # 2. retargeting a real capture, when a Bandai Namco clip is on disk (a local copy, or
    # mrlib's cache after `mrlib data fetch bandai`); the demo itself downloads nothing
    bvh = bandai_dir() / "data" / "dataset-1_walk_happy_001.bvh"
    if bvh.exists():
        stages.start("retarget", f"{bvh.name} onto SMPL")
        t = time.perf_counter()
        real = mrlib.load_motion(bvh)
        real = real.replace(contacts=mrlib.representation.foot_contacts(real, body))
        dt = time.perf_counter() - t
        err = real.meta["retarget_error_mean_cm"]
        img = render_meshes(real, body, frames=evenly_spaced_frames(len(real), 6))
        save_titled_image(
            img,
            f"{bvh.name} retargeted onto SMPL ({err:.1f} cm mean joint error)",
            out / "retargeted_bvh.png",
        )
        print(f"  retargeted in {dt:.2f} s, mean joint error {err:.2f} cm")
        lines += ["", "## Retargeting", ""]
        lines.append(
            f"- `{bvh.name}` -> SMPL in {dt:.2f} s, mean joint error {err:.2f} cm "
            "-> `retargeted_bvh.png`"
        )
    else:
        stages.start(
            "retarget",
            f"skipped: no Bandai Namco clip at {bvh.parent} (`mrlib data fetch bandai` "
            "fetches the clips, or set MRLIB_DATA_DIR to a copy)",
        )

    # 3. training
    stages.start(
        "train",
        f"'{preset}' preset, {cfg.model.num_levels} levels in blocks of {cfg.block_size}, "
        f"iterations per block {cfg.block_iterations}, clips at {clips[0].fps:g} fps",
    )
    data = TrainingSet.from_motions(clips, body=body)
    from mrlib.io.transaction import current_transaction

    scratch = current_transaction().scratch_folder(out / "model")
    res = _train_with_eta(data, cfg, scratch, body, progress)
    model = load_model(res.checkpoint)
    _publish_model(scratch, out / "model")
    print(f"  trained in {res.wall_time_s:.0f} s -> {out / 'model' / 'checkpoint.pt'}")
    lines += ["", "## Training", ""]
    lines.append(
        f"- `{preset}` preset: {cfg.model.num_levels} levels, iterations per block "
        f"{cfg.block_iterations}, {res.wall_time_s:.0f} s -> `model/checkpoint.pt`"
    )

    # 4. sampling every label
    length = 2 * clips[0].num_frames
    stages.start("sample", f"every label, {length} frames each (twice the training length)")
    lines += ["", "## Samples", ""]
    make_folders(out / "samples")
    pure = {}
    for lab in _bar(model.labels, "sampling and rendering", unit="label", enabled=progress):
        m = generate(model, lab, length=length, seed=seed)
        pure[lab] = m
        mrlib.save_motion(m, out / "samples" / f"{lab}.npz")
        mrlib.save_motion(m, out / "samples" / f"{lab}.bvh")
        img = render_meshes(m, body, frames=evenly_spaced_frames(len(m), 6))
        save_titled_image(img, f"generated '{lab}' (seed {seed})", out / f"sample_{lab}.png")
        lines.append(f"- `{lab}`: `samples/{lab}.npz`, `samples/{lab}.bvh`, `sample_{lab}.png`")
    render_mesh_animation(
        list(pure.values()),
        out / "sample.gif",
        body,
        seconds=4.0,
        titles=[f"'{lab}'" for lab in pure],
        spacing=1.2,
        window_size=(220 * len(pure), 360),
        progress=progress,
    )
    lines.append("- animated preview of one sample per label: [`sample.gif`](sample.gif)")

    # 5. crossover
    L = model.num_levels
    coarse, fine = (
        ("walk_sad", "walk_happy")
        if {"walk_sad", "walk_happy"} <= set(model.labels)
        else (model.labels[0], model.labels[-1])
    )
    split = L // 2
    stages.start("crossover", f"'{coarse}' at levels 1-{split}, '{fine}' at levels {split + 1}-{L}")
    mix = generate(model, Condition.crossover(coarse, fine, split), length=length, seed=seed)
    mrlib.save_motion(mix, out / "samples" / "crossover.npz")
    mrlib.save_motion(mix, out / "samples" / "crossover.bvh")
    img = render_meshes(mix, body, frames=evenly_spaced_frames(len(mix), 6))
    save_titled_image(
        img,
        f"crossover: '{coarse}' at levels 1-{split} (coarse), '{fine}' at levels {split + 1}-{L} (fine)",
        out / "crossover.png",
    )
    render_mesh_animation(
        [pure[coarse], mix, pure[fine]],
        out / "crossover.gif",
        body,
        seconds=4.0,
        titles=[f"'{coarse}'", f"{coarse} 1-{split} + {fine} {split + 1}-{L}", f"'{fine}'"],
        window_size=(720, 360),
        progress=progress,
    )
    lines.append(
        f"- crossover `{coarse}` (levels 1-{split}) + `{fine}` (levels {split + 1}-{L}): "
        "`samples/crossover.npz`, `crossover.png`, and beside the two pure labels with "
        "the same noise: [`crossover.gif`](crossover.gif)"
    )

    # 6. evaluation
    stages.start("evaluate", f"{n_eval} samples per label against the training clips")
    result = evaluate_model(
        model,
        settings=EvaluationSettings(num_samples=n_eval, seed=seed),
        body=body,
        progress=progress,
        contacts="both",
    )
    result.save(out / "evaluation")
    plot_evaluation(result, out / "evaluation" / "evaluation.png")
    lines += ["", "## Quality at a glance", "", headline_table(result), ""]
    lines += [
        "Samples are shown after the foot-contact clean-up (`mrlib.sampling.cleanup`: analytic leg IK "
        "that plants each foot while it is labelled in contact); `ours (raw)` is the "
        "generator's own output. "
        "Read the model's rows against the calibration rows: the training clip played twice "
        "is what real motion scores (full coverage, the capture's own foot sliding), a "
        "frozen first frame what a model that does not move scores. Condition fidelity: "
        "share of samples whose nearest training clip has the label asked for (chance "
        f"{100 / len(model.labels):.0f} %). Full table below and in `evaluation/`.",
        "",
        result.to_markdown(),
        "",
    ]
    stages.end()
    lines += ["## Time per stage", ""]
    lines += [f"- {name}: {s:.1f} s" for name, s in stages.times.items()]
    lines.append(f"- total: {stages.total:.0f} s")
    summary = out / "summary.md"
    write_text(summary, "\n".join(lines) + "\n", overwrite=True)
    print()
    print(headline_table(result))
    when_written(lambda: print(f"\ndone in {stages.total:.0f} s: see {summary}"))
    return summary


# what a demo run writes at the top of its folder (file names, folders, patterns)
DEMO_OUTPUTS = ("summary.md", "model", "samples", "evaluation", "sample.gif", "crossover.gif",
                "crossover.png", "retargeted_bvh.png", "train_*.png", "sample_*.png")  # fmt: skip


def check_demo_folder(out: Path, *, overwrite: bool) -> None:
    """Refuse ``out`` when it holds an earlier demo run's files and ``overwrite`` is off:
    the demo replaces a whole run, so it asks before it starts, not at its first write.
    Other files in ``out`` are left alone either way."""
    from mrlib.io.outputs import OutputError, OutputExistsError

    if out.exists() and not out.is_dir():
        raise OutputError(out, "is not a folder; --out takes a folder")
    if overwrite or not out.is_dir():
        return
    for pattern in DEMO_OUTPUTS:
        found = sorted(out.glob(pattern))
        if found:
            raise OutputExistsError(
                found[0],
                "an earlier demo run's output; pass --overwrite to replace that run, "
                "or choose another --out",
            )


def headline_table(result) -> str:
    """Coverage, condition fidelity and foot skating per method (mean over labels),
    the model first and then the calibration rows, as a Markdown table."""
    eps = (result.settings.eps, result.settings.tight_eps)
    keys = (
        ("coverage_pct", f"Coverage eps {eps[0]:g} %", "{:.1f}"),
        ("coverage_tight_pct", f"Coverage eps {eps[1]:g} %", "{:.1f}"),
        ("cond_fidelity_pct", "Cond. fidelity %", "{:.1f}"),
        ("skate_pct", "Foot skating %", "{:.1f}"),
        ("skate_speed", "Skate speed m/s", "{:.3f}"),
    )
    rows = ["| | " + " | ".join(h for _, h, _ in keys) + " |", "|---|" + "---:|" * len(keys)]
    for d in result.summary():
        vals = [
            f.format(d[f"{k}_mean"]) if np.isfinite(d[f"{k}_mean"]) else "–" for k, _, f in keys
        ]
        rows.append(f"| {d['method']} | " + " | ".join(vals) + " |")
    return "\n".join(rows)
