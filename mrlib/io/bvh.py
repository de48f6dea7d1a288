"""BVH files: a strict parser, vectorised forward kinematics and a writer.

The module is long because it is the whole format in one place: the writer must emit
exactly what the parser accepts, and both follow the Euler-angle and channel
conventions below, which the forward kinematics applies.

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

from __future__ import annotations

import math
import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from mrlib.errors import BVHFormatError
from mrlib.io.paths import read_text_bounded
from mrlib.representation.motion import MAX_FPS

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
]

_CHANNEL_NAMES = {
    "xposition": "Xposition",
    "yposition": "Yposition",
    "zposition": "Zposition",
    "xrotation": "Xrotation",
    "yrotation": "Yrotation",
    "zrotation": "Zrotation",
}
_AXIS = {"X": 0, "Y": 1, "Z": 2}


@dataclass(frozen=True)
class BVHSkeleton:
    """The HIERARCHY section.

    Attributes:
        names: ``J`` joint names in file order (parents precede children).
        parents: ``J`` parent indices, -1 for the root.
        offsets: ``(J, 3)`` float64 rest translations relative to the parent, file units.
        channels: per joint, the channel names in file order (``"Zrotation"``, ...).
        end_sites: ``(joint index, (3,) offset)`` pairs, one per ``End Site`` block.
    """

    names: tuple[str, ...]
    parents: tuple[int, ...]
    offsets: np.ndarray
    channels: tuple[tuple[str, ...], ...]
    end_sites: tuple[tuple[int, np.ndarray], ...] = ()

    @property
    def num_joints(self) -> int:
        return len(self.names)

    @property
    def num_channels(self) -> int:
        return sum(len(c) for c in self.channels)

    def index(self, name: str) -> int:
        """Index of the joint called ``name`` (KeyError if absent)."""
        try:
            return self.names.index(name)
        except ValueError:
            raise KeyError(name) from None

    def channel_starts(self) -> np.ndarray:
        """``(J,)`` index of each joint's first channel in a frame line."""
        sizes = np.array([len(c) for c in self.channels], dtype=np.int64)
        return np.concatenate([[0], np.cumsum(sizes)[:-1]]).astype(np.int64)


@dataclass(frozen=True)
class BVH:
    """A parsed BVH file: skeleton, channel values and frame time.

    Attributes:
        skeleton: the hierarchy.
        motion: ``(T, C)`` float64 channel values, angles in degrees.
        frame_time: seconds per frame.
        source: where it came from (a path or ``"<string>"``), used in error messages.
    """

    skeleton: BVHSkeleton
    motion: np.ndarray
    frame_time: float
    source: str = field(default="<string>")

    @property
    def num_frames(self) -> int:
        return len(self.motion)

    @property
    def fps(self) -> float:
        return 1.0 / self.frame_time


# ----------------------------------------------------------------------------------------
# Parsing
# ----------------------------------------------------------------------------------------
class _Tokens:
    """Whitespace tokens of the HIERARCHY part with their 1-based line numbers; braces
    are split off so ``ROOT Hips {`` and ``{`` on its own line read the same."""

    def __init__(self, lines: list[str], source: str):
        self.source = source
        self.items: list[tuple[str, int]] = []
        self.pos = 0
        self.motion_line = None  # index into lines of the MOTION keyword
        for i, line in enumerate(lines):
            if line.strip().upper() == "MOTION":
                self.motion_line = i
                break
            for tok in re.split(r"\s+|([{}])", line):
                if tok:
                    self.items.append((tok, i + 1))
        # where to point when the hierarchy ends early: the line before MOTION, or the end
        self.last_line = self.motion_line if self.motion_line is not None else len(lines)

    def error(self, problem: str, line: int | None = None) -> BVHFormatError:
        if line is None:
            line = self.items[self.pos][1] if self.pos < len(self.items) else self.last_line
        return BVHFormatError(self.source, f"line {line}: {problem}")

    def peek(self) -> str | None:
        return self.items[self.pos][0] if self.pos < len(self.items) else None

    def next(self, what: str) -> tuple[str, int]:
        if self.pos >= len(self.items):
            where = "before MOTION" if self.motion_line is not None else "at end of file"
            raise self.error(f"expected {what}, file ends {where} (truncated hierarchy?)")
        tok = self.items[self.pos]
        self.pos += 1
        return tok

    def name(self, what: str) -> tuple[str, int]:
        """A joint name: every token up to the end of its line or a ``{`` (3ds Max and
        other tools write names with spaces, ``JOINT Bip01 L Thigh``)."""
        tok, line = self.next(what)
        if tok == "{":
            raise self.error(f"expected {what}, got '{{'", line)
        parts = [tok]
        while self.pos < len(self.items) and self.items[self.pos][1] == line:
            nxt = self.items[self.pos][0]
            if nxt == "{":
                break
            parts.append(nxt)
            self.pos += 1
        return " ".join(parts), line

    def expect(self, word: str) -> int:
        tok, line = self.next(f"'{word}'")
        if tok.upper() != word.upper():
            raise self.error(f"expected '{word}', got '{tok}'", line)
        return line

    def number(self, what: str) -> float:
        tok, line = self.next(what)
        try:
            val = float(tok)
        except ValueError:
            raise self.error(f"expected a number for {what}, got '{tok}'", line) from None
        if not math.isfinite(val):
            raise self.error(f"{what} is not finite ('{tok}')", line)
        return val


