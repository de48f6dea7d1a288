"""Samples at the clips' frame rate: a model trained at a lower rate, its output raised.

The ``preview`` preset trains at 15 fps on 30-fps clips, so its samples are 15-fps clips. Raised
to the clips' 30 fps, they are scored against the 30-fps training clips: jerk (mean joint
jerk over the clips') and foot skating (share of contact vertex-frames faster than
``SKATE_SPEED_THRESHOLD``) beside the clips' own, for the two ways ``Motion.resample``
raises a rate: slerp and linear translation (``smooth=False``) and cubic splines
(``smooth=True``), both applied to the cleaned 15-fps samples, and ``Sampler(fps=30)``, which
raises the raw draw by splines and plants the feet at 30 fps. The same for the samples at the model's own 15 fps, scored against the
clips at 15 fps.

Uses the ``preview`` model of the four Bandai walks (``walk_{normal,happy,sad,angry}_001``,
``train_cached``: from mrlib's model cache, trained there first when missing, ~4 min), cleaned
samples (the default sampler), ``--samples`` per label of twice the clip's length.
``--split heldout``: ``--preset`` models of the five held-out styles of ``bench/heldout.py``
(training seeds ``--seeds``), for figures from walks no setting of
the raised output was chosen on.

    python bench/output_rate.py [--samples 10] [--seed 0] [--split dev|heldout] [--seeds 0,1]

``--restyle``: restyled takes instead of samples: the development walks' ``_002`` takes
(never seen in training; the normal walk's lasts too short) restyled by the same ``preview`` model to every label (the
default level, seed 0, cleaned), scored at the takes' 30 fps against each take: the
result at the model's rate raised by slerp and by splines, and ``mrlib.restyle``'s
default (the model's output raised by splines before the path and the feet are laid at
the take's rate).

``--path``: samples that walk a path (``mrlib.sampling.constraints.generate_on_path``,
``circle:2``, 10 s), the same ways as the plain samples.

``--continue``: the first 2 s of each training walk's ``_002`` take continued by 2 s
under its label (``continue_motion``; ``--samples`` seeds), the new frames
(from the prefix's last) scored the same ways; then where they slide (the first
``JOIN_S`` after the join, and after) and how many of their frames are in contact
(as the model chose per label; ``--match-contact-rate`` / ``--cut-contacts``: every label
at its contact rate / cut at 0.5).

``--preset demo --clip-fps 24``: the other direction, clips at a lower rate than the model's
(the 30-fps captures resampled to 24 fps by splines stand in for 24-fps captures; the
``demo`` model trains at 30 fps on them, development walks only), its samples lowered to
the clips' 24 fps the same three ways.
"""

from __future__ import annotations

import argparse
from dataclasses import replace

import numpy as np
from common import add_contact_reading_args

import mrlib
from mrlib.errors import ClipTooShortError
from mrlib.evaluation.results import contact_reading
from mrlib.metrics.plausibility import foot_skating, mean_jerk, motion_kinematics
from mrlib.sampling.restyling import restyle_lengths
from mrlib.training.data import TrainingSet
from mrlib.training.trainer import train_cached

CLIPS = ["walk_normal_001", "walk_happy_001", "walk_sad_001", "walk_angry_001"]
HELDOUT_STYLES = ("active", "childish", "chimpira", "feminine", "giant")  # bench/heldout.py's


