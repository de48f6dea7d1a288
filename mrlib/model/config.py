"""Configuration of the networks and of training, with named presets.

The module is long because it is the table of presets next to the fields they set,
with the reasons for their values (below and in each preset's docstring), so that a
reader checks a preset against its fields and the paper in one place.

Configs are frozen dataclasses; make variants with ``dataclasses.replace`` (or
``TrainConfig.replace``) and save them as JSON next to every checkpoint
(``config_to_json`` / ``config_from_json``). ``PRESETS`` names them: ``paper``,
``tutorial`` and ``demo`` for labels, ``speech_paper`` and ``speech_tutorial`` for speech.

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
summed into one generator step (the paper's Eq. 6; GANimator takes a separate
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

Options that only studies used, and no preset, were removed after their study (their
findings stay in ``docs/results.md`` and ``docs/notes/``): ``REMOVED_OPTIONS`` lists them;
a saved config that still sets one to its old default loads, any other value is refused.

Every measured figure behind these choices is in ``docs/results.md``, with the command
that measures it (``bench/condition_control.py``, ``bench/speech_sync.py``,
``bench/demo_budget.py``).
"""

from __future__ import annotations

import dataclasses
import json
import math
from dataclasses import dataclass, field

import torch

from mrlib.errors import MrlibError, check_fields
from mrlib.representation.skeleton import UPPER_BODY_JOINTS

__all__ = [
    "ModelConfig",
    "LossWeights",
    "TrainConfig",
    "paper",
    "tutorial",
    "demo",
    "speech_paper",
    "speech_tutorial",
    "speech_demo",
    "SPEECH_NUM_LEVELS",
    "PRESETS",
    "PRESET_FPS",
    "PRESET_SUMMARIES",
    "preset_names",
    "describe_presets",
    "get_preset",
    "training_config",
    "block_iterations_for",
    "quick",
    "check_device",
    "ganimator_mode",
    "config_to_json",
    "config_from_json",
]


SPEECH_NUM_LEVELS = 10  # L for speech-guided synthesis (paper, Sec. 3.2)

# Bounds on network sizes, checked before anything is allocated (a config may come from
# a checkpoint someone else wrote): far above any preset, far below what would exhaust
# memory. The paper uses 8-10 levels, kernels of 5 and widths up to 256.
MAX_LEVELS = 32
MAX_KERNEL_SIZE = 65
MAX_HIDDEN = 2048  # channels of one hidden layer
MAX_HIDDEN_LAYERS = 16


class ConfigError(MrlibError, ValueError):
    """A configuration value is out of range or inconsistent."""


