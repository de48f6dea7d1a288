"""The BEAT2 files mrlib knows (``mrlib.datasets.beat2``): fetched for real from a local
HTTP server on 127.0.0.1 that serves them in the host's layout (``$MRLIB_BEAT2_URL``
points at it; the cache is a temporary folder), read from a local copy first, laid out
for ``SpeechTrainingSet.from_folders``, and made into a training set in one call.

The good-fetch and training-set tests serve / read the offline sample in ``../shared``
(skipped without it); the others use bytes made here. The real host (Hugging Face) is
never asked: its layout and revision are unverified (see the module's docstring)."""

from __future__ import annotations

import hashlib
import http.server
import os
import threading
from pathlib import Path

import numpy as np
import pytest

from mrlib.datasets import beat2
from mrlib.datasets.fetching import DataFetchError

ROOT = Path(__file__).resolve().parents[1]
SAMPLE = Path(os.environ.get("MRLIB_BEAT2_SAMPLE", ROOT.parent / "shared/data/beat2-sample"))
# the sample's own layout (flat, audio-only clips in unpaired/) -> the host's paths
SAMPLE_FILES = {
    "smplxflame_30/2_scott_0_1_1.npz": "2_scott_0_1_1.npz",
    "wave16k/2_scott_0_1_1.wav": "2_scott_0_1_1.wav",
    "wave16k/2_scott_0_2_2.wav": "unpaired/2_scott_0_2_2.wav",
    "wave16k/2_scott_0_3_3.wav": "unpaired/2_scott_0_3_3.wav",
    "wave16k/2_scott_0_4_4.wav": "unpaired/2_scott_0_4_4.wav",
}
needs_sample = pytest.mark.skipif(
    not all((SAMPLE / f).is_file() for f in SAMPLE_FILES.values()), reason="no BEAT2 sample here"
)
PREFIX = "/" + beat2.BEAT2_SUBDIR + "/"


class _Server:
    """Serves ``files`` ({registry path: bytes or a file}) at
    ``http://127.0.0.1:<port>/<ref>/beat_english_v2.0.0/<registry path>``; counts
    requests."""

    def __init__(self, files: dict[str, bytes | Path]):
        self.files, self.requests = files, []
        outer = self

        class Handler(http.server.BaseHTTPRequestHandler):
            def do_GET(self):  # noqa: N802 (http.server's name)
                outer.requests.append(self.path)
                rel = self.path.split(PREFIX, 1)[-1] if PREFIX in self.path else None
                body = outer.files.get(rel) if rel is not None else None
                body = body.read_bytes() if isinstance(body, Path) else body
                if body is None:
                    self.send_error(404)
                    return
                self.send_response(200)
                self.send_header("Content-Length", str(len(body)))
                self.end_headers()
                self.wfile.write(body)

            def log_message(self, *args):
                pass

        self.httpd = http.server.ThreadingHTTPServer(("127.0.0.1", 0), Handler)
        self.url = f"http://127.0.0.1:{self.httpd.server_address[1]}/{beat2.BEAT2_REF}"
        threading.Thread(target=self.httpd.serve_forever, daemon=True).start()

    def close(self):
        self.httpd.shutdown()
        self.httpd.server_close()


@pytest.fixture
def cache(tmp_path, monkeypatch):
    """An empty cache and no local copy: what a fresh clone has."""
    monkeypatch.setenv("MRLIB_CACHE_DIR", str(tmp_path / "cache"))
    monkeypatch.setenv("MRLIB_BEAT2_DIR", str(tmp_path / "no-such-folder"))
    return tmp_path / "cache" / "beat2"


def _fake_local(root: Path, layout: str) -> dict[str, Path]:
    """A local copy of made-up bytes in the host's or the sample's layout."""
    out = {}
    for rel, flat in SAMPLE_FILES.items():
        p = root / (rel if layout == "host" else flat)
        p.parent.mkdir(parents=True, exist_ok=True)
        p.write_bytes(rel.encode())
        out[rel] = p
    return out