def scores(m, body) -> tuple[float, float]:
    joints, feet = motion_kinematics(m, body)
    return mean_jerk(joints, m.fps), foot_skating(feet, m.contacts, m.fps)[1]


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--samples", type=int, default=10)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--split", choices=("dev", "heldout"), default="dev")
    ap.add_argument("--seeds", default="0", help="--split heldout: training seeds")
    ap.add_argument("--preset", choices=("preview", "demo"), default="preview")
    ap.add_argument("--restyle", action="store_true", help="restyled unseen takes, not samples")
    ap.add_argument("--path", action="store_true", help="samples on a path (circle:2, 10 s)")
    ap.add_argument("--continue", dest="cont", action="store_true", help="continued takes")
    add_contact_reading_args(ap, "--continue: ")
    ap.add_argument("--clip-fps", type=float, default=None,
                    help="the clips' rate (resampled from the capture's) [the capture's]")  # fmt: skip
    args = ap.parse_args(argv)
    if args.split == "heldout" and args.clip_fps:
        ap.error("--split heldout uses the models of bench/heldout.py at the clips' rate")
    mrlib.threads.use()
    body = mrlib.load_body_model()
    names = CLIPS if args.split == "dev" else [f"walk_{s}_001" for s in HELDOUT_STYLES]
    source = mrlib.datasets.bandai.tutorial_clips(names)
    if source.synthetic:
        print("the Bandai clips are not available here (MRLIB_DATA_DIR, cache or network)")
        return 1
    config = mrlib.get_preset(args.preset)
    full = {m.label: m for m in (mrlib.load_motion(p, body=body) for p in source.paths)}
    if args.clip_fps:
        full = {k: m.resample(args.clip_fps, smooth=True) for k, m in full.items()}
    for m in full.values():
        m.contacts = mrlib.representation.foot_contacts(m, body)
    low = {k: m.resample(config.fps, smooth=bool(args.clip_fps)) for k, m in full.items()}
    if args.split == "dev":
        data, seeds = TrainingSet.from_motions(list(low.values()), body=body), [None]
    else:  # built as bench/heldout.py builds it, so its cached models are the ones used
        clips = [mrlib.load_motion(p, fps=config.fps) for p in source.paths]
        data, seeds = TrainingSet.from_motions(clips, body=body), [int(s) for s in args.seeds.split(",")]  # fmt: skip
    for seed in seeds:
        cfg = config if seed is None else config.replace(seed=seed)
        model, _ = train_cached(data, cfg, body=body, progress=False)
        if seed is not None:
            print(f"\n## training seed {seed}")
        reading = mrlib.Sampler(match_contact_rate=args.match_contact_rate)
        print(f"contact labels: {contact_reading(model, reading)}")
        if args.restyle:
            restyled(model, args, body)
        elif args.path:
            on_path(model, full, args, body)
        elif args.cont:
            continued(model, names, args, body)
        else:
            table(model, full, low, args, body)
    return 0


def tally(got: dict, ways, cj: float, cs: float, ratio: dict, extra: dict) -> str:
    """A row's cells: each way's mean jerk over ``cj`` and skating in %; the ratio and the
    points over ``cs`` appended to ``ratio`` and ``extra``."""
    r = {w: np.mean(v, axis=0) for w, v in got.items()}
    for w in ways:
        ratio[w].append(r[w][0] / cj)
        extra[w].append(100 * (r[w][1] - cs))
    return " | ".join(f"{r[w][0] / cj:.2f} | {100 * r[w][1]:.1f}" for w in ways)


def on_path(model, full: dict, args, body) -> None:
    """Samples walking ``circle:2``, raised to the clips' rate three ways."""
    from mrlib.sampling.constraints import generate_on_path

    ways = ("slerp", "spline", "Sampler(fps)")
    print(
        f"model at {model.fps:g} fps; {args.samples} cleaned samples per label on circle:2, 10 s\n"
    )
    print("| label | clip skating % | " + " | ".join(f"{w}: jerk ratio | skating %" for w in ways) + " |")  # fmt: skip
    print("|---|---:|" + "---:|---:|" * len(ways))
    ratio, extra = {w: [] for w in ways}, {w: [] for w in ways}
    for label, clip in full.items():
        cj, cs = scores(clip, body)
        got = {w: [] for w in ways}
        for b in range(args.samples):
            kw = dict(seconds=10.0, seed=args.seed + b, body=body)
            low = generate_on_path(
                model, "circle:2", label, sampler=mrlib.Sampler(candidates=1), **kw
            )
            got["slerp"].append(scores(low.resample(clip.fps), body))
            got["spline"].append(scores(low.resample(clip.fps, smooth=True), body))
            high = generate_on_path(model, "circle:2", label,
                                    sampler=mrlib.Sampler(fps=clip.fps, candidates=1), **kw)  # fmt: skip
            got["Sampler(fps)"].append(scores(high, body))
        print(f"| {label} | {100 * cs:.1f} | {tally(got, ways, cj, cs, ratio, extra)} |")
    print("\nmean over labels, jerk over the clips' and skating minus the clips' (points): "
          + "; ".join(f"{w} {np.mean(ratio[w]):.2f}x, {np.mean(extra[w]):+.1f}" for w in ways))  # fmt: skip


