"""Configuration of the networks and of training, with the named presets ``paper``,
``tutorial`` and ``demo``.

Configs are frozen dataclasses; make variants with ``dataclasses.replace`` and save them
as JSON next to every checkpoint (``config_to_json`` / ``config_from_json``).

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
channels, as the paper describes z_i) rather than GANimator's default full-channel
N(0, 1), which left the label's effect on random samples weak in our tests.

Beyond the paper (on in ``tutorial``, off in ``paper``): conditional critics
(``ModelConfig(critic_condition=True)``, a projection discriminator, Miyato & Koyama
2018). With unconditional critics a label reaches random generations only through the
reconstruction loss, and single-label samples drift to other labels' motion (condition
fidelity 72 % on four Bandai walks at 400 iterations per block); conditional critics
hold them to their label (82 % at 400, 96 % at 800). Whether a crossover also takes its
fine detail from the fine label depends on what the label term looks at: judging the
whole signal made the crossover a switch between the two labels, and judging only
single-label samples left the detail with the coarse label (2 of 24 cases). The
``tutorial`` preset judges the label on the detail band only (``critic_band="detail"``)
and scores every level with the label that drove it (``critic_mixed="label"``): on
its own, that made the detail follow the fine label in 11 of 24 cases. A label term on
the band each level adds (``critic_band="level"``) kept the low band with A in 24 of 24
but the detail with B in only 2 (10 with the mismatch term): that band is too weak a
signal to steer.

What makes the fine levels follow the fine label is the detail-statistics term
(``LossWeights.detail``, weight 100 in ``tutorial``): at every level from 2 on, the
per-channel RMS of the detail that level adds to a random generation is pulled to the
mean of the training clips of the label driving that level, a style as channel
statistics in the sense of Gatys et al. (2016) and AdaIN (Huang & Belongie 2017). On the
four Bandai walks (crossovers at levels 2 and 4 of all 12 ordered label pairs, training
seeds 0-4) both halves of the crossover claim hold in 23, 23, 22, 22 and 24 of 24 cases
with weight 100, at condition fidelity 93.3, 92.2, 90.9, 94.7 and 93.5 % (96.5 % without
the term, seed 0; all misses but one are low bands of the two most alike walks, normal
and happy, at level 2); weight 200 gives 24, 23 and 23 of 24 but fidelity 93.1, 87.5 and
85.8 %, and weight 50 16 of 24 at 95.6 % (seed 0). Coverage stays at 100 % (eps = 2) in
all of them. See ``mrlib.control``.

``LossWeights.mismatch`` adds to a conditional critic's loss the real clips shown with a
wrong condition (Reed et al. 2016). For speech it is what ties gestures to the audio
(``mrlib.speech_train.speech_tutorial``). For labels it is off in ``tutorial``: on the
four Bandai walks (weight 1, before the detail term) it raised condition fidelity from
96.5 % to 99.2 % but left the crossover much as it was (low band from A in 19 of 24
cases, residual from B in 13, both in 8; coverage 100 % at eps = 2). Added to the
current ``tutorial`` (weight 1, training seed 2) it raised fidelity from 90.9 % to
97.4 % but took the low band from A in only 16 of 24 cases (22 without it): the
crossover drifts back towards a switch between the labels.
"""

from __future__ import annotations

import dataclasses
import json
from dataclasses import dataclass, field

from mrlib.errors import MrlibError