MAX_DEPTH = 256  # joints nested deeper than this are refused (humanoid rigs: < 40)
# files over this are refused from their size, before reading: about 20 minutes of a
# 60-joint rig at 120 fps; mrlib trains on at most 18,000 frames of a clip anyway
MAX_BVH_BYTES = 256 * 2**20
# "Frame Time:" bounds in seconds per frame, one pair for the reader (which refuses
# others) and the writer (which never writes them): 1000 fps down to 0.01 fps
MIN_FRAME_TIME = 1.0 / MAX_FPS
MAX_FRAME_TIME = 100.0


def frame_time_problem(frame_time: float) -> str | None:
    """Why ``frame_time`` (seconds) is no BVH frame time, or None when it is one."""
    if math.isfinite(frame_time) and MIN_FRAME_TIME <= frame_time <= MAX_FRAME_TIME:
        return None
    return (
        f"'Frame Time:' must be seconds per frame between {MIN_FRAME_TIME:g} and "
        f"{MAX_FRAME_TIME:g} ({1 / MAX_FRAME_TIME:g} to {1 / MIN_FRAME_TIME:g} fps)"
    )


def _parse_joint(tk: _Tokens, name: str, parent: int, out: dict, depth: int = 0) -> None:
    if depth >= MAX_DEPTH:
        raise tk.error(f"joints nested more than {MAX_DEPTH} deep (at '{name}'): not a skeleton")
    index = len(out["names"])
    out["names"].append(name)
    out["parents"].append(parent)
    tk.expect("{")
    tk.expect("OFFSET")
    out["offsets"].append([tk.number(f"OFFSET of joint '{name}'") for _ in range(3)])
    channels: list[str] = []
    if (tk.peek() or "").upper() == "CHANNELS":
        tk.next("CHANNELS")
        n_tok, n_line = tk.next("the number of channels")
        if not n_tok.isdigit() or int(n_tok) > 6:
            raise tk.error(
                f"expected a channel count 0..6 for joint '{name}', got '{n_tok}'", n_line
            )
        for _ in range(int(n_tok)):
            tok, line = tk.next(f"a channel name for joint '{name}'")
            canon = _CHANNEL_NAMES.get(tok.lower())
            if canon is None:
                raise tk.error(
                    f"expected a channel name (Xposition..Zrotation) for joint '{name}', got "
                    f"'{tok}' (CHANNELS says {n_tok} channels)",
                    line,
                )
            if canon in channels:
                raise tk.error(f"channel {canon} listed twice for joint '{name}'", line)
            channels.append(canon)
    out["channels"].append(tuple(channels))
    while True:
        tok, line = tk.next(f"'JOINT', 'End Site' or '}}' closing joint '{name}'")
        up = tok.upper()
        if up == "}":
            return
        if up == "JOINT":
            child, _ = tk.name("a joint name")
            if child in out["names"]:
                raise tk.error(f"duplicate joint name '{child}'", line)
            _parse_joint(tk, child, index, out, depth + 1)
        elif up == "END":
            tk.expect("Site")
            tk.expect("{")
            tk.expect("OFFSET")
            off = np.array([tk.number(f"End Site OFFSET under '{name}'") for _ in range(3)])
            tk.expect("}")
            out["end_sites"].append((index, off))
        else:
            raise tk.error(
                f"expected 'JOINT', 'End Site' or '}}' in joint '{name}', got '{tok}'", line
            )


