"""Named presets of ``TrainConfig`` (``PRESETS``): ``paper``, ``tutorial``, ``demo`` and
``preview`` for labels, ``speech_paper``, ``speech_tutorial`` and ``speech_demo`` for
speech, each next to the reasons for its values, so that a reader checks a preset against
the paper in one place; and the command line's overrides of a preset (``training_config``).

What the paper fixes (Moreno-Villamarin et al., CVMP 2024, Sec. 3-4): L = 8 levels for
labels (10 for speech), F = 4/3, FiLM embedding of size 8, WGAN-GP, Adam with lr 1e-4,
loss weights adv 1 / con 5 / rec 50 / smooth 5, blocks of two consecutive levels,
15000 iterations for the first block (levels 1-2) and 25000 for each other block, style
mixing on 90% of random generations.

What it leaves open, taken from GANimator (Li et al., SIGGRAPH 2022, its option parser
defaults and models/__init__.py): kernel size 5, reflect padding, four conv layers with
128, 256, 256 hidden channels (rounded up to a multiple of the joint count), LeakyReLU
0.2, skeleton neighbourhood radius 2, lambda_gp = 1, Adam betas = PyTorch's defaults
(0.9, 0.999), 5 critic steps per generator step, one sample per clip and step, noise
amplitudes from the data pyramid.

Our own choices (also open in the paper): the reconstruction and adversarial terms are
summed into one generator step (the paper's Eq. 11; GANimator takes a separate
reconstruction step); the smoothness term applies to the finer half of the levels
("finer temporal resolution levels", Sec. 3.4), the contact term to every level; the
reconstruction noise z*_1 is a draw of the random noise z_1 (N(0, sigma_1), shared by all
channels, as the paper describes z_i) rather than GANimator's full-channel N(0, 1).

Beyond the paper, on in the ``tutorial`` presets and off in ``paper``:

* conditional critics (``ModelConfig.critic_condition``, a projection discriminator,
  Miyato & Koyama 2018): with the paper's unconditional critics a label reaches random
  generations only through the reconstruction loss, and single-label samples drift to
  other labels' motion;
* a label term that sees only the detail band (``critic_band="detail"``), scoring every
  level of a mixed sample with the label that drove it (``critic_mixed="label"``);
* the detail-statistics term (``LossWeights.detail``): what makes a crossover's fine
  levels follow the fine label;
* for speech, the mismatch term (``LossWeights.mismatch``, Reed et al. 2016): what ties
  gestures to the audio rather than to any speech.

Every measured figure behind these choices is in ``docs/results.md``, with the command
that measures it (``bench/condition_control.py``, ``bench/speech_sync.py``,
``bench/demo_budget.py``).
"""

from __future__ import annotations

import dataclasses

from mrlib.model.config import (
    SPEECH_NUM_LEVELS,
    ConfigError,
    LossWeights,
    ModelConfig,
    TrainConfig,
)
from mrlib.representation.skeleton import UPPER_BODY_JOINTS

__all__ = [
    "paper",
    "tutorial",
    "demo",
    "preview",
    "speech_paper",
    "speech_tutorial",
    "speech_demo",
    "PRESETS",
    "PRESET_SUMMARIES",
    "preset_names",
    "describe_presets",
    "get_preset",
    "training_config",
    "block_iterations_for",
    "quick",
    "ganimator_mode",
]


def paper() -> TrainConfig:
    """The paper's label-conditioned setting (Sec. 3-4): L = 8, F = 4/3, 15000 iterations
    for levels 1-2 and 25000 for each further block, weights 1/5/50/5, Adam 1e-4."""
    return TrainConfig(
        model=ModelConfig(num_levels=8, scale_factor=4 / 3),
        loss=LossWeights(adv=1.0, con=5.0, rec=50.0, smooth=5.0, gp=1.0),
        block_size=2,
        block_iterations=(15000, 25000, 25000, 25000),
        lr=1e-4,
    )


def tutorial() -> TrainConfig:
    """A CPU budget for labels: the paper's 8 levels and losses, narrower networks (72/144/144
    hidden channels in the generators, 48/96/96 in the critics), 2 critic steps per generator
    step, a larger learning rate (5e-4: a few thousand iterations instead of 90000), 800
    iterations per block, conditional critics whose label term sees the detail band
    (``critic_band="detail"``), each level scored with the label that drove it
    (``critic_mixed="label"``), and the detail-statistics term at weight 100.

    Condition fidelity, crossover evidence, coverage and training time of this preset on
    four Bandai walks, over five training seeds and against its variants, are in
    ``docs/results.md`` (``python bench/condition_control.py --seed N``)."""
    return TrainConfig(
        model=ModelConfig(
            num_levels=8,
            scale_factor=4 / 3,
            gen_hidden=(72, 144, 144),
            disc_hidden=(48, 96, 96),
            critic_condition=True,
            critic_band="detail",
        ),
        block_size=2,
        block_iterations=(800, 800, 800, 800),
        lr=5e-4,
        n_critic=2,
        critic_mixed="label",
        loss=LossWeights(detail=100.0),
        checkpoint_every=200,
        log_every=10,
    )


