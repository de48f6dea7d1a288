"""Reading BVH files: a strict parser that refuses a malformed file with its 1-based line
number and what was expected, and never reads a file larger than ``MAX_BVH_BYTES``.
Conventions: ``mrlib.io.bvh``.
"""

from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np

from mrlib.errors import BVHFormatError
from mrlib.io.bvh.hierarchy import BVH, BVHSkeleton, frame_time_problem
from mrlib.io.paths import read_text_bounded

__all__ = ["MAX_DEPTH", "MAX_BVH_BYTES", "parse_bvh", "read_bvh"]

_CHANNEL_NAMES = {
    "xposition": "Xposition",
    "yposition": "Yposition",
    "zposition": "Zposition",
    "xrotation": "Xrotation",
    "yrotation": "Yrotation",
    "zrotation": "Zrotation",
}

MAX_DEPTH = 256  # joints nested deeper than this are refused (humanoid rigs: < 40)
# files over this are refused from their size, before reading: about 20 minutes of a
# 60-joint rig at 120 fps; mrlib trains on at most 18,000 frames of a clip anyway
MAX_BVH_BYTES = 256 * 2**20


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
            where = (
                "the hierarchy ends at MOTION" if self.motion_line is not None else "the file ends"
            )
            raise self.error(f"expected {what}, but {where} (truncated hierarchy?)")
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
        declared = next(
            (i + 1 for i in range(first - 1, -1, -1) if lines[i].lstrip().startswith("Frames")),
            first,
        )
        if short:
            raise BVHFormatError(
                source,
                f"line {declared}: 'Frames: {n_frames}' but the file ends at line {len(lines)} "
                f"after {len(rows)} frame lines (truncated file?)",
            )
        raise BVHFormatError(
            source,
            f"line {row_lines[n_frames]}: more frame lines than declared ('Frames: {n_frames}' "
            f"on line {declared}; the file has {len(rows)})",
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
        text: the whole file (a leading byte-order mark is skipped; a ``Frame Time:``
            written with a decimal comma, and no point, is read with the frame lines
            that follow it the same way).
        source: a name for error messages (the path when reading a file).

    Returns:
        A ``BVH``; ``motion`` is ``(T, C)`` with ``C = skeleton.num_channels``.

    Raises:
        BVHFormatError: with the source, the 1-based line number and what was expected
            (missing HIERARCHY/MOTION, bad tokens, wrong value counts, non-numeric or
            non-finite values, a ``Frames:`` count that disagrees with the frame lines).
    """
    source = str(source)
    lines = text.removeprefix("\ufeff").splitlines()  # a byte-order mark (Windows tools)
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
    ft = header["Frame Time"]
    # a decimal comma (a locale's export: "0,0333333"): the frame lines are written so too
    comma = "," in ft and "." not in ft
    try:
        frame_time = float(ft.replace(",", ".") if comma else ft)
    except ValueError:
        frame_time = float("nan")
    problem = frame_time_problem(frame_time)
    if problem is not None:
        raise BVHFormatError(source, f"line {i}: {problem}, got '{header['Frame Time']}'")
    if comma:
        lines = lines[:i] + [ln.replace(",", ".") for ln in lines[i:]]
    motion = _parse_frames(lines, i, n_frames, skeleton.num_channels, source)
    return BVH(skeleton=skeleton, motion=motion, frame_time=frame_time, source=source)


def read_bvh(path: str | Path) -> BVH:
    """Read and parse a BVH file (see ``parse_bvh``)."""
    path = Path(path)
    text = read_text_bounded(path, MAX_BVH_BYTES, "one BVH file", BVHFormatError, errors="replace")
    return parse_bvh(text, source=path)