def _parse_frames(lines: list[str], first: int, n_frames: int, n_channels: int, source: str):
    """Frame lines ``lines[first:]`` -> ``(T, C)`` float64, checking counts and values."""
    rows: list[list[str]] = []
    row_lines: list[int] = []
    for i in range(first, len(lines)):
        toks = lines[i].split()
        if not toks:
            continue
        if len(toks) != n_channels:
            raise BVHFormatError(
                source,
                f"line {i + 1}: expected {n_channels} values in frame {len(rows) + 1} "
                f"(the sum of the CHANNELS counts), got {len(toks)}",
            )
        rows.append(toks)
        row_lines.append(i + 1)
    if len(rows) != n_frames:
        short = len(rows) < n_frames
        line = len(lines) if short else row_lines[n_frames]
        raise BVHFormatError(
            source,
            f"line {line}: 'Frames: {n_frames}' but the file has {len(rows)} frame lines "
            f"({'truncated file?' if short else 'more frame lines than declared'})",
        )
    if n_frames == 0:
        return np.zeros((0, n_channels))
    try:
        data = np.array(rows, dtype=np.float64)
    except ValueError:
        data = None
    if data is None or not np.isfinite(data).all():
        for r, toks in enumerate(rows):  # slow path only to locate the problem
            for c, tok in enumerate(toks):
                try:
                    v = float(tok)
                except ValueError:
                    raise BVHFormatError(
                        source, f"line {row_lines[r]}: value {c + 1} is not a number: '{tok}'"
                    ) from None
                if not math.isfinite(v):
                    raise BVHFormatError(
                        source, f"line {row_lines[r]}: value {c + 1} is not finite: '{tok}'"
                    )
    return data.reshape(n_frames, n_channels)


def parse_bvh(text: str, *, source: str | Path = "<string>") -> BVH:
    """Parse the text of a BVH file.

    Args:
        text: the whole file.
        source: a name for error messages (the path when reading a file).

    Returns:
        A ``BVH``; ``motion`` is ``(T, C)`` with ``C = skeleton.num_channels``.

    Raises:
        BVHFormatError: with the source, the 1-based line number and what was expected
            (missing HIERARCHY/MOTION, bad tokens, wrong value counts, non-numeric or
            non-finite values, a ``Frames:`` count that disagrees with the frame lines).
    """
    source = str(source)
    lines = text.splitlines()
    tk = _Tokens(lines, source)
    if tk.peek() is None:
        raise BVHFormatError(source, "line 1: expected 'HIERARCHY', the file is empty")
    tk.expect("HIERARCHY")
    tok, line = tk.next("'ROOT'")
    if tok.upper() != "ROOT":
        raise tk.error(f"expected 'ROOT', got '{tok}'", line)
    root, _ = tk.name("the root joint's name")
    out: dict = {"names": [], "parents": [], "offsets": [], "channels": [], "end_sites": []}
    _parse_joint(tk, root, -1, out)
    if tk.peek() is not None:
        tok, line = tk.items[tk.pos]
        what = (
            "a second ROOT (only one skeleton per file is supported)"
            if tok.upper() == "ROOT"
            else f"'{tok}'"
        )
        raise tk.error(f"expected 'MOTION' after the hierarchy, got {what}", line)
    if tk.motion_line is None:
        raise BVHFormatError(
            source, f"line {len(lines)}: expected a 'MOTION' section after the hierarchy, file ends"
        )
    skeleton = BVHSkeleton(
        names=tuple(out["names"]),
        parents=tuple(out["parents"]),
        offsets=np.asarray(out["offsets"], dtype=np.float64).reshape(-1, 3),
        channels=tuple(out["channels"]),
        end_sites=tuple(out["end_sites"]),
    )

    # MOTION header: "Frames: N" and "Frame Time: dt", each on its own line.
    i = tk.motion_line + 1
    header: dict[str, str] = {}
    for key, pattern in (
        ("Frames", r"frames\s*:\s*(\S*)\s*$"),
        ("Frame Time", r"frame\s+time\s*:\s*(\S*)\s*$"),
    ):
        while i < len(lines) and not lines[i].strip():
            i += 1
        if i >= len(lines):
            raise BVHFormatError(
                source, f"line {len(lines)}: expected '{key}:' after MOTION, file ends"
            )
        m = re.match(pattern, lines[i].strip(), flags=re.IGNORECASE)
        if m is None:
            raise BVHFormatError(
                source, f"line {i + 1}: expected '{key}: <number>', got '{lines[i].strip()}'"
            )
        header[key] = m.group(1)
        i += 1
    try:
        n_frames = int(header["Frames"])
    except ValueError:
        n_frames = -1
    if n_frames < 0:
        raise BVHFormatError(
            source,
            f"line {i - 1}: 'Frames:' must be a non-negative integer, got '{header['Frames']}'",
        )
    try:
        frame_time = float(header["Frame Time"])
    except ValueError:
        frame_time = float("nan")
    problem = frame_time_problem(frame_time)
    if problem is not None:
        raise BVHFormatError(source, f"line {i}: {problem}, got '{header['Frame Time']}'")
    motion = _parse_frames(lines, i, n_frames, skeleton.num_channels, source)
    return BVH(skeleton=skeleton, motion=motion, frame_time=frame_time, source=source)


