"""Control beyond labels: root paths, keyframes and in-betweening, body-part
composition, seamless loops and continuation.

Each constraint is a function of a trained model (or, where it can be, of any motion),
usable the same way for label and speech models wherever it works on the output. Those
that generate take a ``condition`` (a label or a ``mrlib.Condition``) and a ``sampler``
(a ``mrlib.Sampler``: fine noise, guidance, and whether the feet are planted), as
``mrlib.generate`` does:

* :func:`generate_on_path` / :func:`follow_path` (``path``): walk a ground-plane path,
  feet planted.
* :func:`generate_with_keyframes` / :func:`apply_keyframes` (``keyframes``): hold full
  or partial poses at given frames (the noise fit: :class:`KeyframeFit`);
  :func:`continue_motion` extends a prefix (its noise fit: :class:`NoiseFit`).
* :func:`generate_parts` (``num=``, as ``mrlib.generate``) / :func:`splice_parts`
  (``compose``): a label per body part (``mrlib.Condition.parts``);
  :func:`generate_sharpened` (``sharpen``) fits a sample's noise so that each part shows
  its label (the fit: :class:`Sharpening`).
* :func:`generate_loop` (``loop``): a loop whose end joins its start.

How each works, and what was measured against what, is in the submodules' docstrings
and ``docs/results.md``; ``notebooks/06_constraints.ipynb`` shows them with widgets.
"""

from mrlib.sampling.constraints import compose, keyframes
from mrlib.sampling.constraints.common import PARTS, parse_parts, part_joints
from mrlib.sampling.constraints.compose import *  # noqa: F403 (its __all__, below)
from mrlib.sampling.constraints.keyframe_files import Keyframe, load_keyframes, save_keyframes
from mrlib.sampling.constraints.keyframes import *  # noqa: F403 (its __all__, below)
from mrlib.sampling.constraints.loop import generate_loop, loop_seam, roll_loop, tile_loop
from mrlib.sampling.constraints.optimise import NoiseFit
from mrlib.sampling.constraints.path import GroundPath, follow_path, ground_track, parse_path
from mrlib.sampling.constraints.path_measure import path_error
from mrlib.sampling.constraints.path_sample import generate_on_path, natural_pace, path_seconds
from mrlib.sampling.constraints.sharpen import (
    MARGIN,
    SHARPEN_STEPS,
    Sharpening,
    generate_sharpened,
    label_margin_objective,
)

__all__ = [
    "GroundPath",
    "parse_path",
    "follow_path",
    "generate_on_path",
    "natural_pace",
    "path_seconds",
    "ground_track",
    "path_error",
    "Keyframe",
    "save_keyframes",
    "load_keyframes",
    *keyframes.__all__,
    "NoiseFit",
    "PARTS",
    "part_joints",
    "parse_parts",
    *compose.__all__,
    "SHARPEN_STEPS",
    "MARGIN",
    "Sharpening",
    "label_margin_objective",
    "generate_sharpened",
    "generate_loop",
    "loop_seam",
    "tile_loop",
    "roll_loop",
]
