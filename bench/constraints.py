"""Constraints on a trained model: paths, keyframes, body parts, loops (mrlib.sampling.constraints).

Uses the `tutorial` model of ``bench/condition_control.py`` (4 Bandai walks:
normal / happy / sad / angry_001, 30 fps), trained there or here on first use and reused
after (``mrlib.training.trainer.train_or_reuse``, same folder). Prints, per constraint:

* **path**: a 20 s circle (r = 2 m) and a 20 s figure-eight (r = 2 m) for every walk
  label and ``--samples`` seeds, by ``bend`` (``generate_on_path``) and ``optimise``
  (noise optimisation, networks frozen: ``experiments/path_optimise.py``, reference
  code): pelvis-to-path distance off the line (mean / max), coverage of the
  label's training clip (30-frame windows, eps = 2) and foot skating (share of contact
  vertex-frames above the speed threshold) beside the training clip's;
* **keyframes**: in-betweening from the first frame of one walk to the last frame of
  another (full poses, root fixed at the start) plus a partial keyframe (right arm of a
  third walk) in the middle, 4 s: largest rotation and root errors at the keyframes and
  the jerk of the 1 s around each keyframe over the training clips' mean jerk, beside
  the same for unconstrained samples of the label (same seeds, same windows), without
  the noise fit, with it for the keyframes alone (``still=0``) and with its jerk term
  (``--key-steps`` Adam steps of the fit, ``--joint-jerk`` that term's weight of the
  joint positions; ``--no-clean`` leaves the feet unplanted);
* **parts**: upper body from one label, lower body from another, for every ordered
  pair, by ``film`` (``experiments/film_parts.py``, reference code) and ``splice``
  (``generate_parts``): condition fidelity per part; and the same measure
  on each label's second capture take, which the model never saw;
* **sharpen**: each label's samples with the noise fitted towards that label on one
  part (``mrlib.sampling.constraints.sharpen``, what ``generate_parts(..., sharpen=N)`` splices),
  for each of ``--sharpen-steps``: the part's fidelity by the measure the fit lowers
  (6D rotations) and by the part's joint positions in the body's frame, which it never
  sees; coverage (eps 2 and 1) and global diversity of the part against the label's
  clip; raw jerk over the clip's, raw foot skating, seconds per sample;
* **loop**: 4 s loops by ``circular`` (begun at the calmest frame, the default, and at
  the sample's frame 0) and ``crossfade``, and raw samples closed on themselves: seam
  step over the 95th percentile of the loop's own steps.

    python bench/constraints.py                 # seed 0 model, 3 samples per case
    python bench/constraints.py --samples 5 --threads 2
    python bench/constraints.py --only keyframes loop
    python bench/constraints.py --only parts --guidance 0.5
    python bench/constraints.py --only keyframes --ramp
    python bench/constraints.py --only keyframes --joint-jerk 0 --no-clean
    python bench/constraints.py --lr 2e-3 --only parts   # bench/condition_control.py --lr 2e-3's model
    python bench/constraints.py --only sharpen --samples 10 --sharpen-steps 0,20,50,100

Writes ``<run folder>/constraints.json`` (``constraints_guidance<G>.json`` with ``--guidance``).
"""

from __future__ import annotations

import argparse
import itertools
import json
import time
from dataclasses import replace

import numpy as np
import torch
from common import (
    TUTORIAL_CLIPS,
    add_iterations_arg,
    bandai_clips,
    bandai_dir,
    set_threads,
    trained_model,
    tutorial_run,
    with_iterations,
    write_json,
)
from experiments.film_parts import generate_film_parts
from experiments.path_optimise import generate_on_path_optimised

import mrlib
from mrlib.metrics import coverage, metric_features
from mrlib.metrics.plausibility import foot_skating, mean_jerk, motion_kinematics
from mrlib.model.presets import get_preset
from mrlib.representation.features import features_to_motion
from mrlib.sampling import constraints as C
from mrlib.sampling.generation import generate

