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


# -- path CSVs and keyframe files (mrlib sample --path / --keyframes) --------------------
PATH_CSV = b"# a walk\nx,z,t\n0,0,0\n1.5,0.2,1.0\n3,1,2.25\n4,2.5,3.5\n"


@st.composite
def path_texts(draw) -> bytes:
    """CSV-like text built from pieces a path file is made of (headers, separators,
    numbers good and bad, comments, stray bytes)."""
    header = draw(st.sampled_from(["", "x,z\n", "x,z,t\n", "t,x,z\n", "x z\n", "x,y\n", ",,\n",
                                   "x,x,z\n", "X, Z, T\n"]))  # fmt: skip
    sep = draw(st.sampled_from([",", " ", "\t", ", ", ";"]))
    number = st.one_of(
        st.floats(-1e3, 1e3, allow_nan=False).map(lambda v: f"{v:.3f}"),
        st.sampled_from(BAD_NUMBERS + ["", "x", "1e999", "0x10", "1_0", "\u00b9"]),
    )
    rows = draw(st.lists(st.lists(number, min_size=0, max_size=4), min_size=0, max_size=8))
    body = "\n".join(sep.join(r) for r in rows)
    tail = draw(st.sampled_from([b"", b"\n# end\n", b"\xff\xfe", b"\x00", b"#\xe9\n"]))
    return header.encode() + body.encode() + tail


def _keyframe_npz() -> bytes:

    from mrlib.sampling.constraints import Keyframe, save_keyframes

    m = synthetic_walk("walk_sad", seconds=1.0, fps=10.0)
    kfs = [Keyframe.from_motion(m, 0, 0), Keyframe.from_motion(m, 5, 12, joints=[0, 3, 6])]
    import tempfile

    with tempfile.TemporaryDirectory() as tmp:
        return save_keyframes(Path(tmp) / "kf.npz", kfs).read_bytes()


def _keyframe_npz_with(**arrays) -> bytes:
    """A keyframe file whose arrays are replaced (shape, dtype and value damage)."""
    from io import BytesIO

    with np.load(BytesIO(_keyframe_npz())) as z:
        d = {k: z[k] for k in z.files}
    d.update(arrays)
    buf = BytesIO()
    np.savez(buf, **d)
    return buf.getvalue()


@st.composite
def keyframe_arrays(draw) -> bytes:
    """A keyframe file with one array replaced by a damaged one."""
    key = draw(st.sampled_from(["frames", "poses", "joint_mask", "trans", "trans_mask"]))
    value = draw(
        st.sampled_from(
            [
                np.array(np.nan), np.array(3), np.array(["a", "b"]), np.array([0.0, np.nan]),
                np.array([1.7, 2.0]), np.array([-1, 3]), np.array([0, 10**12]),
                np.zeros((2, 24)), np.ones(2, bool), np.full((2, 24, 3), 1e30),
                np.full((2, 3), np.inf), np.zeros((3, 24, 3)), np.zeros((2, 3), np.complex64),
                np.zeros((0,)), np.array([True, False]), np.full((2, 24), 2),
            ]
        )
    )  # fmt: skip
    return _keyframe_npz_with(**{key: value})


def _check_constraint_file(path: Path, payload: bytes, kind: str) -> None:
    from mrlib.sampling.constraints import GroundPath, load_keyframes

    path.write_bytes(payload)
    try:
        if kind == "csv":
            p = GroundPath.from_csv(path)
            assert np.isfinite(p.points).all() and np.abs(p.points).max() <= 1e6
            assert np.isfinite(p.length) and len(p.points) >= 2
            if p.times is not None:
                assert np.isfinite(p.times).all() and (np.diff(p.times) > 0).all()
        else:
            for kf in load_keyframes(path):
                assert 0 <= kf.frame <= 5_000_000 and isinstance(kf.frame, int)
                if kf.poses is not None:
                    assert np.isfinite(kf.poses).all() and kf.poses.shape == (24, 3)
                if kf.trans is not None:
                    assert np.isfinite(kf.trans).all() and np.abs(kf.trans).max() <= 1000
    except MrlibError as e:
        assert path.name in str(e), f"error does not name the file: {e}"