def test_the_registry_lists_five_files_of_speaker_2_with_hash_and_size():
    reg, sizes = beat2.beat2_registry(), beat2.beat2_sizes()
    assert list(reg) == list(SAMPLE_FILES) and set(sizes) == set(reg)
    assert all(v.startswith("sha256:") and len(v) == 7 + 64 for v in reg.values())
    assert beat2.beat2_clips()["2_scott_0_1_1"] == tuple(list(SAMPLE_FILES)[:2])
    assert beat2.BEAT2_REF in beat2.BEAT2_URL  # "main" until verified: see the docstring


@needs_sample
def test_the_registry_matches_the_sample():
    reg, sizes = beat2.beat2_registry(), beat2.beat2_sizes()
    for rel, flat in SAMPLE_FILES.items():
        data = (SAMPLE / flat).read_bytes()
        assert reg[rel] == "sha256:" + hashlib.sha256(data).hexdigest() and sizes[rel] == len(data)


@needs_sample
def test_fetch_from_a_server_then_reuse_the_cache(cache, monkeypatch, capsys):
    srv = _Server({rel: SAMPLE / flat for rel, flat in SAMPLE_FILES.items()})
    try:
        monkeypatch.setenv("MRLIB_BEAT2_URL", srv.url)
        assert beat2.beat2_dir() == cache
        assert beat2.fetch_beat2(progress=False) == cache
        for rel, flat in SAMPLE_FILES.items():
            assert (cache / rel).read_bytes() == (SAMPLE / flat).read_bytes()
        assert len(srv.requests) == 5
        assert all(r.startswith(f"/{beat2.BEAT2_REF}{PREFIX}") for r in srv.requests)
        assert "CC BY-NC 4.0" in capsys.readouterr().out  # the licence, on first download
        beat2.fetch_beat2(["2_scott_0_1_1"], progress=False)
        paired, unpaired = beat2.beat2_speech_folders(progress=False)
        assert len(srv.requests) == 5  # cached: no request
        assert "CC BY-NC" not in capsys.readouterr().out  # said once
    finally:
        srv.close()
    assert sorted(p.name for p in paired.iterdir()) == ["2_scott_0_1_1.npz", "2_scott_0_1_1.wav"]
    assert (paired / "2_scott_0_1_1.npz").resolve() == cache / "smplxflame_30/2_scott_0_1_1.npz"
    assert sorted(p.name for p in unpaired.iterdir()) == [
        f"2_scott_0_{k}_{k}.wav" for k in (2, 3, 4)
    ]


def test_a_file_with_another_hash_is_refused_and_not_kept(cache, monkeypatch):
    srv = _Server({"wave16k/2_scott_0_2_2.wav": b"RIFF but not the same file"})
    try:
        monkeypatch.setenv("MRLIB_BEAT2_URL", srv.url)
        with pytest.raises(DataFetchError) as err:
            beat2.fetch_beat2(["2_scott_0_2_2"], progress=False)
    finally:
        srv.close()
    msg = str(err.value)
    assert "\n" not in msg and "SHA-256" in msg and "2_scott_0_2_2.wav" in msg
    assert srv.url in msg and "MRLIB_BEAT2_URL" in msg
    assert [p for p in cache.rglob("*") if p.is_file()] == []  # no partial or temporary file


def test_a_dead_server_and_an_unknown_stem_are_one_line(cache, monkeypatch):
    monkeypatch.setenv("MRLIB_BEAT2_URL", "http://127.0.0.1:9/x")
    with pytest.raises(DataFetchError) as err:
        beat2.fetch_beat2(["2_scott_0_3_3"], progress=False)
    msg = str(err.value)
    assert "\n" not in msg and "127.0.0.1:9/x/beat_english_v2.0.0/wave16k/" in msg
    assert "MRLIB_BEAT2_DIR" in msg
    with pytest.raises(DataFetchError, match="not a BEAT2 clip mrlib can fetch"):
        beat2.fetch_beat2(["1_wayne_0_1_1"], progress=False)


