"""Configuration of the networks and of training: frozen dataclasses, saved as JSON next
to every checkpoint (``config_to_json`` / ``config_from_json``). Make variants with
``dataclasses.replace`` (or ``TrainConfig.replace``); the named presets and the reasons
for their values are in ``mrlib.model.presets``.

Options that only studies used, and no preset, were removed after their study (their
findings stay in ``docs/results.md`` and ``docs/notes/``): ``REMOVED_OPTIONS`` lists them;
a saved config that still sets one to its old default loads, any other value is refused.
"""

from __future__ import annotations

import dataclasses
import json
import math
from dataclasses import dataclass, field

import torch

from mrlib.errors import MrlibError, check_fields

__all__ = [
    "ModelConfig",
    "LossWeights",
    "TrainConfig",
    "SPEECH_NUM_LEVELS",
    "check_device",
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
    """Weights of the generator objective (paper Eq. 11) and of the gradient penalty."""

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
    # Frame rate the clips are resampled to before training (None: the clips' own). The
    # preview preset trains at 15 fps, half the Bandai clips' rate, the demo preset at 30.
    fps: float | None = None
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
        if self.fps is not None and not (math.isfinite(self.fps) and 0 < self.fps <= 1000):
            raise ConfigError(f"fps must be None or a number in (0, 1000], got {self.fps}")
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
