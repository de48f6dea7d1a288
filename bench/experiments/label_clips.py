"""A label model's training clips and the sampler measures that ``fine_noise.py`` and
``guidance.py`` compare samples by (formerly ``bench/tutorial_checkpoint.py``)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from mrlib.metrics import (
    condition_fidelity,
    coverage,
    global_diversity,
    local_diversity,
    metric_features,
)
from mrlib.metrics.plausibility import foot_skating, mean_jerk, motion_kinematics
from mrlib.model.trained import GenerativeModel
from mrlib.representation.features import features_to_motion
from mrlib.representation.motion import Motion
from mrlib.sampling.cleanup import cleanup_foot_contacts
from mrlib.sampling.constraints import part_fidelity
from mrlib.sampling.generation import generate
from mrlib.sampling.sampler import Sampler


class LabelClips:
    """A label model's training clips by label, with what the sampler benchmarks compare
    samples against: the clips' metric features, and jerk and skating of any motion."""

    def __init__(self, model: GenerativeModel, body) -> None:
        self.body, self.fps = body, model.fps
        self.clips: dict[str, Motion] = {
            model.labels[model.clip_labels[k]]: features_to_motion(x, model.fps, betas=model.betas)
            for k, x in enumerate(model.features)
        }
        self.refs = {lab: metric_features(m) for lab, m in self.clips.items()}
        self.own_jerk = {lab: self.jerk(m) for lab, m in self.clips.items()}

    def jerk(self, m: Motion) -> float:
        """Mean joint jerk (m/s^3)."""
        return mean_jerk(motion_kinematics(m, self.body)[0], self.fps)

    def skating(self, m: Motion) -> float:
        """Share of contact vertex-frames sliding above the threshold."""
        return foot_skating(motion_kinematics(m, self.body)[1], m.contacts, self.fps)[1]

    def measure(
        self, model: GenerativeModel, samples: int, sampler: Sampler | None = None
    ) -> dict[str, float]:
        """``samples`` samples per label of twice the label's clip (seed 0) drawn with
        ``sampler``'s fine noise and guidance, raw and after the foot-contact clean-up; every
        figure is the mean over the labels, except ``worst_part`` (the lowest per-part
        fidelity). Jerk is over the label's own clip's; the rest is of the cleaned samples
        against the label's clip, but ``*_raw``."""
        rows = []
        for lab, clip in self.clips.items():
            raw = generate(model, lab, length=2 * clip.num_frames, seed=0, num=samples,
                           sampler=replace(sampler or Sampler(), fix_contacts=False))  # fmt: skip
            clean = [cleanup_foot_contacts(m, self.body) for m in raw]
            f = [metric_features(m) for m in clean]
            ref = self.refs[lab]
            part = part_fidelity(clean, model, {"upper": lab, "lower": lab})
            rows.append({
                "jerk_raw": np.mean([self.jerk(m) for m in raw]) / self.own_jerk[lab],
                "jerk_clean": np.mean([self.jerk(m) for m in clean]) / self.own_jerk[lab],
                "coverage": coverage(f, ref), "coverage_eps1": coverage(f, ref, eps=1.0),
                "global_div": global_diversity(f, ref), "local_div": local_diversity(f, ref),
                "fidelity": condition_fidelity([(h, lab) for h in f], self.refs),
                "upper": part["upper"], "lower": part["lower"],
                "skating_raw": np.mean([self.skating(m) for m in raw]),
                "skating_clean": np.mean([self.skating(m) for m in clean]),
            })  # fmt: skip
        out = {k: float(np.mean([r[k] for r in rows])) for k in rows[0]}
        out["worst_part"] = float(min(min(r["upper"], r["lower"]) for r in rows))
        return out