@pytest.mark.parametrize("layout", ["host", "sample"])
def test_a_local_copy_in_mrlib_beat2_dir_is_read_first(tmp_path, monkeypatch, layout):
    local = _fake_local(tmp_path / "beat2", layout)
    monkeypatch.setenv("MRLIB_BEAT2_DIR", str(tmp_path / "beat2"))
    monkeypatch.setenv("MRLIB_CACHE_DIR", str(tmp_path / "cache"))
    monkeypatch.setenv("MRLIB_BEAT2_URL", "http://127.0.0.1:9/never-asked")
    assert beat2.beat2_local_dir() == beat2.beat2_dir() == tmp_path / "beat2"
    assert beat2.beat2_files(progress=False) == local  # no download: the server is dead
    monkeypatch.setenv("MRLIB_BEAT2_DIR", str(tmp_path / "empty"))
    (tmp_path / "empty").mkdir()
    assert beat2.beat2_local_dir() is None and beat2.beat2_dir() == tmp_path / "cache" / "beat2"


def test_speech_folders_pair_the_files_by_stem(tmp_path, monkeypatch):
    """The host's layout becomes links in the cache (no copies); the sample's layout is
    read as it is when every stem is asked for, through links for a subset."""
    local = _fake_local(tmp_path / "host", "host")
    monkeypatch.setenv("MRLIB_BEAT2_DIR", str(tmp_path / "host"))
    monkeypatch.setenv("MRLIB_CACHE_DIR", str(tmp_path / "cache"))
    paired, unpaired = beat2.beat2_speech_folders(progress=False)
    assert tmp_path / "cache" in paired.parents and unpaired.parent == paired.parent
    assert {p.name: p.resolve() for p in paired.iterdir()} == {
        "2_scott_0_1_1.npz": local["smplxflame_30/2_scott_0_1_1.npz"],
        "2_scott_0_1_1.wav": local["wave16k/2_scott_0_1_1.wav"],
    }
    assert {p.name: p.resolve() for p in unpaired.iterdir()} == {
        f"2_scott_0_{k}_{k}.wav": local[f"wave16k/2_scott_0_{k}_{k}.wav"] for k in (2, 3, 4)
    }
    assert all(p.is_symlink() for p in [*paired.iterdir(), *unpaired.iterdir()])
    assert beat2.beat2_speech_folders(progress=False) == (paired, unpaired)  # made once
    only = beat2.beat2_speech_folders(["2_scott_0_2_2.wav"], progress=False)
    assert only[0] is None and [p.name for p in only[1].iterdir()] == ["2_scott_0_2_2.wav"]

    _fake_local(tmp_path / "flat", "sample")
    monkeypatch.setenv("MRLIB_BEAT2_DIR", str(tmp_path / "flat"))
    assert beat2.beat2_speech_folders() == (tmp_path / "flat", tmp_path / "flat" / "unpaired")
    sub = beat2.beat2_speech_folders(["2_scott_0_1_1", "2_scott_0_3_3"])
    assert sub[0].parent.parent == tmp_path / "cache" / "beat2" / "speech-folders"
    assert [p.name for p in sub[1].iterdir()] == ["2_scott_0_3_3.wav"]


@needs_sample
def test_a_training_set_in_one_call_holds_one_clip_out(tmp_path, monkeypatch):
    from mrlib.speech import SpeechFeatureExtractor, beat2_training_set

    monkeypatch.setenv("MRLIB_BEAT2_DIR", str(SAMPLE))
    monkeypatch.setenv("MRLIB_CACHE_DIR", str(tmp_path / "cache"))
    monkeypatch.setenv("MRLIB_BEAT2_URL", "http://127.0.0.1:9/never-asked")
    data, held = beat2_training_set(SpeechFeatureExtractor(kind="logmel"), progress=False)
    assert data.num_paired == 1 and data.num_unpaired == 2 and data.fps == 25.0
    assert data.unpaired_names == ["2_scott_0_2_2", "2_scott_0_3_3"]
    assert held == [SAMPLE / "unpaired" / "2_scott_0_4_4.wav"]
    assert data.motion.names == ["2_scott_0_1_1"]
    assert 60 * 25 < data.motion.features[0].shape[0] < 64 * 25  # 63.5 s at 25 fps