def demo() -> TrainConfig:
    """The ``tutorial`` networks, losses and critics on a budget of minutes: one critic step
    per generator step, the critics' mismatch term at weight 2 (``LossWeights.mismatch``:
    real clips shown with a wrong label teach the critics which motion goes with which
    label; with the label term alone, samples of the Bandai happy walk were nearest the
    normal walk in 23-38 % of windows), the clips at 30 fps (``fps``) and 1200 / 800 /
    300 / 200 iterations for the four blocks: the coarse blocks, cheap per iteration,
    get most of them.

    Why 30 fps: at 15 fps (``preview``) a fast walk moves so far between frames that two
    captures of it half a frame apart already differ by 0.56-0.76 in the metric
    features (the tight coverage threshold is 1), and a foot contact that starts one frame
    late costs a whole unit; the fast walks lost coverage at eps 1 (the happy and angry
    development walks 0-51 % of windows). Why this budget: at 30 fps, 800 / 600 / 400 /
    300 iterations left the happy walk at 68-86 % fidelity and 84 % coverage on one seed;
    more coarse iterations kept coverage at 93.6-100 % for every development walk on both
    seeds. Both were chosen on
    the development walks; ``bench/heldout.py`` judges the preset on five styles it was
    not chosen on (``docs/results.md``, "Held-out styles")."""
    return tutorial().replace(
        block_iterations=(1200, 800, 300, 200),
        fps=30.0,
        n_critic=1,
        checkpoint_every=0,
        loss=LossWeights(detail=100.0, mismatch=2.0),
    )


def preview() -> TrainConfig:
    """``demo`` at 15 fps with 800 / 600 / 400 / 300 iterations per block: a first look in
    about two thirds of the time, what ``mrlib demo`` and the notebooks train. Slow walks
    are covered as with ``demo``; fast ones lose coverage at eps 1 (the angry and happy
    Bandai walks 0-51 %: ``docs/results.md``)."""
    return demo().replace(fps=15.0, block_iterations=(800, 600, 400, 300))


def speech_paper() -> TrainConfig:
    """The paper's speech setting (Sec. 3.2, 6): L = 10, F = 4/3, FiLM on the upper body,
    the label setting's optimiser and loss weights. The paper gives no iteration counts
    for speech; we reuse its label schedule (15000 iterations for levels 1-2, 25000 per
    further block). No speech mixing (``mix_prob = 0``)."""
    return TrainConfig(
        model=ModelConfig(
            num_levels=SPEECH_NUM_LEVELS, scale_factor=4 / 3, film_joints=UPPER_BODY_JOINTS
        ),
        block_size=2,
        block_iterations=(15000, 25000, 25000, 25000, 25000),
        mix_prob=0.0,
    )


def speech_tutorial() -> TrainConfig:
    """A CPU budget for a dozen ~10 s speech clips at 25 fps: L = 10 as in the paper,
    narrower networks, one critic step per generator step, 3900 iterations in all, and
    conditional critics that learn whether motion and speech go together.

    Why it departs from the paper: the learning rate is 2e-3, not 1e-4 (a few thousand
    iterations instead of 115000: at 1e-4 the arms are not yet reconstructed after 300);
    the smoothness weight is 0.5, not 5 (the smoothness term penalises the fast beat
    strokes that carry the syllable-level coupling); the critics are conditional on the
    speech, judged on the motion's detail band, with the mismatch term
    (``critic_condition=True``, ``critic_band="detail"``, ``LossWeights(mismatch=1)``),
    and their random generations take paired audio (``mrlib.speech.SpeechTrainer``).
    Measured synchrony against the paper's critics: ``docs/results.md``
    (``python bench/speech_sync.py``)."""
    return TrainConfig(
        model=ModelConfig(
            num_levels=SPEECH_NUM_LEVELS,
            scale_factor=4 / 3,
            gen_hidden=(48, 96, 96),
            disc_hidden=(48, 96, 96),
            film_joints=UPPER_BODY_JOINTS,
            critic_condition=True,
            critic_band="detail",
        ),
        block_size=2,
        loss=LossWeights(smooth=0.5, mismatch=1.0),
        block_iterations=(1500, 800, 600, 500, 500),
        lr=2e-3,
        n_critic=1,
        mix_prob=0.0,
        checkpoint_every=500,
        log_every=10,
    )


def speech_demo() -> TrainConfig:
    """``speech_tutorial``'s networks and losses on a budget of minutes on two CPU cores
    (700 iterations instead of 3900), for notebook 04's default run on a minute of BEAT2
    speech (``docs/results.md``, "Co-speech gestures", for what it learns there)."""
    return speech_tutorial().replace(block_iterations=(300, 150, 100, 75, 75), checkpoint_every=0)


def ganimator_mode(config: TrainConfig) -> TrainConfig:
    """``config`` for a GANimator-style baseline (one model per clip, Li et al. 2022): no
    style mixing (one label, nothing to mix) and unconditional critics (so no mismatch
    term either: no wrong label to show)."""
    model = dataclasses.replace(config.model, critic_condition=False)
    loss = dataclasses.replace(config.loss, mismatch=0.0)
    return config.replace(mix_prob=0.0, model=model, loss=loss)