def continued(model, names, args, body) -> None:
    """Unseen takes' first 2 s continued by 2 s, the ways of reaching the take's rate."""
    from mrlib.sampling.constraints import NoiseFit, continue_motion

    takes = mrlib.datasets.bandai.tutorial_clips([n.replace("_001", "_002") for n in names])
    ways = ("spline", "Sampler(fps)")
    seeds = range(args.seed, args.seed + args.samples)
    print(f"model at {model.fps:g} fps; {len(seeds)} continuations per take\n")
    print("| take | take jerk | take skating % | "
          + " | ".join(f"{w}: jerk ratio | skating %" for w in ways) + " |")  # fmt: skip
    print("|---|---:|---:|" + "---:|---:|" * len(ways))
    ratio, extra, joins = {w: [] for w in ways}, {w: [] for w in ways}, {}
    for path in takes.paths:
        take = mrlib.load_motion(path, body=body)
        if take.duration < 2.0:
            print(f"not continued: {take.name} lasts {take.duration:.1f} s")
            continue
        take.contacts = mrlib.representation.foot_contacts(take, body)
        cj, cs = scores(take, body)
        prefix, got = take.slice(0, round(2 * take.fps)), {w: [] for w in ways}
        frames = round(2 * model.fps)
        join = {"share": [], "near": [0, 0], "after": [0, 0]}  # the Sampler(fps) way
        for seed in seeds:
            kw = dict(seed=seed, body=body, fit=NoiseFit(progress=False))
            rate = mrlib.Sampler(match_contact_rate=args.match_contact_rate)
            low = continue_motion(model, prefix, frames, take.label,
                                  sampler=replace(rate, fps=model.fps), **kw)  # fmt: skip
            high = continue_motion(model, prefix, frames, take.label,
                                   sampler=replace(rate, fps=take.fps), **kw)  # fmt: skip
            k = prefix.num_frames - 1  # from the prefix's last frame on
            got["spline"].append(scores(low.resample(take.fps, smooth=True).slice(k), body))
            got["Sampler(fps)"].append(scores(high.slice(k), body))
            near_join(high.slice(k), body, join)
        cells = tally(got, ways, cj, cs, ratio, extra)
        print(f"| {take.name} | {cj:.1f} | {100 * cs:.1f} | {cells} |")
        joins[take.name] = (100 * take.contacts.mean(), join)
    print("\nmean over takes, jerk over the take's and skating minus the take's (points): "
          + "; ".join(f"{w} {np.mean(ratio[w]):.2f}x, {np.mean(extra[w]):+.1f}" for w in ways))  # fmt: skip
    print(f"\nWhere the new frames slide (Sampler(fps)): contact vertex-frames in the first "
          f"{JOIN_S:g} s after the join and after it, and the share of frames in contact\n")  # fmt: skip
    print("| take | in contact %, take / new frames | skating % first 0.25 s (contacts) | after |")
    print("|---|---|---|---|")
    for name, (take_share, j) in joins.items():
        near, after = (100 * a / max(n, 1) for a, n in (j["near"], j["after"]))
        print(f"| {name} | {take_share:.0f} / {100 * np.mean(j['share']):.0f} | {near:.0f} "
              f"({j['near'][1]}) | {after:.0f} ({j['after'][1]}) |")  # fmt: skip


JOIN_S = 0.25  # the new frames next to the prefix's last: where a continuation slides


def near_join(m, body, acc: dict) -> None:
    """Add ``m``'s (from the prefix's last frame on) sliding contact vertex-frames within
    ``JOIN_S`` of the join and after, and its share of frames in contact, to ``acc``."""
    from mrlib.metrics.plausibility import SKATE_SPEED_THRESHOLD, horizontal_speed

    _, feet = motion_kinematics(m, body)
    c = np.asarray(m.contacts) > 0.5
    slide = (horizontal_speed(np.asarray(feet), m.fps) > SKATE_SPEED_THRESHOLD) & c
    n = round(JOIN_S * m.fps)
    for key, part in (("near", slice(0, n)), ("after", slice(n, None))):
        acc[key][0] += int(slide[part].sum())
        acc[key][1] += int(c[part].sum())
    acc["share"].append(float(c[1:].mean()))