def test_holding_out_every_clip_with_motion_is_refused(tmp_path, monkeypatch):
    from mrlib.errors import MotionValueError
    from mrlib.speech import beat2_training_set

    _fake_local(tmp_path / "beat2", "host")
    monkeypatch.setenv("MRLIB_BEAT2_DIR", str(tmp_path / "beat2"))
    monkeypatch.setenv("MRLIB_CACHE_DIR", str(tmp_path / "cache"))
    with pytest.raises(MotionValueError, match="no BEAT2 clip with motion"):
        beat2_training_set(held_out=["2_scott_0_1_1"], progress=False)
    with pytest.raises(DataFetchError, match="not a BEAT2 clip"):
        beat2_training_set(held_out=["2_scott_0_9_9"], progress=False)


def test_the_cli_says_where_and_lists(tmp_path, monkeypatch, capsys):
    from mrlib.app.cli import main

    _fake_local(tmp_path / "beat2", "sample")
    monkeypatch.setenv("MRLIB_CACHE_DIR", str(tmp_path / "cache"))
    monkeypatch.setenv("MRLIB_BEAT2_DIR", str(tmp_path / "beat2"))
    assert main(["data", "where", "beat2"]) == 0
    assert capsys.readouterr().out.strip() == str(tmp_path / "beat2")
    monkeypatch.setenv("MRLIB_BEAT2_DIR", str(tmp_path / "none"))
    assert main(["data", "where", "beat2"]) == 0
    assert capsys.readouterr().out.strip() == f"{tmp_path / 'cache' / 'beat2'} (cache)"
    assert main(["data", "list", "beat2"]) == 0
    assert capsys.readouterr().out.splitlines() == [
        "2_scott_0_1_1  motion + audio",
        "2_scott_0_2_2  audio",
        "2_scott_0_3_3  audio",
        "2_scott_0_4_4  audio",
    ]


@needs_sample
def test_the_cli_fetches_ahead_of_time(cache, monkeypatch, capsys):
    from mrlib.app.cli import main

    srv = _Server({rel: SAMPLE / flat for rel, flat in SAMPLE_FILES.items()})
    try:
        monkeypatch.setenv("MRLIB_BEAT2_URL", srv.url)
        assert main(["data", "fetch", "beat2", "--clips", "2_scott_0_1_1", "--no-progress"]) == 0
    finally:
        srv.close()
    out = capsys.readouterr().out
    assert "CC BY-NC 4.0" in out and f"2 files in {cache}" in out
    assert sorted(p.name for p in cache.rglob("*") if p.is_file()) == [
        "2_scott_0_1_1.npz",
        "2_scott_0_1_1.wav",
    ]


@needs_sample
def test_a_split_holds_out_the_last_seconds_with_their_motion(tmp_path, monkeypatch):
    from mrlib.speech import SpeechFeatureExtractor, beat2_split, load_audio

    monkeypatch.setenv("MRLIB_BEAT2_DIR", str(SAMPLE))
    monkeypatch.setenv("MRLIB_CACHE_DIR", str(tmp_path / "cache"))
    monkeypatch.setenv("MRLIB_BEAT2_URL", "http://127.0.0.1:9/never-asked")
    split = beat2_split(SpeechFeatureExtractor(kind="logmel"), tail_s=15, progress=False)
    assert not split.synthetic and "CC BY-NC" in split.licence and "2 (scott)" in split.source
    tail, rec = split.held_out
    assert split.with_motion == [tail] and split.audio_only == [rec]
    assert rec.name == "2_scott_0_4_4" and rec.motion is None and rec.duration > 60
    head_frames = split.data.motion.lengths[0]
    assert tail.motion.num_frames == 15 * 25 and abs(tail.duration - 15) < 0.05
    whole, sr = load_audio(SAMPLE / "2_scott_0_1_1.wav")
    # the tail is the recording's audio from where the training part ends, and no earlier
    start = int(round(head_frames / 25 * sr))
    assert np.array_equal(tail.wav, whole[start : start + len(tail.wav)])
    assert 48 * 25 < head_frames < 49 * 25  # 63.5 s - 15 s
    assert abs(split.data.paired_features[0].shape[0] / 50 - head_frames / 25) < 0.05