__all__ = [
    "ModelConfig",
    "LossWeights",
    "TrainConfig",
    "paper",
    "tutorial",
    "demo",
    "PRESETS",
    "get_preset",
    "check_device",
    "ganimator_mode",
    "config_to_json",
    "config_from_json",
]


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
    # body (mrlib.skeleton.UPPER_BODY_JOINTS) so the legs are left to the generator.
    film_joints: tuple[int, ...] | None = None
    leaky_slope: float = 0.2
    # Critics that see the condition (projection discriminator, Miyato & Koyama 2018). The
    # paper's critics are unconditional: random generations are then judged only on
    # realism, and the label reaches them only through the reconstruction loss.
    critic_condition: bool = False
    # What the condition term of a conditional critic looks at: "full" = the critic's own
    # features of the whole signal; "detail" = features of a separate branch that sees only
    # the detail band ``x - box_K(x)`` (K = kernel_size), so the label is judged on detail;
    # "level" = a branch that sees only the band the level adds over the level below,
    # ``x - up(down(x))`` with the pyramid's own resampling (``PackedLevels.level_band``).
    critic_band: str = "full"

    def __post_init__(self):
        if self.num_levels < 1:
            raise ConfigError(f"num_levels must be >= 1, got {self.num_levels}")
        if not self.scale_factor > 1:
            raise ConfigError(f"scale_factor must be > 1, got {self.scale_factor}")
        if self.kernel_size % 2 != 1:
            raise ConfigError(f"kernel_size must be odd, got {self.kernel_size}")
        if not self.gen_hidden or not self.disc_hidden:
            raise ConfigError("gen_hidden and disc_hidden need at least one layer")
        if self.critic_band not in ("full", "detail", "level"):
            raise ConfigError(
                f"critic_band must be 'full', 'detail' or 'level', got {self.critic_band!r}"
            )
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
    # condition go together, not only whether each looks real. 0: off.
    mismatch: float = 0.0
    # Labels only (beyond the paper): weight of a detail-statistics term on random
    # generations. At every level from 2 on, the per-channel RMS of the detail the level
    # adds (``PackedLevels.level_band``) is pulled, by an L1 penalty, to the mean of the
    # training clips of the label that drives the level: a style as channel statistics
    # (Gatys et al. 2016; Huang & Belongie 2017), so a crossover's fine levels carry the
    # fine label's amount of detail per joint. 0: off.
    detail: float = 0.0

    def __post_init__(self):
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
    samples_per_clip: int = 1  # random generations per training clip and step
    # z*_1: "shared" = a draw of z_1 itself, N(0, sigma_1) shared by all channels (the paper's
    # noise, Sec. 3.2); "full" = N(0, 1) on every channel (GANimator's default)
    zstar: str = "shared"
    # With conditional critics (ModelConfig.critic_condition): how a style-mixed sample is
    # scored from its crossover level on. "none": without a label (a zero condition, i.e.
    # the critic's unconditional score), so only single-label generations are held to
    # their label; "label": with the label that drove each level.
    critic_mixed: str = "none"
    smooth_from_level: int | None = None  # first level (1-based) with L_smooth; None: L//2+1
    contact_from_level: int = 1  # first level with L_con
    seed: int = 0
    checkpoint_every: int = 1000  # iterations; 0 = only at the end of each block
    log_every: int = 10  # iterations between CSV rows / progress-bar updates
    device: str = "cpu"

    def __post_init__(self):
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
        if self.n_critic < 0 or self.samples_per_clip < 1:
            raise ConfigError("n_critic must be >= 0 and samples_per_clip >= 1")
        if self.zstar not in ("shared", "full"):
            raise ConfigError(f"zstar must be 'shared' or 'full', got {self.zstar!r}")
        if self.critic_mixed not in ("none", "label"):
            raise ConfigError(f"critic_mixed must be 'none' or 'label', got {self.critic_mixed!r}")
        if not 0 <= self.mix_prob <= 1:
            raise ConfigError(f"mix_prob must be in [0, 1], got {self.mix_prob}")
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
        """First level (1-based) that gets the smoothness loss."""
        return (
            self.model.num_levels // 2 + 1
            if self.smooth_from_level is None
            else self.smooth_from_level
        )

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
    """A CPU budget: the paper's 8 levels and losses, narrower networks (72/144/144 hidden
    channels in the generators, 48/96/96 in the critics), 2 critic steps per generator
    step, a larger learning rate (5e-4), 800 iterations per block, conditional critics
    whose label term sees the detail band (``critic_band="detail"``), each level scored
    with the label that drove it (``critic_mixed="label"``), and the detail-statistics
    term at weight 100 (``LossWeights(detail=100)``).

    Measured on four Bandai walks (normal/happy/sad/angry_001, ~900 frames at 30 fps) on
    a 2-core CPU shared with 3 other jobs, one torch thread, training seeds 0 / 1 / 2 /
    3 / 4: condition fidelity 93.3 / 92.2 / 90.9 / 94.7 / 93.5 %; crossovers at levels
    2 and 4 of all 12 label pairs with the low-pass band from the coarse label and the
    detail from the fine label in 23 / 23 / 22 / 22 / 24 of 24 cases; coverage 100 % at
    eps 2 (>= 95.6 % at eps 1); 1765-1932 s of training with three or four such runs on
    the two cores (1088 s with two, at weight 200). Without the detail term (the
    previous preset, seed 0): fidelity 96.5 %, both halves in 8 of 24 (the detail from
    the fine label in 11); with weight 200: 23-24 of 24 but fidelity 93.1 / 87.5 /
    85.8 %. Paper-style unconditional critics: fidelity 71.9 % at 400 and 85.5 % at
    800 iterations per block. ``python bench/condition_control.py --seed N`` measures
    these figures; ``bench/time_to_quality.py`` reports when a model first meets the
    quality target."""
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
    most). The demo trains it on the four synthetic clips of ``data_samples/`` resampled
    to 15 fps (``mrlib.demo.DEMO_FPS``); ``docs/results.md`` has its measured time and
    quality next to other budgets."""
    return tutorial().replace(block_iterations=(800, 600, 400, 300), n_critic=1, checkpoint_every=0)


def ganimator_mode(config: TrainConfig) -> TrainConfig:
    """``config`` for a GANimator-style baseline (one model per clip, Li et al. 2022): no
    style mixing (one label, nothing to mix) and unconditional critics."""
    model = dataclasses.replace(config.model, critic_condition=False)
    return config.replace(mix_prob=0.0, model=model)


PRESETS = {"paper": paper, "tutorial": tutorial, "demo": demo}


def get_preset(name: str) -> TrainConfig:
    """A named preset: ``"paper"``, ``"tutorial"`` or ``"demo"``."""
    if name not in PRESETS:
        raise ConfigError(f"unknown preset {name!r}; choose one of {sorted(PRESETS)}")
    return PRESETS[name]()


def check_device(name: str) -> str:
    """``name`` if PyTorch can run on that device here, else a :class:`ConfigError` that
    says why and what to use instead (``"cpu"``, ``"cuda"``, ``"cuda:1"``, ``"mps"``)."""
    import torch

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


def config_from_json(text: str | dict) -> TrainConfig:
    d = json.loads(text) if isinstance(text, str) else dict(text)
    d = dict(d)
    model = ModelConfig(**d.pop("model"))
    loss = LossWeights(**d.pop("loss"))
    names = {f.name for f in dataclasses.fields(TrainConfig)}
    unknown = set(d) - names
    if unknown:
        raise ConfigError(f"unknown config fields {sorted(unknown)}")
    return TrainConfig(model=model, loss=loss, **d)