SECTIONS = ("path", "keyframes", "parts", "sharpen", "loop")


def skate_share(m, body) -> float:
    _, feet = motion_kinematics(m, body)
    return foot_skating(feet, m.contacts, m.fps)[1]


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seed", type=int, default=0, help="training seed of the model [0]")
    ap.add_argument("--samples", type=int, default=3, help="seeds per case [3]")
    ap.add_argument("--threads", type=int, default=1)
    ap.add_argument("--steps", type=int, default=150,
                    help="noise optimisation steps of the paths' alternative [150]")  # fmt: skip
    ap.add_argument("--key-steps", type=int, default=C.keyframes.FIT_STEPS,
                    help=f"noise optimisation steps of the keyframes [{C.keyframes.FIT_STEPS}]")  # fmt: skip
    ap.add_argument("--still", type=float, default=C.keyframes.STILL,
                    help="keyframes: weight of the jerk term of the noise fit [mrlib's]")  # fmt: skip
    ap.add_argument("--guidance", type=float, default=None,
                    help="sample with this Sampler guidance [mrlib's]")  # fmt: skip
    ap.add_argument("--ramp", action="store_true",
                    help="keyframes: also condition the in-between on a label ramp from the "
                    "first keyframe's label to the last's")  # fmt: skip
    ap.add_argument("--joint-jerk", type=float, default=None,
                    help="keyframes: mrlib.sampling.constraints.keyframes.JOINT_JERK [mrlib's]")  # fmt: skip
    ap.add_argument("--no-clean", action="store_true",
                    help="keyframes: do not plant the feet of the in-betweens")  # fmt: skip
    ap.add_argument("--sharpen-steps", default=f"0,{C.SHARPEN_STEPS}",
                    help="sharpen: steps of the noise fit to compare, comma-separated "
                    f"[0,{C.SHARPEN_STEPS}]")  # fmt: skip
    ap.add_argument("--sharpen-push", action="store_true",
                    help="sharpen: the fit also pushes windows away from the other labels")  # fmt: skip
    ap.add_argument("--sharpen-margin", type=float, default=C.MARGIN,
                    help=f"sharpen: the hinge's margin [{C.MARGIN}]")  # fmt: skip
    ap.add_argument("--sharpen-prior", choices=("zero", "draw"), default=None,
                    help="sharpen: the noise fit's prior centred on 0 or on the draw "
                    "(mrlib.sampling.constraints.optimise.optimise_noise prior_centre) [mrlib's]")  # fmt: skip
    ap.add_argument("--lr", type=float, default=None,
                    help="the model trained with this learning rate "
                    "(bench/condition_control.py --lr) [the preset's]")  # fmt: skip
    add_iterations_arg(ap, "the model trained with these iterations per block "
                       "(bench/condition_control.py --iterations) [the preset's]")  # fmt: skip
    ap.add_argument("--only", nargs="+", choices=SECTIONS, default=list(SECTIONS),
                    help="run these sections only [all]")  # fmt: skip
    a = ap.parse_args()
    set_threads(a.threads)  # explicit: mrlib's own calls keep it (mrlib.threads)
    bandai_clips(TUTORIAL_CLIPS)  # exits before anything else when the data is missing
    cfg = get_preset("tutorial").replace(seed=a.seed)
    suffix = ""
    if a.lr is not None:
        cfg = cfg.replace(lr=a.lr)
        suffix += f"_lr{a.lr:g}"
    cfg, it_suffix = with_iterations(cfg, a.iterations)
    out = tutorial_run(cfg, "tutorial", suffix + it_suffix)  # bench/condition_control.py's run
    model, record, body = trained_model(cfg, TUTORIAL_CLIPS, out)
    print(f"model: {out} ({'reused' if record.reused else 'trained'})", flush=True)
    fps = model.fps
    train = {
        model.labels[model.clip_labels[k]]: features_to_motion(x, fps, betas=model.betas)
        for k, x in enumerate(model.features)
    }
    ref_feats = {lab: metric_features(m) for lab, m in train.items()}
    train_skate = {lab: skate_share(m, body) for lab, m in train.items()}
    train_jerk = float(
        np.mean([mean_jerk(motion_kinematics(m, body)[0], fps) for m in train.values()])
    )
    saved = out / (
        "constraints.json" if a.guidance is None else f"constraints_guidance{a.guidance:g}.json"
    )
    results: dict = json.loads(saved.read_text()) if saved.is_file() else {}
    a.sampler = mrlib.Sampler(guidance=0.0 if a.guidance is None else a.guidance)
    results.update(
        model=str(out), samples=a.samples, fine_noise=a.sampler.fine_noise,
        guidance=a.sampler.guidance,
    )  # fmt: skip
    seeds = range(a.samples)

    # -- paths ----------------------------------------------------------------------------
    if "path" in a.only:
        run_paths(model, body, a, ref_feats, train_skate, seeds, results)
    if "keyframes" in a.only:
        run_keyframes(model, body, a, train, train_jerk, seeds, results)
    if "parts" in a.only:
        run_parts(model, body, a, seeds, results)
    if "sharpen" in a.only:
        run_sharpen(model, body, a, results)
    if "loop" in a.only:
        run_loops(model, body, seeds, results, a.sampler)
    write_json("constraints", results, saved)
    return 0