@dataclass(frozen=True)
class ModelConfig:
    """Networks of the multi-resolution GAN."""

    num_levels: int = 8  # L: 8 for labels, 10 for speech (paper, Sec. 3.2)
    scale_factor: float = 4 / 3  # F between consecutive levels
    kernel_size: int = 5  # temporal kernel of every conv (GANimator)
    gen_hidden: tuple[int, ...] = (128, 256, 256)  # hidden widths of g_i, rounded up to 24k
    disc_hidden: tuple[int, ...] = (128, 256, 256)  # hidden widths of D_i, rounded up to 24k
    neighbour_radius: int = 2  # skeleton conv sees joints within this many hops (Aberman 2020)
    film_dim: int = 8  # size of the condition embedding y_i (paper, Sec. 4.3)
    # Joints whose channels FiLM modulates; None = every channel. Speech uses the upper
    # body (mrlib.representation.skeleton.UPPER_BODY_JOINTS) so the legs are left to the generator.
    film_joints: tuple[int, ...] | None = None
    leaky_slope: float = 0.2
    # Critics that see the condition (projection discriminator, Miyato & Koyama 2018). The
    # paper's critics are unconditional: random generations are then judged only on
    # realism, and the label reaches them only through the reconstruction loss.
    critic_condition: bool = False
    # What the condition term of a conditional critic looks at: "full" = the critic's own
    # features of the whole signal; "detail" = features of a separate branch that sees only
    # the detail band ``x - box_K(x)`` (K = kernel_size), so the label is judged on detail.
    critic_band: str = "full"

    def __post_init__(self):
        check_fields(self, ConfigError)
        if not 1 <= self.num_levels <= MAX_LEVELS:
            raise ConfigError(
                f"num_levels must be in [1, {MAX_LEVELS}], got {self.num_levels} (the paper "
                "uses 8 for labels, 10 for speech)"
            )
        if not self.scale_factor > 1:
            raise ConfigError(f"scale_factor must be > 1, got {self.scale_factor}")
        if self.kernel_size % 2 != 1:
            raise ConfigError(f"kernel_size must be odd, got {self.kernel_size}")
        if not 1 <= self.kernel_size <= MAX_KERNEL_SIZE:
            raise ConfigError(
                f"kernel_size must be in [1, {MAX_KERNEL_SIZE}], got {self.kernel_size}"
            )
        if not self.gen_hidden or not self.disc_hidden:
            raise ConfigError("gen_hidden and disc_hidden need at least one layer")
        for name in ("gen_hidden", "disc_hidden"):
            widths = tuple(getattr(self, name))
            if len(widths) > MAX_HIDDEN_LAYERS or not all(1 <= w <= MAX_HIDDEN for w in widths):
                raise ConfigError(
                    f"{name} must have at most {MAX_HIDDEN_LAYERS} layers of 1 to {MAX_HIDDEN} "
                    f"channels, got {widths}"
                )
        if self.critic_band not in ("full", "detail"):
            raise ConfigError(f"critic_band must be 'full' or 'detail', got {self.critic_band!r}")
        if self.film_joints is not None:
            object.__setattr__(self, "film_joints", tuple(int(j) for j in self.film_joints))
            if any(not 0 <= j < 24 for j in self.film_joints):
                raise ConfigError(
                    f"film_joints must be SMPL joint ids in [0, 24), got {self.film_joints}"
                )
        object.__setattr__(self, "gen_hidden", tuple(self.gen_hidden))
        object.__setattr__(self, "disc_hidden", tuple(self.disc_hidden))


@dataclass(frozen=True)
class LossWeights:
    """Weights of the generator objective (paper Eq. 6) and of the gradient penalty."""

    adv: float = 1.0
    con: float = 5.0  # contact consistency, velocities in m/s
    rec: float = 50.0
    smooth: float = 5.0  # joint positions in metres
    gp: float = 1.0  # GANimator's lambda_gp (the paper does not give it)
    # Conditional critics only (beyond the paper): weight of a mismatch term in the critic
    # loss, E[D(real, wrong condition)] - E[D(real, own condition)] (the "real data, wrong
    # text" negatives of Reed et al., ICML 2016). It teaches the critic whether motion and
    # condition go together, not only whether each looks real. 0: off; left out of a
    # label run with one label (no wrong label to show).
    mismatch: float = 0.0
    # Labels only (beyond the paper): weight of a detail-statistics term on random
    # generations. At every level from 2 on, the per-channel RMS of the detail the level
    # adds (``PackedLevels.level_band``) is pulled, by an L1 penalty, to the mean of the
    # training clips of the label that drives the level: a style as channel statistics
    # (Gatys et al. 2016; Huang & Belongie 2017), so a crossover's fine levels carry the
    # fine label's amount of detail per joint. 0: off.
    detail: float = 0.0

    def __post_init__(self):
        check_fields(self, ConfigError)
        for name in ("adv", "con", "rec", "smooth", "gp", "mismatch", "detail"):
            if getattr(self, name) < 0:
                raise ConfigError(f"loss weight {name} must be >= 0, got {getattr(self, name)}")


