"""Control beyond labels: root paths, keyframes and in-betweening, body-part
composition, seamless loops and continuation.

Each constraint is a function of a trained model (or, where it can be, of any motion),
usable the same way for label and speech models wherever it works on the output:

* :func:`generate_on_path` / :func:`follow_path` (``path``): walk a ground-plane path,
  feet planted.
* :func:`generate_with_keyframes` / :func:`apply_keyframes` (``keyframes``): hold full
  or partial poses at given frames; :func:`continue_motion` extends a prefix.
* :func:`generate_parts` (one) / :func:`generate_many_parts` (a list) / :func:`splice_parts` (``compose``): a condition per body part;
  :func:`generate_sharpened` (``sharpen``) fits a sample's noise so that each part shows
  its label.
* :func:`generate_loop` (``loop``): a loop whose end joins its start.

How each works, and what was measured against what, is in the submodules' docstrings
and ``docs/results.md``; ``notebooks/06_constraints.ipynb`` shows them with widgets.
"""

from mrlib.sampling.constraints.common import PARTS, parse_parts, part_joints
from mrlib.sampling.constraints.compose import (
    arm_leg_coordination,
    gait_phase,
    generate_many_parts,
    generate_parts,
    part_fidelity,
    phase_align,
    splice_parts,
)
from mrlib.sampling.constraints.keyframe_files import Keyframe, load_keyframes, save_keyframes
from mrlib.sampling.constraints.keyframes import (
    align_to_keyframes,
    apply_keyframes,
    continue_motion,
    generate_with_keyframes,
    keyframe_errors,
    keyframe_objective,
)
from mrlib.sampling.constraints.loop import generate_loop, loop_seam, roll_loop, tile_loop
from mrlib.sampling.constraints.path import (
    GroundPath,
    follow_path,
    generate_on_path,
    ground_track,
    natural_pace,
    parse_path,
    path_error,
    path_seconds,
)
from mrlib.sampling.constraints.sharpen import (
    MARGIN,
    SHARPEN_STEPS,
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
    "align_to_keyframes",
    "apply_keyframes",
    "keyframe_errors",
    "keyframe_objective",
    "generate_with_keyframes",
    "continue_motion",
    "PARTS",
    "part_joints",
    "parse_parts",
    "generate_parts",
    "generate_many_parts",
    "splice_parts",
    "gait_phase",
    "phase_align",
    "arm_leg_coordination",
    "part_fidelity",
    "SHARPEN_STEPS",
    "MARGIN",
    "label_margin_objective",
    "generate_sharpened",
    "generate_loop",
    "loop_seam",
    "tile_loop",
    "roll_loop",
]
