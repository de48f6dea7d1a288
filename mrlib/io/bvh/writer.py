"""Writing BVH files: ``format_bvh`` emits exactly what the reader
(``mrlib.io.bvh.reader``) accepts, ``write_bvh`` writes it atomically
(``mrlib.io.outputs``). Conventions: ``mrlib.io.bvh``.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from mrlib.errors import BVHFormatError
from mrlib.io.bvh.hierarchy import BVH, frame_time_problem

__all__ = ["format_bvh", "write_bvh"]


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