def test_the_unmutated_constraint_files_load(tmp_path):
    from mrlib.sampling.constraints import GroundPath, load_keyframes

    (tmp_path / "p.csv").write_bytes(PATH_CSV)
    assert GroundPath.from_csv(tmp_path / "p.csv").duration == pytest.approx(3.5)
    (tmp_path / "kf.npz").write_bytes(_keyframe_npz())
    kfs = load_keyframes(tmp_path / "kf.npz")
    assert [k.frame for k in kfs] == [0, 12] and kfs[1].joints == (0, 3, 6)


@pytest.mark.parametrize("source", ["mutated", "built"])
def test_a_damaged_path_csv_parses_or_raises_an_mrlib_error(source, tmp_path):
    strategy = mutations(PATH_CSV) if source == "mutated" else path_texts()

    @FUZZ
    @given(strategy)
    def run(payload):
        _check_constraint_file(tmp_path / "fuzz.csv", payload, "csv")

    run()


@pytest.mark.parametrize("source", ["mutated", "arrays"])
def test_a_damaged_keyframe_file_loads_or_raises_an_mrlib_error(source, tmp_path):
    strategy = mutations(_keyframe_npz()) if source == "mutated" else keyframe_arrays()

    @FUZZ
    @given(strategy)
    def run(payload):
        _check_constraint_file(tmp_path / "fuzz.npz", payload, "npz")

    run()


# the cases, each by name
CONSTRAINT_CASES = {
    "3-column header over 2-column rows": ("csv", b"x,z,t\n0,0\n1,1\n"),
    "first line ,,": ("csv", b",,\n0,0\n1,1\n"),
    "non-UTF-8 in a comment": ("csv", b"# caf\xe9\n0,0\n1,1\n"),
    "t = 1e9": ("csv", b"0,0,0\n1,0,1e9\n"),
    "coordinates 1e308": ("csv", b"0,0\n1e308,0\n"),
    "a FIFO-like empty file": ("csv", b""),
    "NaN frame": ("npz", None),
    "0-d frames": ("npz", None),
    "string frames": ("npz", None),
    "frame 1.7": ("npz", None),
    "1-D joint_mask": ("npz", None),
    "axis-angle x 1e30": ("npz", None),
    "a .npy renamed .npz": ("npz", None),
}


def _constraint_payload(name: str) -> bytes:
    import io

    kind, payload = CONSTRAINT_CASES[name]
    if payload is not None:
        return payload
    if name == ".npy renamed .npz" or name == "a .npy renamed .npz":
        buf = io.BytesIO()
        np.save(buf, np.zeros((3, 72)))
        return buf.getvalue()
    return _keyframe_npz_with(
        **{
            "NaN frame": {"frames": np.array([0.0, np.nan])},
            "0-d frames": {"frames": np.array(3)},
            "string frames": {"frames": np.array(["a", "b"])},
            "frame 1.7": {"frames": np.array([0.0, 1.7])},
            "1-D joint_mask": {"joint_mask": np.ones(2, bool)},
            "axis-angle x 1e30": {"poses": np.full((2, 24, 3), 1e30)},
        }[name]
    )


@pytest.mark.parametrize("name", list(CONSTRAINT_CASES))
def test_named_constraint_file_cases_are_refused(name, tmp_path):
    from mrlib.sampling.constraints import GroundPath, load_keyframes

    kind = CONSTRAINT_CASES[name][0]
    path = tmp_path / f"case.{kind}"
    path.write_bytes(_constraint_payload(name))
    with pytest.raises(MrlibError, match=r"case\."):
        (GroundPath.from_csv if kind == "csv" else load_keyframes)(path)