def read_bvh(path: str | Path) -> BVH:
    """Read and parse a BVH file (see ``parse_bvh``)."""
    path = Path(path)
    text = read_text_bounded(path, MAX_BVH_BYTES, "one BVH file", BVHFormatError, errors="replace")
    return parse_bvh(text, source=path)


# ----------------------------------------------------------------------------------------
# Euler angles
# ----------------------------------------------------------------------------------------
def _axis_matrix(axis: int, angle: np.ndarray) -> np.ndarray:
    """``(...,)`` radians -> ``(..., 3, 3)`` rotation about one coordinate axis."""
    c, s = np.cos(angle), np.sin(angle)
    R = np.zeros(angle.shape + (3, 3))
    i, j = (axis + 1) % 3, (axis + 2) % 3
    R[..., axis, axis] = 1.0
    R[..., i, i] = c
    R[..., j, j] = c
    R[..., j, i] = s
    R[..., i, j] = -s
    return R


def euler_to_matrix(angles: np.ndarray, order: str, degrees: bool = True) -> np.ndarray:
    """Euler angles -> rotation matrices, composed left to right.

    Args:
        angles: ``(..., K)`` angles, ``K = len(order)``.
        order: axis letters, e.g. ``"ZXY"`` (any length; repeated axes allowed).
        degrees: whether ``angles`` are in degrees (BVH) or radians.

    Returns:
        ``(..., 3, 3)`` ``R = R_order[0](a0) @ R_order[1](a1) @ ...``.
    """
    angles = np.asarray(angles, dtype=np.float64)
    if angles.shape[-1] != len(order):
        raise ValueError(f"angles (..., {angles.shape[-1]}) do not match order '{order}'")
    if degrees:
        angles = np.deg2rad(angles)
    R = np.broadcast_to(np.eye(3), angles.shape[:-1] + (3, 3))
    for k, ax in enumerate(order.upper()):
        R = R @ _axis_matrix(_AXIS[ax], angles[..., k])
    return np.array(R)