@dataclass(frozen=True)
class TrainConfig:
    """Block-wise adversarial training."""

    model: ModelConfig = field(default_factory=ModelConfig)
    loss: LossWeights = field(default_factory=LossWeights)
    block_size: int = 2  # consecutive levels trained together
    block_iterations: tuple[int, ...] = (15000, 25000, 25000, 25000)  # one entry per block
    lr: float = 1e-4
    betas: tuple[float, float] = (0.9, 0.999)
    n_critic: int = 5  # critic steps per generator step (GANimator's D_fact)
    mix_prob: float = 0.9  # share of random generations that mix two conditions
    # With conditional critics (ModelConfig.critic_condition): how a style-mixed sample is
    # scored from its crossover level on. "none": without a label (a zero condition, i.e.
    # the critic's unconditional score), so only single-label generations are held to
    # their label; "label": with the label that drove each level.
    critic_mixed: str = "none"
    seed: int = 0
    checkpoint_every: int = 1000  # iterations; 0 = only at the end of each block
    log_every: int = 10  # iterations between CSV rows / progress-bar updates
    device: str = "cpu"

    def __post_init__(self):
        check_fields(self, ConfigError)
        object.__setattr__(self, "block_iterations", tuple(int(n) for n in self.block_iterations))
        object.__setattr__(self, "betas", tuple(float(b) for b in self.betas))
        if self.block_size < 1:
            raise ConfigError(f"block_size must be >= 1, got {self.block_size}")
        if len(self.block_iterations) != self.num_blocks:
            raise ConfigError(
                f"{self.model.num_levels} levels in blocks of {self.block_size} make "
                f"{self.num_blocks} blocks, but block_iterations has "
                f"{len(self.block_iterations)} entries"
            )
        if any(n < 0 for n in self.block_iterations):
            raise ConfigError("block_iterations must be >= 0")
        if self.n_critic < 0:
            raise ConfigError(f"n_critic must be >= 0, got {self.n_critic}")
        if self.critic_mixed not in ("none", "label"):
            raise ConfigError(f"critic_mixed must be 'none' or 'label', got {self.critic_mixed!r}")
        if not 0 <= self.mix_prob <= 1:
            raise ConfigError(f"mix_prob must be in [0, 1], got {self.mix_prob}")
        if not (math.isfinite(self.lr) and self.lr > 0):
            raise ConfigError(f"lr (Adam's learning rate) must be finite and > 0, got {self.lr}")
        if self.loss.mismatch and not self.model.critic_condition:
            raise ConfigError("loss.mismatch needs conditional critics (critic_condition=True)")

    @property
    def num_blocks(self) -> int:
        return -(-self.model.num_levels // self.block_size)

    @property
    def blocks(self) -> list[list[int]]:
        """0-based level indices of every block, e.g. ``[[0, 1], [2, 3], ...]``."""
        L, s = self.model.num_levels, self.block_size
        return [list(range(i, min(i + s, L))) for i in range(0, L, s)]

    @property
    def smooth_start(self) -> int:
        """First level (1-based) that gets the smoothness loss: the finer half."""
        return self.model.num_levels // 2 + 1

    def replace(self, **changes) -> TrainConfig:
        return dataclasses.replace(self, **changes)


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
    """The ``tutorial`` networks, losses and critics on a budget of minutes, for
    ``mrlib demo``: one critic step per generator step and 800 / 600 / 400 / 300
    iterations for the four blocks (the coarse blocks are cheap, the fine ones cost
    most), and the critics' mismatch term at weight 2 (``LossWeights.mismatch``): at this
    budget the label term alone did not tell two similar labels apart (samples of the
    Bandai happy walk were nearest the normal walk in 23-38 % of windows), and real clips
    shown with a wrong label teach the critics which motion goes with which label. The demo trains it on the four synthetic clips of ``data_samples/`` resampled
    to 15 fps (``mrlib.app.demo.DEMO_FPS``); ``docs/results.md`` has its measured time and
    quality next to other budgets."""
    return tutorial().replace(
        block_iterations=(800, 600, 400, 300),
        n_critic=1,
        checkpoint_every=0,
        loss=LossWeights(detail=100.0, mismatch=2.0),
    )


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
    (700 iterations instead of 3900), for notebook 04's default run on a handful of
    synthetic clips: enough for the arms to follow the loudness, not for the tutorial's
    measured synchrony."""
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
    "speech_paper": speech_paper,
    "speech_tutorial": speech_tutorial,
    "speech_demo": speech_demo,
}


# Frame rate a preset trains at when it wants one (clips are resampled to it first): the
# demo budget trains at 15 fps, half the Bandai clips' rate, for minutes on two CPU cores.
PRESET_FPS = {"demo": 15.0}

# One line per preset for ``--help`` (``mrlib train``, ``train-speech``, ``demo``); times
# are on 2 CPU cores, measured in ``docs/results.md``. Speech presets are ``speech_*``.
PRESET_SUMMARIES = {
    "paper": "the paper's: 15k + 3 x 25k iterations, full-width networks (use a GPU)",
    "tutorial": "CPU budget: narrower networks, 800 iterations per block (~20 min)",
    "demo": "tutorial networks, 800/600/400/300 iterations, 1 critic step (minutes)",
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
        fps = f" [{PRESET_FPS[n]:g} fps]" if n in PRESET_FPS else ""
        lines.append(f"  {n:<{width}}  {PRESET_SUMMARIES.get(n, '')}{fps}".rstrip())
    return "\n".join(lines)


def get_preset(name: str) -> TrainConfig:
    """A named preset of ``PRESETS``: ``"paper"``, ``"tutorial"``, ``"demo"``,
    ``"speech_paper"`` or ``"speech_tutorial"``."""
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


def check_device(name: str) -> str:
    """``name`` if PyTorch can run on that device here, else a :class:`ConfigError` that
    says why and what to use instead (``"cpu"``, ``"cuda"``, ``"cuda:1"``, ``"mps"``)."""
    try:
        dev = torch.device(str(name))
    except (RuntimeError, ValueError):
        raise ConfigError(
            f"unknown device {name!r}; use 'cpu', 'cuda', 'cuda:N' or 'mps'"
        ) from None
    if dev.type == "cuda":
        if not torch.cuda.is_available():
            why = (
                "this PyTorch build has no CUDA support"
                if torch.version.cuda is None
                else "no CUDA GPU is visible"
            )
            raise ConfigError(
                f"device {name!r}: {why} (torch {torch.__version__}); use --device cpu"
            )
        if dev.index is not None and dev.index >= torch.cuda.device_count():
            raise ConfigError(
                f"device {name!r}: only {torch.cuda.device_count()} CUDA device(s) here"
            )
    elif dev.type == "mps":
        if not torch.backends.mps.is_available():
            raise ConfigError(f"device {name!r}: MPS is not available here; use --device cpu")
    elif dev.type != "cpu":
        raise ConfigError(f"device {name!r} is not supported; use 'cpu', 'cuda', 'cuda:N' or 'mps'")
    return str(name)


def config_to_json(config: TrainConfig) -> str:
    return json.dumps(dataclasses.asdict(config), indent=2, sort_keys=True)


# Study options removed from mrlib, by section of a saved config ("" = TrainConfig
# itself), with the value every preset had: a saved config that has one at that value
# loads as if it were absent (the same training); any other value is refused.
REMOVED_OPTIONS: dict[str, dict[str, object]] = {
    "model": {"critic_contacts": False},
    "loss": {"con_norm": "squared", "con_on_rec": False},
    "": {
        "zstar": "shared",
        "samples_per_clip": 1,
        "smooth_from_level": None,
        "contact_from_level": 1,
    },
}


def _drop_removed(d: dict, section: str) -> dict:
    """``d`` without the removed options of ``section`` that hold their old default;
    a :class:`ConfigError` for one that does not."""
    d = dict(d)
    for name, default in REMOVED_OPTIONS[section].items():
        if name in d:
            value = d.pop(name)
            if value != default:
                where = f"{section}.{name}" if section else name
                raise ConfigError(
                    f"config option {where}={value!r} was a study option removed from mrlib; "
                    "train or load this run with an earlier version of mrlib"
                )
    return d


def config_from_json(text: str | dict) -> TrainConfig:
    """The config of ``config_to_json`` text (or its dict). A config saved by an earlier
    mrlib may still hold an option of ``REMOVED_OPTIONS``: at its old default it is
    dropped; with another value (a run that used the study option) it is refused."""
    d = json.loads(text) if isinstance(text, str) else dict(text)
    d = _drop_removed(d, "")
    model = _drop_removed(d.pop("model"), "model")
    if model.get("critic_band") == "level":
        raise ConfigError(
            "config option model.critic_band='level' was a study option removed from mrlib; "
            "train or load this run with an earlier version of mrlib"
        )
    model = ModelConfig(**model)
    loss = LossWeights(**_drop_removed(d.pop("loss"), "loss"))
    names = {f.name for f in dataclasses.fields(TrainConfig)}
    unknown = set(d) - names
    if unknown:
        raise ConfigError(f"unknown config fields {sorted(unknown)}")
    return TrainConfig(model=model, loss=loss, **d)
