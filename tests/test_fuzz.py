"""Property: a damaged motion file loads as finite motion or raises an MrlibError that
names the file; never another exception, never a hang.

Mutations of a real Bandai Namco BVH (cut to a few frames at test time, never stored)
and of an npz written by mrlib: byte flips, truncation, line deletion, and numbers
replaced by nan, inf, 1e308, huge integers and the like. ``make test`` runs a slice
(``MRLIB_FUZZ_EXAMPLES``, default 60 per file type, derandomised); a long local run:

    MRLIB_FUZZ_EXAMPLES=5000 MRLIB_FUZZ_RANDOM=1 pytest tests/test_fuzz.py
"""

from __future__ import annotations

import os
import re
import signal
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from mrlib.datasets.synthetic import synthetic_walk
from mrlib.errors import MrlibError
from mrlib.io import default_data_dir, load_motion, save_motion
from mrlib.representation.motion import Motion

# damaged numbers overflow in numpy on their way to being refused: expected here
pytestmark = pytest.mark.filterwarnings("ignore::RuntimeWarning")
EXAMPLES = int(os.environ.get("MRLIB_FUZZ_EXAMPLES", "60"))
FUZZ = settings(
    max_examples=EXAMPLES,
    deadline=None,
    derandomize=not os.environ.get("MRLIB_FUZZ_RANDOM"),
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture],
    database=None,
)
TIME_BOX_S = 20  # one load; a hang fails the test
BAD_NUMBERS = ["nan", "inf", "-inf", "1e308", "-1e308", "1e-320", "9" * 40, "-0", "1e30", "0"]
BANDAI_BVH = default_data_dir() / "data" / "dataset-1_walk_normal_001.bvh"


def _short_bvh(path: Path, frames: int = 12) -> bytes:
    """The file's hierarchy and its first ``frames`` frames."""
    text = path.read_text()
    head, motion = text.split("MOTION", 1)
    lines = motion.strip().splitlines()
    body = [ln for ln in lines[2:] if ln.strip()][:frames]
    return f"{head}MOTION\nFrames: {len(body)}\n{lines[1]}\n" + "\n".join(body) + "\n"


@pytest.fixture(scope="module")
def bvh_bytes() -> bytes:
    if not BANDAI_BVH.is_file():
        pytest.skip(f"Bandai Namco data not found at {BANDAI_BVH.parent}")
    return _short_bvh(BANDAI_BVH).encode()


@pytest.fixture(scope="module")
def npz_bytes(tmp_path_factory) -> bytes:
    m = synthetic_walk("walk_sad", seconds=1.2, fps=10.0)
    path = save_motion(m.replace(label="walk_sad"), tmp_path_factory.mktemp("npz") / "clip.npz")
    return path.read_bytes()


@st.composite
def mutations(draw, data: bytes):
    kind = draw(st.sampled_from(["flip", "truncate", "delete_line", "number", "several"]))
    out = bytearray(data)
    for _ in range(draw(st.integers(2, 6)) if kind == "several" else 1):
        k = kind if kind != "several" else draw(st.sampled_from(["flip", "number", "delete_line"]))
        if k == "flip" and out:
            i = draw(st.integers(0, len(out) - 1))
            out[i] ^= draw(st.integers(1, 255))
        elif k == "truncate":
            out = out[: draw(st.integers(0, len(out)))]
        elif k == "delete_line":
            lines = bytes(out).split(b"\n")
            del lines[draw(st.integers(0, len(lines) - 1))]
            out = bytearray(b"\n".join(lines))
        elif k == "number":
            spans = [m.span() for m in re.finditer(rb"-?\d+(\.\d+)?(e-?\d+)?", bytes(out))]
            if spans:
                a, b = spans[draw(st.integers(0, len(spans) - 1))]
                out[a:b] = draw(st.sampled_from(BAD_NUMBERS)).encode()
    return bytes(out)


class _Hang(Exception):
    pass


def _load_within_time_box(path: Path):
    def on_alarm(signum, frame):
        raise _Hang(f"loading {path.name} took more than {TIME_BOX_S} s")

    old = signal.signal(signal.SIGALRM, on_alarm)
    signal.alarm(TIME_BOX_S)
    try:
        return load_motion(path)
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, old)


def _check(path: Path, payload: bytes) -> None:
    path.write_bytes(payload)
    try:
        m = _load_within_time_box(path)
    except MrlibError as e:
        assert path.name in str(e), f"error does not name the file: {e}"
        return
    assert isinstance(m, Motion)
    assert np.isfinite(m.poses).all() and np.isfinite(m.trans).all() and m.num_frames >= 1


def test_the_unmutated_files_load(bvh_bytes, npz_bytes, tmp_path):
    for name, payload in (("clip.bvh", bvh_bytes), ("clip.npz", npz_bytes)):
        (tmp_path / name).write_bytes(payload)
        assert load_motion(tmp_path / name).num_frames >= 10


@pytest.mark.slow
@pytest.mark.parametrize("kind", ["bvh", "npz"])
def test_a_damaged_file_loads_or_raises_an_mrlib_error(kind, request, tmp_path):
    data = request.getfixturevalue(f"{kind}_bytes")

    @FUZZ
    @given(mutations(data))
    def run(payload):
        _check(tmp_path / f"fuzz.{kind}", payload)

    run()