def matrix_to_euler(R: np.ndarray, order: str, degrees: bool = True) -> np.ndarray:
    """Rotation matrices -> Tait-Bryan angles with ``R = R_i(a) @ R_j(b) @ R_k(c)``.

    Args:
        R: ``(..., 3, 3)`` rotation matrices.
        order: three distinct axis letters, e.g. ``"ZXY"``.
        degrees: return degrees (BVH) or radians.

    Returns:
        ``(..., 3)`` angles; the middle one is in ``[-90, 90]`` degrees. At gimbal lock
        (middle angle +-90) the last angle is set to 0.
    """
    order = order.upper()
    if len(order) != 3 or len(set(order)) != 3:
        raise ValueError(f"order must be three distinct axes, got '{order}'")
    i, j, k = (_AXIS[a] for a in order)
    s = 1.0 if (j - i) % 3 == 1 else -1.0  # +1 for cyclic orders (XYZ, YZX, ZXY)
    R = np.asarray(R, dtype=np.float64)
    cos_b = np.hypot(R[..., i, i], R[..., i, j])
    b = np.arctan2(s * R[..., i, k], cos_b)
    a = np.arctan2(-s * R[..., j, k], R[..., k, k])
    c = np.arctan2(-s * R[..., i, j], R[..., i, i])
    lock = cos_b < 1e-9  # R = R_i(a) R_j(+-90): read a from column j, set c = 0
    if np.any(lock):
        a = np.where(lock, np.arctan2(s * R[..., k, j], R[..., j, j]), a)
        c = np.where(lock, 0.0, c)
    out = np.stack([a, b, c], axis=-1)
    return np.rad2deg(out) if degrees else out


# ----------------------------------------------------------------------------------------
# Forward kinematics
# ----------------------------------------------------------------------------------------
def bvh_local_transforms(bvh: BVH) -> tuple[np.ndarray, np.ndarray]:
    """Per-frame local rotations and translations from the channel values.

    Returns:
        ``rot (T, J, 3, 3)``: joint frame -> parent frame.
        ``trans (T, J, 3)``: joint origin in the parent frame (the OFFSET, with the
        components that have position channels replaced by their values), file units.
    """
    sk = bvh.skeleton
    T, J = bvh.num_frames, sk.num_joints
    rot = np.empty((T, J, 3, 3))
    trans = np.broadcast_to(sk.offsets, (T, J, 3)).copy()
    start = 0
    for j, chans in enumerate(sk.channels):
        order = ""
        cols: list[int] = []
        for c, name in enumerate(chans):
            if name.endswith("position"):
                trans[:, j, _AXIS[name[0]]] = bvh.motion[:, start + c]
            else:
                order += name[0]
                cols.append(start + c)
        if order:
            rot[:, j] = euler_to_matrix(bvh.motion[:, cols], order)
        else:
            rot[:, j] = np.eye(3)
        start += len(chans)
    return rot, trans


