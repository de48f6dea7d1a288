"""BVH files: the hierarchy model, a strict reader, a writer and the forward kinematics.

The format in four modules, all following the conventions below:

* ``mrlib.io.bvh.hierarchy``: ``BVHSkeleton`` (the HIERARCHY section) and ``BVH`` (a
  whole file), the frame-time bounds reader and writer share (``frame_time_problem``);
* ``mrlib.io.bvh.reader``: ``parse_bvh`` / ``read_bvh``, which refuse a malformed file
  with the line and what was expected;
* ``mrlib.io.bvh.writer``: ``format_bvh`` / ``write_bvh``, which emit exactly what the
  reader accepts;
* ``mrlib.io.bvh.kinematics``: Euler angles (``euler_to_matrix``, ``matrix_to_euler``)
  and vectorised forward kinematics (``bvh_forward_kinematics``).

Every public name is importable from ``mrlib.io.bvh`` itself.

BVH conventions assumed here (those of Biovision's format as read by Blender, MotionBuilder
and most research code):

* Every joint's ``CHANNELS`` line lists its animated degrees of freedom in the order their
  values appear in a frame line. Any subset is allowed: the Bandai Namco data has 6
  channels on every joint, the CMU conversion 6 on the root and 3 elsewhere.
* Rotation channels are Euler angles in **degrees**, composed in the order listed, each
  multiplying on the right: ``Zrotation Xrotation Yrotation`` means
  ``R_local = Rz(z) @ Rx(x) @ Ry(y)``, mapping the joint's frame into its parent's.
* Position channels *replace* the matching component of the joint's ``OFFSET`` (the
  parent-frame translation); components without a channel keep the offset.
* Positions are in the file's own unit (cm for most files); nothing is converted here.

Shapes: T frames, J joints (End Sites are not joints), C channels in total.
"""

from mrlib.errors import BVHFormatError
from mrlib.io.bvh.hierarchy import (
    BVH,
    MAX_FRAME_TIME,
    MIN_FRAME_TIME,
    BVHSkeleton,
    frame_time_problem,
)
from mrlib.io.bvh.kinematics import (
    ReferenceFrameWarning,
    bvh_forward_kinematics,
    bvh_local_transforms,
    euler_to_matrix,
    forward_kinematics,
    matrix_to_euler,
    without_reference_frame,
)
from mrlib.io.bvh.reader import MAX_BVH_BYTES, MAX_DEPTH, parse_bvh, read_bvh
from mrlib.io.bvh.writer import format_bvh, write_bvh

__all__ = [
    "BVHSkeleton",
    "BVH",
    "parse_bvh",
    "read_bvh",
    "format_bvh",
    "write_bvh",
    "euler_to_matrix",
    "matrix_to_euler",
    "bvh_local_transforms",
    "forward_kinematics",
    "bvh_forward_kinematics",
    "frame_time_problem",
    "without_reference_frame",
    "ReferenceFrameWarning",
    "MIN_FRAME_TIME",
    "MAX_FRAME_TIME",
    "MAX_BVH_BYTES",
    "MAX_DEPTH",
    "BVHFormatError",
]
