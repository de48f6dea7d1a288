"""The reference runs a refactor of the training or sampling code must reproduce bit for
bit, as one command, and their digests.

In ``--out``, on one torch thread: ``label`` (``data_samples/*.npz``, ``demo`` preset cut
to 4 levels, 40 iterations per block), ``tutorial`` (4 levels, 12 iterations, a checkpoint
every 5, 15 fps), ``interrupted`` (``label`` stopped by a callback at block 2 iteration
13, as by Ctrl-C, then resumed), ``speech`` (a tiny co-speech run on synthetic bursts,
conditional critics and the mismatch term, stopped at block 2 iteration 4 and resumed),
then ``samples`` of ``label`` and ``speech_samples`` from a synthetic waveform.
``DIR/digest.json`` has the SHA-256 of every checkpoint tensor (at the stop and the end),
the losses.csv rows but their time, each sample's poses / trans / contacts, and the
machine: digests compare on one machine and thread count only. ~45 s on two cores::

    python bench/reference_runs.py --out /tmp/ref   # before the refactor; --out /tmp/new after
    python bench/reference_runs.py --compare /tmp/ref/digest.json /tmp/new/digest.json

``--compare`` prints a line per entry (same / differs) and ``identical`` or ``N differ``;
exit code 0 only when identical. ``--runs label --seed 1``: one run, another seed.
"""

from __future__ import annotations

import argparse
import csv
import hashlib
import json
import sys
import time
from pathlib import Path

from common import ROOT, machine, set_threads

RUNS = ("label", "tutorial", "interrupted", "speech", "samples", "speech_samples")
NEEDS = {"samples": "label", "speech_samples": "speech"}
SR, SPEECH_FPS = 16_000, 12.5


# -- digests ------------------------------------------------------------------------------------
def sha(x) -> str:
    """SHA-256 of a tensor or array: dtype, shape and bytes."""
    import torch

    t = torch.as_tensor(x).detach().cpu().contiguous()
    head = f"{t.dtype}{tuple(t.shape)}".encode()
    return hashlib.sha256(head + t.flatten().view(torch.uint8).numpy().tobytes()).hexdigest()


def checkpoint_digest(path: Path) -> dict[str, str]:
    """Every leaf of the checkpoint dict by its key path: tensors by :func:`sha`, short
    plain values as written, long ones by the SHA-256 of their text (``checksum``, a
    digest of all the rest, is left out)."""
    import torch

    from mrlib.model.checkpoint import load_checkpoint

    out: dict[str, str] = {}

    def walk(value, key: str) -> None:
        if isinstance(value, dict):
            for k in sorted(value, key=str):
                walk(value[k], f"{key}/{k}" if key else str(k))
        elif isinstance(value, (list, tuple)) and not all(isinstance(v, (str, int)) for v in value):
            for i, v in enumerate(value):  # lists of tensors / dicts; not of names or ints
                walk(v, f"{key}[{i}]")
        elif isinstance(value, torch.Tensor):
            out[key] = sha(value)
        else:
            text = repr(value)
            out[key] = text if len(text) <= 80 else hashlib.sha256(text.encode()).hexdigest()

    state = load_checkpoint(path)
    state.pop("checksum", None)
    walk(state, "")
    return out


def motions_digest(result, key: str = "") -> dict[str, str]:
    """poses / trans / contacts of every Motion in what a sampling call returns (a Motion,
    a list, ``(motion, [levels])``), by its position."""
    if isinstance(result, (list, tuple)):
        parts = [motions_digest(r, f"{key}{i}.") for i, r in enumerate(result)]
        return {k: v for part in parts for k, v in part.items()}
    return {
        key + name: "None" if getattr(result, name) is None else sha(getattr(result, name))
        for name in ("poses", "trans", "contacts")
    }


def run_digest(out: Path, name: str) -> dict[str, dict]:
    """A run's checkpoint, and its losses.csv rows but the ``time_s`` column."""
    with (out / "losses.csv").open(newline="") as f:
        rows = [{k: v for k, v in r.items() if k != "time_s"} for r in csv.DictReader(f)]
    losses = {f"row{i}": json.dumps(r) for i, r in enumerate(rows)}
    return {f"{name}/checkpoint": checkpoint_digest(out / "checkpoint.pt"),
            f"{name}/losses": losses}  # fmt: skip


# -- the runs -----------------------------------------------------------------------------------
def stop_at(block: int, iteration: int):
    """A callback that stops training like Ctrl-C after ``iteration`` of ``block`` (1-based)."""

    def callback(tr, _losses) -> None:
        if tr.block + 1 == block and tr.iteration == iteration:
            raise KeyboardInterrupt

    return callback