PRESETS = {
    "paper": paper,
    "tutorial": tutorial,
    "demo": demo,
    "preview": preview,
    "speech_paper": speech_paper,
    "speech_tutorial": speech_tutorial,
    "speech_demo": speech_demo,
}


# One line per preset for ``--help`` (``mrlib train``, ``train-speech``, ``demo``); times
# are on 2 CPU cores, measured in ``docs/results.md``. Speech presets are ``speech_*``.
PRESET_SUMMARIES = {
    "paper": "the paper's: 15k + 3 x 25k iterations, full-width networks (use a GPU)",
    "tutorial": "CPU budget: narrower networks, 800 iterations per block (20-30 min)",
    "demo": "tutorial networks, 1200/800/300/200 iterations, 1 critic step (~6 min)",
    "preview": "demo at 15 fps, 800/600/400/300 iterations (~4 min; fast motion suffers)",
    "speech_paper": "the paper's speech setting: 10 levels, the label schedule (use a GPU)",
    "speech_tutorial": "CPU budget for ~12 speech clips of 10 s: 3900 iterations (20-30 min)",
    "speech_demo": "speech_tutorial's networks, 700 iterations (minutes; notebook 04's default)",
}


def preset_names(kind: str | None = None) -> list[str]:
    """Names of ``PRESETS`` in registry order: all of them, or those for ``kind``
    ``"labels"`` or ``"speech"`` (the ``speech_*`` ones)."""
    if kind not in (None, "labels", "speech"):
        raise ConfigError(f"kind must be 'labels' or 'speech', got {kind!r}")
    names = list(PRESETS)
    if kind is None:
        return names
    return [n for n in names if n.startswith("speech_") == (kind == "speech")]


def describe_presets(kind: str | None = None) -> str:
    """A ``--help`` block: one line per preset of ``kind`` (see :func:`preset_names`),
    its name, its fps when it sets one, and :data:`PRESET_SUMMARIES`."""
    names = preset_names(kind)
    width = max(map(len, names))
    lines = []
    for n in names:
        rate = PRESETS[n]().fps
        fps = f" [{rate:g} fps]" if rate is not None else ""
        lines.append(f"  {n:<{width}}  {PRESET_SUMMARIES.get(n, '')}{fps}".rstrip())
    return "\n".join(lines)


def get_preset(name: str) -> TrainConfig:
    """A named preset of ``PRESETS``: ``"paper"``, ``"tutorial"``, ``"demo"``,
    ``"preview"``, ``"speech_paper"``, ``"speech_tutorial"`` or ``"speech_demo"``."""
    if name not in PRESETS:
        raise ConfigError(f"unknown preset {name!r}; choose one of {sorted(PRESETS)}")
    return PRESETS[name]()


def block_iterations_for(iterations, num_blocks: int) -> tuple[int, ...]:
    """Iterations per block for a model of ``num_blocks`` blocks from one value for all
    blocks or one value per block."""
    its = (iterations,) if isinstance(iterations, int) else tuple(iterations)
    its = its * num_blocks if len(its) == 1 else its
    if len(its) != num_blocks:
        raise ConfigError(f"iterations has {len(its)} values but the model has {num_blocks} blocks")
    return tuple(int(n) for n in its)


def training_config(
    preset: str,
    iterations=None,
    levels: int | None = None,
    seed: int | None = None,
    device: str | None = None,
    lr: float | None = None,
) -> TrainConfig:
    """A preset with the command line's overrides applied (``mrlib train``).

    ``iterations``: one value for every block or one per block. Changing ``levels``
    keeps the preset's first-block budget for block 1 and its last block's budget for
    every other block. ``lr``: Adam's learning rate."""
    cfg = get_preset(preset)
    model = cfg.model if levels is None else dataclasses.replace(cfg.model, num_levels=levels)
    n = -(-model.num_levels // cfg.block_size)
    if iterations is not None:
        its = block_iterations_for(iterations, n)
    else:
        base = cfg.block_iterations
        its = tuple(base[0] if b == 0 else base[min(b, len(base) - 1)] for b in range(n))
    changes = {"model": model, "block_iterations": its}
    if seed is not None:
        changes["seed"] = seed
    if device is not None:
        changes["device"] = device
    if lr is not None:
        changes["lr"] = float(lr)
    return cfg.replace(**changes)


def quick(config: TrainConfig, iterations=10, hidden: tuple[int, ...] | None = None, **changes):
    """A smoke-test budget of ``config`` (what the notebooks run in CI): ``iterations``
    per block (one value, or one per block), no intermediate checkpoints, and, with
    ``hidden``, the same narrower widths for generators and critics. The numbers such a
    model gives mean nothing; it only runs every step. ``changes`` go to ``replace``."""
    model = config.model
    if hidden is not None:
        model = dataclasses.replace(model, gen_hidden=tuple(hidden), disc_hidden=tuple(hidden))
    its = block_iterations_for(iterations, config.num_blocks)
    return config.replace(model=model, block_iterations=its, checkpoint_every=0, **changes)