def run_paths(model, body, a, ref_feats, train_skate, seeds, results) -> None:
    print("\n## Path (20 s)\n")
    print(
        "| path | method | pelvis to path mean / max (cm) | coverage | skating (training) | s per sample |"
    )
    print("|---|---|---|---|---|---|")
    results["path"] = []
    for spec in ("circle:2", "eight:2"):
        for method in ("bend", "optimise"):
            err, emax, cov, sk, tsk, secs = [], [], [], [], [], []
            for lab in model.labels:
                for s in seeds:
                    t0 = time.perf_counter()
                    if method == "bend":
                        m = C.generate_on_path(model, spec, lab, seconds=20.0, seed=s,
                                               sampler=a.sampler, body=body)  # fmt: skip
                    else:
                        m = generate_on_path_optimised(model, spec, lab, seconds=20.0, seed=s,
                                                       fit=C.NoiseFit(a.steps), sampler=a.sampler,
                                                       body=body)  # fmt: skip
                    secs.append(time.perf_counter() - t0)
                    e = C.path_error(m, spec, body)
                    err.append(e["lateral_mean_m"])  # off the line; "mean_m": off its schedule
                    emax.append(e["lateral_max_m"])
                    cov.append(coverage(metric_features(m), ref_feats[lab]))
                    sk.append(skate_share(m, body))
                    tsk.append(train_skate[lab])
            row = {
                "path": spec, "method": method, "mean_cm": 100 * float(np.mean(err)),
                "max_cm": 100 * float(np.max(emax)), "coverage": float(np.mean(cov)),
                "min_coverage": float(np.min(cov)), "skate": float(np.mean(sk)),
                "train_skate": float(np.mean(tsk)), "seconds": float(np.mean(secs)),
            }  # fmt: skip
            results["path"].append(row)
            print(f"| {spec} | {method} | {row['mean_cm']:.1f} / {row['max_cm']:.1f} | "
                  f"{100 * row['coverage']:.1f} % (min {100 * row['min_coverage']:.1f} %) | "
                  f"{100 * row['skate']:.1f} % ({100 * row['train_skate']:.1f} %) | {row['seconds']:.1f} |",
                  flush=True)  # fmt: skip