def restyled(model, args, body) -> None:
    """Unseen takes restyled to every label, the ways of reaching the take's rate."""
    takes = mrlib.datasets.bandai.tutorial_clips([n.replace("_001", "_002") for n in CLIPS])
    ways = ("slerp", "spline", "restyle default")
    print(f"model at {model.fps:g} fps; each take restyled to {len(model.labels)} labels\n")
    print("| take | frames, fps | take jerk | take skating % | "
          + " | ".join(f"{w}: jerk ratio | skating %" for w in ways) + " |")  # fmt: skip
    print("|---|---|---:|---:|" + "---:|---:|" * len(ways))
    ratio, extra = {w: [] for w in ways}, {w: [] for w in ways}
    for path in takes.paths:
        take = mrlib.load_motion(path, body=body)
        try:
            restyle_lengths(model, take.resampled_frames(model.fps), take.name)
        except ClipTooShortError as e:  # the normal walk's second take lasts 1 s
            print(f"not restyled: {e}")
            continue
        take.contacts = mrlib.representation.foot_contacts(take, body)
        cj, cs = scores(take, body)
        got = {w: [] for w in ways}
        for lab in model.labels:
            low = mrlib.restyle(model, take, lab, seed=args.seed, body=body,
                                sampler=mrlib.Sampler(fps=model.fps))  # fmt: skip
            got["slerp"].append(scores(low.resample(take.fps), body))
            got["spline"].append(scores(low.resample(take.fps, smooth=True), body))
            out = mrlib.restyle(model, take, lab, seed=args.seed, body=body)
            assert out.num_frames == take.num_frames and out.fps == take.fps
            got["restyle default"].append(scores(out, body))
        cells = tally(got, ways, cj, cs, ratio, extra)
        print(f"| {take.name} | {take.num_frames}, {take.fps:g} | {cj:.1f} | {100 * cs:.1f} | {cells} |")  # fmt: skip
    print("\nmean over takes, jerk over the take's and skating minus the take's (points): "
          + "; ".join(f"{w} {np.mean(ratio[w]):.2f}x, {np.mean(extra[w]):+.1f}" for w in ways))  # fmt: skip
    w = "restyle default"
    print(f"{w}, worst take: jerk {max(ratio[w]):.2f}x the take's, skating {max(extra[w]):+.1f} points over the take's")  # fmt: skip


def table(model, full: dict, low: dict, args, body) -> None:
    print(
        f"model at {model.fps:g} fps; clips at {next(iter(full.values())).fps:g} fps; "
        f"{args.samples} cleaned samples per label, seeds {args.seed}..\n"
    )
    ways = ("slerp", "spline", "Sampler(fps)")
    print(
        "| label | rate | clip jerk | clip skating % | "
        + " | ".join(f"{w}: jerk ratio | skating %" for w in ways)
        + " |"
    )
    print("|---|---|---:|---:|" + "---:|---:|" * len(ways))
    ratio = {w: [] for w in (*ways, "model")}
    extra = {w: [] for w in ways}
    for label, clip in full.items():
        length = 2 * low[label].num_frames
        kw = dict(length=length, seed=args.seed, num=args.samples, body=body)
        one = mrlib.Sampler(candidates=1)  # the ways of raising the rate on the same draws
        samples = mrlib.generate(model, label, sampler=one, **kw)  # cleaned at the model's rate
        at_rate = mrlib.generate(
            model, label, sampler=mrlib.Sampler(fps=clip.fps, candidates=1), **kw
        )
        scored = {
            "slerp": [scores(s.resample(clip.fps), body) for s in samples],
            "spline": [scores(s.resample(clip.fps, smooth=True), body) for s in samples],
            "Sampler(fps)": [scores(s, body) for s in at_rate],
            "model": [scores(s, body) for s in samples],
        }
        r = {k: np.mean(v, axis=0) for k, v in scored.items()}
        cj, cs = scores(clip, body)
        lj, ls = scores(
            low[label].replace(contacts=mrlib.representation.foot_contacts(low[label], body)), body
        )
        cells = " | ".join(f"{r[w][0] / cj:.2f} | {100 * r[w][1]:.1f}" for w in ways)
        print(f"| {label} | {clip.fps:g} fps | {cj:.1f} | {100 * cs:.1f} | {cells} |")
        print(f"| {label} | {model.fps:g} fps (model) | {lj:.1f} | {100 * ls:.1f} | {r['model'][0] / lj:.2f} | "
              f"{100 * r['model'][1]:.1f} |" + " – | – |" * (len(ways) - 1))  # fmt: skip
        for w in ways:
            ratio[w].append(r[w][0] / cj)
            extra[w].append(100 * (r[w][1] - cs))
        ratio["model"].append(r["model"][0] / lj)
    print(f"\nmean over labels at {clip.fps:g} fps, jerk over the clips' and skating minus the clips' (points): "
          + "; ".join(f"{w} {np.mean(ratio[w]):.2f}x, {np.mean(extra[w]):+.1f}" for w in ways)
          + f"; at the model's own {model.fps:g} fps: jerk {np.mean(ratio['model']):.2f}x")  # fmt: skip
    w = "Sampler(fps)"
    print(f"{w}, worst label: jerk {max(ratio[w]):.2f}x the clip's, skating {max(extra[w]):+.1f} points over the clip's")  # fmt: skip


if __name__ == "__main__":
    raise SystemExit(main())