def bursts(seconds: float, seed: int):
    """A waveform at :data:`SR` of tone bursts (1-3 harmonics of 100-220 Hz) and pauses."""
    import numpy as np

    rng = np.random.default_rng(seed)
    wav, t = np.zeros(int(seconds * SR), np.float32), 0.2
    while t < seconds - 0.4:
        dur = rng.uniform(0.1, 0.35)
        a, b = int(t * SR), int((t + dur) * SR)
        tt, f0 = np.arange(b - a) / SR, rng.uniform(100, 220)
        tone = sum(np.sin(2 * np.pi * f0 * h * tt) / h for h in (1, 2, 3))
        wav[a:b] = rng.uniform(0.05, 0.4) * np.hanning(b - a) * tone
        t += dur + rng.choice([0.05, 0.1, 0.5])
    return wav


def speech_run(seed: int):
    """``(data, config)`` of the speech run: three paired clips (bursts, rule-based gestures
    on a standing base) and two unpaired ones as log-mel; conditional critics, mismatch."""
    import mrlib.speech as sp
    from mrlib.model.config import LossWeights, ModelConfig, TrainConfig
    from mrlib.representation.skeleton import UPPER_BODY_JOINTS
    from mrlib.speech.gestures import apply_offsets, gesture_offsets, loop_motion

    logmel = sp.SpeechFeatureExtractor(kind="logmel", n_mels=12, pitch=False)

    def clip(seconds, seed, paired):
        wav = bursts(seconds, seed)
        args = (f"clip{seed}", logmel(wav, SR), logmel.fps, logmel.frame_offset_s, len(wav) / SR)
        if not paired:
            return sp.SpeechClip(*args, None)
        T = round(seconds * SPEECH_FPS)
        base = sp.standing_base(seconds=2.0, fps=SPEECH_FPS, seed=seed)
        offsets = gesture_offsets(wav, SR, SPEECH_FPS, T, seed)
        motion = apply_offsets(loop_motion(base, T), offsets).replace(contacts=None)
        return sp.SpeechMotionPair(*args, None, motion=motion)

    pairs = [clip(s, k, True) for k, s in enumerate((2.4, 3.0, 2.7))]
    unpaired = [clip(s, 10 + k, False) for k, s in enumerate((3.5, 1.2))]
    data = sp.SpeechTrainingSet.from_clips(pairs, unpaired, logmel.config, fps=SPEECH_FPS)
    model = ModelConfig(num_levels=4, gen_hidden=(24,), disc_hidden=(24,), neighbour_radius=1,
                        film_joints=UPPER_BODY_JOINTS, critic_condition=True, critic_band="detail")  # fmt: skip
    loss = LossWeights(smooth=0.5, mismatch=1.0)
    return data, TrainConfig(model=model, block_size=2, block_iterations=(12, 10), n_critic=2,
                             mix_prob=0.5, critic_mixed="none", loss=loss, checkpoint_every=5,
                             log_every=1, seed=seed, lr=2e-3)  # fmt: skip