def run_keyframes(model, body, a, train, train_jerk, seeds, results) -> None:
    fps = model.fps
    print("\n## Keyframes (4 s in-between)\n")
    print(f"training clips' mean jerk {train_jerk:.1f} m/s^3\n")
    if a.joint_jerk is not None:
        C.keyframes.JOINT_JERK = a.joint_jerk
    clean = not a.no_clean
    key = "keyframes" + (f"_jointjerk{a.joint_jerk:g}" if a.joint_jerk is not None else "")
    key += "_noclean" if a.no_clean else ""
    print(f"JOINT_JERK {C.keyframes.JOINT_JERK:g}, feet {'planted' if clean else 'as generated'}\n")
    print(
        "| from -> to (label) | steps | still | max rotation error (deg) | max root error (cm) | jerk ratio at keyframes (start / middle / end) | unconstrained samples, same windows | the label's training clip | s per in-between |"
    )
    print("|---|---|---|---|---|---|---|---|---|")
    results[key] = []
    N = int(4 * fps)
    labs = model.labels
    for i, (a_lab, b_lab) in enumerate(itertools.permutations(labs, 2)):
        if i % 3:  # a third of the ordered pairs keeps the run short
            continue
        arm_from = train[labs[(labs.index(b_lab) + 1) % len(labs)]]
        kfs = [
            C.Keyframe.from_motion(train[a_lab], 0, 0),
            C.Keyframe(N // 2, arm_from.poses[arm_from.num_frames // 2],
                       joints=("right_shoulder", "right_elbow", "right_wrist")),
            C.Keyframe.from_motion(train[b_lab], -1, N - 1, root=False),
        ]  # fmt: skip
        h = int(fps // 2)

        def around(m, kfs=kfs, h=h):
            J = motion_kinematics(m, body)[0]
            return [
                mean_jerk(J[max(0, k.frame - h) : k.frame + h + 1], fps) / train_jerk for k in kfs
            ]

        control = np.asarray(
            [
                around(generate(model, b_lab, length=N, seed=s, sampler=a.sampler, body=body))
                for s in seeds
            ]  # fmt: skip
        )
        own = mean_jerk(motion_kinematics(train[b_lab], body)[0], fps) / train_jerk
        cases = [(0, 0.0, False), (a.key_steps, 0.0, False), (a.key_steps, a.still, False)]
        if a.ramp:
            cases.append((a.key_steps, a.still, True))
        for steps, still, ramp in cases:
            rot, pos, jr, dt = [], [], [], []
            for s in seeds:
                t0 = time.perf_counter()
                if ramp:
                    m = ramped_in_between(model, kfs, N, a_lab, b_lab, s, steps, still, body,
                                          replace(a.sampler, fix_contacts=clean))  # fmt: skip
                else:
                    m = C.generate_with_keyframes(model, kfs, N, b_lab, seed=s,
                                                  sampler=replace(a.sampler, fix_contacts=clean),
                                                  fit=C.KeyframeFit(steps, still=still),
                                                  body=body)  # fmt: skip
                dt.append(time.perf_counter() - t0)
                e = C.keyframe_errors(m, kfs)
                rot.append(e["rotation_deg"])
                pos.append(e["trans_cm"])
                jr.append(around(m))
            jr = np.asarray(jr)
            row = {"from": a_lab, "to": b_lab + (" (ramp)" if ramp else ""), "steps": steps,
                   "still": still,
                   "rotation_deg": float(np.max(rot)),
                   "trans_cm": float(np.max(pos)), "jerk_ratio_mean": jr.mean(0).tolist(),
                   "jerk_ratio_max": jr.max(0).tolist(),
                   "unconstrained_jerk_ratio_mean": control.mean(0).tolist(),
                   "label_clip_jerk_ratio": float(own), "seconds": float(np.mean(dt))}  # fmt: skip
            results[key].append(row)
            print(f"| {a_lab} -> {row['to']} | {steps} | {still:g} | {row['rotation_deg']:.2g} | {row['trans_cm']:.2g} | "
                  + " / ".join(f"{m_:.2f} (max {x_:.2f})" for m_, x_ in zip(jr.mean(0), jr.max(0), strict=True))
                  + " | " + " / ".join(f"{c_:.2f}" for c_ in control.mean(0))
                  + f" | {own:.2f} | {row['seconds']:.1f} |", flush=True)  # fmt: skip


def ramped_in_between(model, kfs, N, a_lab, b_lab, seed, steps, still, body, sampler):
    """``generate_with_keyframes`` with the condition eased over time from ``a_lab`` (the
    first keyframe's clip) to ``b_lab`` (the last's), the noise of their mean sigma."""
    from mrlib.sampling.constraints.common import fitted_motion, planted
    from mrlib.sampling.generation import (
        check_conditions,
        draw_noise,
        guided_weights,
        label_inputs,
        noise_amplitude,
    )

    Wa = mrlib.Condition.label(a_lab).weights(model)
    Wb = mrlib.Condition.label(b_lab).weights(model)
    lengths, _, _ = label_inputs(model, Wb, N, sampler)
    Ga, Gb = guided_weights(Wa, sampler), guided_weights(Wb, sampler)
    conds = []
    for i, T in enumerate(lengths):
        u = torch.linspace(0, 1, T)[:, None]
        u = u * u * (3 - 2 * u)
        conds.append(((1 - u) * Ga[i] + u * Gb[i])[None])
    amp = noise_amplitude(model, (Wa + Wb) / 2, sampler)
    noises = draw_noise(lengths, amp, seed, 1, model.device)
    loss_fn = C.keyframe_objective(model, kfs, N, still, body)
    m = fitted_motion(model, noises, check_conditions(model, conds, lengths), b_lab, "ramp",
                      loss_fn, C.NoiseFit(steps))  # fmt: skip
    m = planted(m, sampler, body)
    return C.apply_keyframes(C.align_to_keyframes(m, kfs, body), kfs)


def run_parts(model, body, a, seeds, results) -> None:
    labs = model.labels
    print("\n## Body parts (upper / lower from different labels)\n")
    methods = {"film": ("film", False), "splice": ("splice", False),
               "splice, gait-aligned": ("splice", True)}  # fmt: skip
    print("| upper | lower | " + " | ".join(f"{k}: fidelity upper / lower, coordination"
                                          for k in methods) + " |")  # fmt: skip
    print("|---|---|" + "---|" * len(methods))
    results["parts"] = []
    length = 2 * int(model.lengths[:, -1].max())
    for up, low in itertools.permutations(labs, 2):
        parts = {"upper": up, "lower": low}
        row = {"upper": up, "lower": low}
        cells = []
        for key, (method, align) in methods.items():
            if method == "film":
                ms = generate_film_parts(model, parts, length, seed=0, num_samples=a.samples,
                                         sampler=a.sampler, body=body)  # fmt: skip
            else:
                ms = C.generate_parts(model, mrlib.Condition.parts(parts, in_step=align),
                                      length=length, seed=0, num=a.samples, sampler=a.sampler,
                                      body=body)  # fmt: skip
            row[key] = C.part_fidelity(ms, model, parts)
            row[key]["coordination"] = float(np.mean([C.arm_leg_coordination(m, body) for m in ms]))
            f = row[key]
            cells.append(
                f"{100 * f['upper']:.1f} / {100 * f['lower']:.1f} %, {f['coordination']:.2f}"
            )
        results["parts"].append(row)
        print(f"| {up} | {low} | " + " | ".join(cells) + " |", flush=True)
    for key in methods:
        f = [[r[key]["upper"], r[key]["lower"]] for r in results["parts"]]
        co = [r[key]["coordination"] for r in results["parts"]]
        print(f"{key}: mean fidelity {100 * np.mean(f):.1f} %, worst part {100 * np.min(f):.1f} %; "
              f"arm-leg coordination mean {np.mean(co):.2f}, lowest {np.min(co):.2f}")  # fmt: skip
    clips = {model.labels[model.clip_labels[k]]: features_to_motion(x, model.fps, betas=model.betas)
             for k, x in enumerate(model.features)}  # fmt: skip
    print("training clips' arm-leg coordination: " + ", ".join(
        f"{lab} {C.arm_leg_coordination(m, body):.2f}" for lab, m in clips.items()))  # fmt: skip
    second_takes(model, body, results)


def run_sharpen(model, body, a, results) -> None:
    """Samples of each label fitted towards it on one part (module docstring)."""
    from mrlib.metrics import condition_fidelity, global_diversity
    from mrlib.sampling.constraints.compose import body_frame_joints
    from mrlib.sampling.constraints.sharpen import part_columns

    steps_list = [int(v) for v in a.sharpen_steps.split(",")]
    length = 2 * int(model.lengths[:, -1].max())
    clips = {model.labels[model.clip_labels[k]]: features_to_motion(x, model.fps, betas=model.betas)
             for k, x in enumerate(model.features)}  # fmt: skip
    refs = {lab: metric_features(m) for lab, m in clips.items()}
    pos = {lab: body_frame_joints(m, body) for lab, m in clips.items()}
    jerk = {lab: mean_jerk(motion_kinematics(m, body)[0], model.fps) for lab, m in clips.items()}
    centre = a.sharpen_prior or C.Sharpening().prior_centre
    how = "pulled and pushed" if a.sharpen_push else "pulled"
    print(f"\n## Sharpened parts ({a.samples} samples of {length} frames per label and part, "
          f"windows {how}, margin {a.sharpen_margin:g}, prior centred on {centre})\n")  # fmt: skip
    print("| part | label | steps | fidelity: rotations (fitted) | joint positions (not fitted) "
          "| coverage eps 2 / 1 | global div. | raw jerk | raw skating | s per sample |")  # fmt: skip
    print("|---|---|---:|---:|---:|---|---:|---:|---:|---:|")
    results["sharpen"] = []
    for part in ("upper", "lower"):
        cols = part_columns(part)
        js = [j for j in C.part_joints(part) if j > 0]
        pref = {lab: p[:, js].reshape(len(p), -1) for lab, p in pos.items()}
        for lab in model.labels:
            for steps in steps_list:
                t0 = time.perf_counter()
                raw = C.generate_sharpened(model, lab, (part,), length, seed=0, num=a.samples,
                                           sampler=replace(a.sampler, fix_contacts=False),
                                           fit=C.Sharpening(steps, a.sharpen_margin,
                                                            a.sharpen_push, centre))  # fmt: skip
                dt = (time.perf_counter() - t0) / a.samples
                ms = [mrlib.sampling.cleanup_foot_contacts(m, body) for m in raw]
                f = [metric_features(m)[:, cols] for m in ms]
                ref = refs[lab][:, cols]
                p = [body_frame_joints(m, body)[:, js].reshape(m.num_frames, -1) for m in ms]
                row = dict(
                    part=part, label=lab, steps=steps, seconds=dt,
                    fidelity=C.part_fidelity(ms, model, {part: lab})[part],
                    positions=condition_fidelity([(q, lab) for q in p], pref),
                    coverage=coverage(f, ref), coverage_eps1=coverage(f, ref, eps=1.0),
                    global_div=global_diversity(f, ref),
                    jerk=float(np.mean([mean_jerk(motion_kinematics(m, body)[0], model.fps)
                                        for m in raw])) / jerk[lab],
                    skating=float(np.mean([skate_share(m, body) for m in raw])),
                )  # fmt: skip
                results["sharpen"].append(row)
                print(f"| {part} | {lab} | {steps} | {100 * row['fidelity']:.1f} % | "
                      f"{100 * row['positions']:.1f} % | {100 * row['coverage']:.1f} / "
                      f"{100 * row['coverage_eps1']:.1f} % | {row['global_div']:.3f} | "
                      f"{row['jerk']:.2f} | {100 * row['skating']:.1f} % | {dt:.1f} |", flush=True)  # fmt: skip
    for steps in steps_list:
        rs = [r for r in results["sharpen"] if r["steps"] == steps]
        fid = [r["fidelity"] for r in rs]
        print(f"{steps} steps: parts >= 90 % {sum(v >= 0.9 for v in fid)} of {len(fid)}, "
              f"worst {100 * min(fid):.1f} %, mean {100 * np.mean(fid):.1f} %; by joint positions "
              f"mean {100 * np.mean([r['positions'] for r in rs]):.1f} %; global div. mean "
              f"{np.mean([r['global_div'] for r in rs]):.3f}")  # fmt: skip


def second_takes(model, body, results) -> None:
    """The same measure on capture the model never saw: each label's second Bandai take
    (``_002``), whole body and per part, against the model's training clips."""
    from mrlib.evaluation.fidelity import nearest_sequence_strip
    from mrlib.metrics.coverage import condition_fidelity
    from mrlib.metrics.windows import model_references

    print("\n### The measure on each label's second capture take (not trained on)\n")
    print("| take | frames | whole body | upper | lower | nearest label, whole body |")
    print("|---|---:|---:|---:|---:|---|")
    _, labels, feats = model_references(model)
    refs = {lab: np.concatenate([f for f, lb in zip(feats, labels, strict=True) if lb == lab])
            for lab in dict.fromkeys(labels)}  # fmt: skip
    results["second_takes"] = []
    for lab in model.labels:
        path = bandai_dir() / "data" / f"dataset-1_{lab}_002.bvh"
        if not path.is_file():
            continue
        m = mrlib.load_motion(path)
        m = m.replace(contacts=mrlib.representation.foot_contacts(m, body), label=lab)
        if m.num_frames < 30:
            continue
        whole = condition_fidelity([(metric_features(m), lab)], refs)
        part = C.part_fidelity([m], model, {"upper": lab, "lower": lab})
        near = nearest_sequence_strip(m, model).label_shares()
        top = max(near, key=near.get)
        results["second_takes"].append(
            dict(take=path.stem, frames=m.num_frames, whole=whole, **part)
        )
        print(f"| {path.stem} | {m.num_frames} | {100 * whole:.1f} % | {100 * part['upper']:.1f} % | "
              f"{100 * part['lower']:.1f} % | {top} ({100 * near[top]:.0f} %) |", flush=True)  # fmt: skip


def run_loops(model, body, seeds, results, sampler) -> None:
    fps, labs = model.fps, model.labels
    print("\n## Loops (4 s): seam step / 95th percentile of own steps\n")
    print("| label | circular | circular, begun at the sample's frame 0 | crossfade "
          "| raw sample closed on itself |")  # fmt: skip
    print("|---|---|---|---|---|")
    results["loop"] = []
    N = int(4 * fps)
    cases = {"circular": ("circular", "calm"), "circular_frame0": ("circular", "sample"),
             "crossfade": ("crossfade", "calm")}  # fmt: skip
    for lab in labs:
        row = {"label": lab}
        for key, (method, start) in cases.items():
            r = []
            for s in seeds:
                m = C.generate_loop(model, lab, N, seed=s, method=method, start=start,
                                    sampler=sampler, body=body)  # fmt: skip
                sm = C.loop_seam(m, body)
                r.append(sm["seam"] / sm["p95"])
            row[key] = r
        r = []
        for s in seeds:
            m = generate(model, lab, length=N, seed=s, sampler=sampler, body=body)
            step = m.trans[-1] - m.trans[-2]
            m.meta["loop_offset"] = (m.trans[-1] - m.trans[0] + step).tolist()
            sm = C.loop_seam(m, body)
            r.append(sm["seam"] / sm["p95"])
        row["raw"] = r
        results["loop"].append(row)
        print(f"| {lab} | " + " | ".join(
            f"{np.mean(row[k]):.2f} (max {np.max(row[k]):.2f})" for k in (*cases, "raw")
        ) + " |", flush=True)  # fmt: skip


if __name__ == "__main__":
    raise SystemExit(main())