def forward_kinematics(
    parents: tuple[int, ...] | list[int], rot: np.ndarray, trans: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Global rotations and positions from local ones, vectorised over frames.

    Args:
        parents: ``J`` parent indices (-1 for roots); parents precede children.
        rot: ``(T, J, 3, 3)`` local rotations (joint frame -> parent frame).
        trans: ``(T, J, 3)`` joint origins in the parent frame (world frame for roots).

    Returns:
        ``global_rot (T, J, 3, 3)`` joint frame -> world and ``positions (T, J, 3)``.
    """
    g_rot = np.empty_like(rot)
    pos = np.empty_like(trans)
    for j, p in enumerate(parents):
        if p < 0:
            g_rot[:, j] = rot[:, j]
            pos[:, j] = trans[:, j]
        else:
            g_rot[:, j] = g_rot[:, p] @ rot[:, j]
            pos[:, j] = pos[:, p] + np.einsum("tab,tb->ta", g_rot[:, p], trans[:, j])
    return g_rot, pos


def _forward_kinematics_naive(parents, rot, trans):
    """Frame-by-frame 4x4 reference for ``forward_kinematics`` (tests only)."""
    T, J = rot.shape[:2]
    g_rot = np.zeros_like(rot)
    pos = np.zeros_like(trans)
    for t in range(T):
        world = [None] * J
        for j in range(J):
            M = np.eye(4)
            M[:3, :3] = rot[t, j]
            M[:3, 3] = trans[t, j]
            world[j] = M if parents[j] < 0 else world[parents[j]] @ M
            g_rot[t, j] = world[j][:3, :3]
            pos[t, j] = world[j][:3, 3]
    return g_rot, pos


def bvh_forward_kinematics(bvh: BVH) -> tuple[np.ndarray, np.ndarray]:
    """``(global_rot (T, J, 3, 3), positions (T, J, 3))`` of a BVH in file units."""
    rot, trans = bvh_local_transforms(bvh)
    return forward_kinematics(bvh.skeleton.parents, rot, trans)


# ----------------------------------------------------------------------------------------
# Writing
# ----------------------------------------------------------------------------------------
def _fmt(x: float) -> str:
    s = f"{x:.6f}".rstrip("0").rstrip(".")
    return "0" if s in ("-0", "") else s


def format_bvh(bvh: BVH, *, precision: int = 6) -> str:
    """BVH text of ``bvh`` (tab-indented hierarchy, one frame per line).

    The hierarchy is written depth first; joints stored in another order (e.g. SMPL's
    breadth-first one) are reordered, and their frame values with them, so reading the
    text back gives the same skeleton up to joint order.

    ``precision`` is the number of decimals of the frame values (6 keeps Euler angles in
    degrees to 1e-6, i.e. about 2e-8 rad).
    """
    sk = bvh.skeleton
    kids: list[list[int]] = [[] for _ in sk.names]
    for j, p in enumerate(sk.parents):
        if p >= 0:
            kids[p].append(j)
    ends: dict[int, list[np.ndarray]] = {}
    for j, off in sk.end_sites:
        ends.setdefault(j, []).append(off)
    out = ["HIERARCHY"]

    order: list[int] = []  # joints in the order written: frame values must follow it

    def emit(j: int, depth: int) -> None:
        order.append(j)
        ind = "\t" * depth
        kw = "ROOT" if sk.parents[j] < 0 else "JOINT"
        out.append(f"{ind}{kw} {sk.names[j]}")
        out.append(f"{ind}{{")
        out.append(f"{ind}\tOFFSET " + " ".join(_fmt(v) for v in sk.offsets[j]))
        if sk.channels[j]:
            out.append(f"{ind}\tCHANNELS {len(sk.channels[j])} " + " ".join(sk.channels[j]))
        for c in kids[j]:
            emit(c, depth + 1)
        for off in ends.get(j, []):
            out.extend(
                [
                    f"{ind}\tEnd Site",
                    f"{ind}\t{{",
                    f"{ind}\t\tOFFSET " + " ".join(_fmt(v) for v in off),
                    f"{ind}\t}}",
                ]
            )
        out.append(f"{ind}}}")

    for r in (j for j, p in enumerate(sk.parents) if p < 0):
        emit(r, 0)
    frame_time = f"{bvh.frame_time:.8f}"
    problem = frame_time_problem(float(frame_time))  # as written: what a reader sees
    if problem is not None:
        raise BVHFormatError(
            bvh.source, f"cannot write a BVH: {problem}, got {bvh.frame_time:.8g} s"
        )
    out += ["MOTION", f"Frames: {bvh.num_frames}", f"Frame Time: {frame_time}"]
    text = "\n".join(out) + "\n"
    if bvh.num_frames:
        starts = sk.channel_starts()
        cols = np.concatenate(
            [np.arange(starts[j], starts[j] + len(sk.channels[j])) for j in order]
        )
        values = bvh.motion[:, cols.astype(np.int64)]
        pieces = [text]
        for a in range(0, len(values), 4096):  # in pieces: a few MB of strings at a time
            body = np.char.mod(f"%.{precision}f", np.round(values[a : a + 4096], precision) + 0.0)
            pieces.append("\n".join(" ".join(row) for row in body) + "\n")
        text = "".join(pieces)
    return text


def write_bvh(path: str | Path, bvh: BVH, *, precision: int = 6, overwrite: bool = True) -> Path:
    """Write ``bvh`` to ``path`` (see ``format_bvh``); returns the path.

    Written atomically and never through a symbolic link (``mrlib.io.outputs``);
    ``overwrite=False`` refuses an existing file (``OutputExistsError``)."""
    from mrlib.io.outputs import write_text

    return write_text(Path(path), format_bvh(bvh, precision=precision), overwrite=overwrite)