def reference_runs(out: Path, runs: set[str], seed: int) -> tuple[dict, dict]:
    """Train and sample ``runs`` in ``out``: ``(digests by entry, seconds by run)``."""
    import mrlib
    from mrlib.model.presets import training_config
    from mrlib.sampling.generation import reconstruct
    from mrlib.speech import SpeechTrainer, generate_from_audio, load_speech_model

    body, clips = mrlib.load_body_model(), sorted((ROOT / "data_samples").glob("*.npz"))
    label_cfg = training_config("demo", 40, 4, seed)
    digests, seconds = {}, {}

    def fit(d, cfg, **kw):  # a fresh label run on data_samples/ at the config's frame rate
        data = mrlib.TrainingSet.from_files(clips, fps=cfg.fps, body=body)
        return mrlib.train(data, cfg, d, body=body, progress=False, overwrite=True, **kw)

    def label(d):
        fit(d, label_cfg)
        digests.update(run_digest(d, "label"))

    def tutorial(d):
        fit(d, training_config("tutorial", 12, 4, seed).replace(checkpoint_every=5, fps=15.0))
        digests.update(run_digest(d, "tutorial"))

    def interrupted(d):
        res = fit(d, label_cfg.replace(checkpoint_every=9), callback=stop_at(2, 13))
        assert res.interrupted, "the callback did not stop the run"
        digests["interrupted@stop/checkpoint"] = checkpoint_digest(d / "checkpoint.pt")
        mrlib.train(None, None, d, resume=d / "checkpoint.pt", body=body, progress=False)
        digests.update(run_digest(d, "interrupted"))

    def speech(d):
        options = {"random_audio": "all"}
        tr = SpeechTrainer.start(*speech_run(seed), d, body=body, overwrite=True, options=options)
        assert tr.fit(progress=False, callback=stop_at(2, 4)).interrupted
        digests["speech@stop/checkpoint"] = checkpoint_digest(d / "checkpoint.pt")
        resumed = SpeechTrainer.start(None, None, d, resume=d / "checkpoint.pt", body=body)
        resumed.fit(progress=False)
        digests.update(run_digest(d, "speech"))

    def samples(_d):
        model = mrlib.load_model(out / "label" / "checkpoint.pt")
        a, b = model.labels[0], model.labels[-1]
        calls = {
            "label": dict(condition=a),
            "crossover": dict(condition=mrlib.Condition.crossover(a, b, 2)),
            "blend": dict(condition=mrlib.Condition.blend(a, b, 0.3)),
            "num3": dict(condition=b, num=3),
            "levels": dict(condition=a, levels=True),
            "sampler": dict(condition=b, sampler=mrlib.Sampler(fine_noise=0.5, guidance=1.0)),
            "raw": dict(condition=a, sampler=mrlib.Sampler(fix_contacts=False)),
        }
        for name, kw in calls.items():
            got = mrlib.generate(model, seed=0, body=body, **kw)
            digests[f"samples/{name}"] = motions_digest(got)
        digests["samples/reconstruct"] = motions_digest(reconstruct(model, 1, levels=True))

    def speech_samples(_d):
        model, wav = load_speech_model(out / "speech" / "checkpoint.pt"), bursts(3.0, 20)
        got = generate_from_audio(model, wav, sr=SR, seed=0, body=body)
        digests["speech_samples/audio"] = motions_digest(got)
        raw = mrlib.Sampler(fine_noise=0.5, fix_contacts=False)
        got = generate_from_audio(model, wav, sr=SR, seed=1, num=2, sampler=raw, levels=True)
        digests["speech_samples/raw_levels"] = motions_digest(got)

    for fn in (label, tutorial, interrupted, speech, samples, speech_samples):
        if fn.__name__ not in runs:
            continue
        t = time.perf_counter()
        fn(out / fn.__name__)
        seconds[fn.__name__] = round(time.perf_counter() - t, 1)
        print(f"{fn.__name__}: {seconds[fn.__name__]} s", flush=True)
    return digests, seconds


# -- compare ------------------------------------------------------------------------------------
def compare(a_path: Path, b_path: Path) -> int:
    """Print a line per entry of two digest files and the count that differ; 0 if none."""
    a, b = (json.loads(Path(p).read_text()) for p in (a_path, b_path))
    if (a["machine"], a["cpu_flags"]) != (b["machine"], b["cpu_flags"]):
        print("note: other machine, torch or thread count; digests compare on one only")
    differ = 0
    for name in sorted(set(a["entries"]) | set(b["entries"])):
        x, y = a["entries"].get(name), b["entries"].get(name)
        if x is None or y is None:
            line = f"missing in {'A' if x is None else 'B'}"
        elif x == y:
            line = f"same ({len(x)} keys)"
        else:
            keys = sorted(k for k in set(x) | set(y) if x.get(k) != y.get(k))
            line = f"differs: {len(keys)} of {len(x)} keys ({', '.join(keys[:4])}{', ...' * (len(keys) > 4)})"
        differ += not line.startswith("same")
        print(f"{name}: {line}")
    print("identical" if differ == 0 else f"{differ} differ")
    return int(differ > 0)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", type=Path, help="folder of the runs and digest.json")
    ap.add_argument("--compare", nargs=2, type=Path, metavar=("A", "B"), help="two digest.json")
    ap.add_argument("--runs", nargs="+", choices=RUNS, default=RUNS, help="[all]")
    ap.add_argument("--seed", type=int, default=0, help="the training seed of every run")
    args = ap.parse_args(argv)
    if args.compare:
        return compare(*args.compare)
    if args.out is None:
        ap.error("give --out DIR (to run) or --compare A B")
    runs = set(args.runs) | {NEEDS[r] for r in args.runs if r in NEEDS}
    set_threads(1)
    t = time.perf_counter()
    digests, seconds = reference_runs(args.out, runs, args.seed)
    info = Path("/proc/cpuinfo").read_text().splitlines() if Path("/proc/cpuinfo").exists() else []
    flags = next((ln.split(":", 1)[1].strip() for ln in info if ln.startswith("flags")), "")
    m = machine()
    record = {"machine": {k: m[k] for k in ("cpu", "arch", "torch", "numpy", "torch_threads")},
              "cpu_flags": flags, "seed": args.seed,
              "seconds": {**seconds, "total": round(time.perf_counter() - t, 1)},
              "entries": digests}  # fmt: skip
    path = args.out / "digest.json"
    path.write_text(json.dumps(record, indent=1, sort_keys=True) + "\n")
    print(f"{len(digests)} entries -> {path} ({record['seconds']['total']} s)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
