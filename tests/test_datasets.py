"""Fetching the Bandai Namco clips on first use (``mrlib.datasets.bandai``), for real: a local HTTP
server on 127.0.0.1 serves the dataset's files under the upstream layout, the fetcher's
base URL (``$MRLIB_DATA_URL``) points at it, and the cache is a temporary folder.

The good-fetch tests serve the offline mirror in ``../shared`` (skipped without it); the
failure tests serve bytes made here and need no dataset."""

from __future__ import annotations

import http.server
import os
import subprocess
import sys
import threading
from pathlib import Path

import pytest

from mrlib.datasets import bandai as datasets
from mrlib.datasets.bandai import DataFetchError

ROOT = Path(__file__).resolve().parents[1]
PREFIX = "/" + datasets.BANDAI_SUBDIR + "/"
MIRROR = datasets.bandai_local_dir()  # what the server serves: $MRLIB_DATA_DIR or ../shared
needs_mirror = pytest.mark.skipif(MIRROR is None, reason="no local copy of the dataset to serve")


class _Server:
    """Serves ``files`` ({relative path: bytes}) or files under ``root`` at
    ``http://127.0.0.1:<port>/<ref>/dataset/.../<relative path>``; counts requests."""

    def __init__(self, root: Path | None = None, files: dict[str, bytes] | None = None):
        self.root, self.files, self.requests = root, files or {}, []
        outer = self

        class Handler(http.server.BaseHTTPRequestHandler):
            def do_GET(self):  # noqa: N802 (http.server's name)
                outer.requests.append(self.path)
                rel = self.path.split(PREFIX, 1)[-1] if PREFIX in self.path else None
                body = None
                if rel is not None and rel in outer.files:
                    body = outer.files[rel]
                elif rel is not None and outer.root is not None and ".." not in rel:
                    p = outer.root / rel
                    body = p.read_bytes() if p.is_file() else None
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
        self.url = f"http://127.0.0.1:{self.httpd.server_address[1]}/{datasets.BANDAI_REF}"
        self.thread = threading.Thread(target=self.httpd.serve_forever, daemon=True)
        self.thread.start()

    def close(self):
        self.httpd.shutdown()
        self.httpd.server_close()


@pytest.fixture
def cache(tmp_path, monkeypatch):
    """An empty cache and no local dataset: what a fresh clone from GitHub has."""
    monkeypatch.setenv("MRLIB_CACHE_DIR", str(tmp_path / "cache"))
    monkeypatch.setenv("MRLIB_DATA_DIR", str(tmp_path / "no-such-folder"))
    return tmp_path / "cache" / "bandai-namco-motion-1"


def _fake_files():
    """Bytes for the always-fetched files and one clip, with a registry that fits them."""
    import hashlib

    files = {
        "LICENSE": b"licence text\n",
        "cfg/content_label.txt": b"walk\n",
        "cfg/style_label.txt": b"happy\n",
        "data/dataset-1_walk_happy_001.bvh": b"HIERARCHY\n",
        "data/dataset-1_walk_happy_001.json": b'{"content": 0, "style": 0}\n',
    }
    reg = {k: "sha256:" + hashlib.sha256(v).hexdigest() for k, v in files.items()}
    return files, reg


def test_registry_lists_every_clip_with_a_sha256():
    reg = datasets.bandai_registry()
    bvh = [k for k in reg if k.endswith(".bvh")]
    assert len(bvh) == 174 and all(k.replace(".bvh", ".json") in reg for k in bvh)
    assert {"LICENSE", "cfg/style_label.txt", "cfg/content_label.txt"} <= set(reg)
    assert all(v.startswith("sha256:") and len(v) == 7 + 64 for v in reg.values())


def test_pinned_to_a_commit_not_a_branch():
    assert len(datasets.BANDAI_REF) == 40 and int(datasets.BANDAI_REF, 16) >= 0
    assert datasets.BANDAI_REF in datasets.BANDAI_URL


@needs_mirror
def test_fetch_then_reuse_the_cache_without_a_request(cache, monkeypatch, capsys):
    srv = _Server(root=MIRROR)
    try:
        monkeypatch.setenv("MRLIB_DATA_URL", srv.url)
        root = datasets.fetch_bandai(["walk_happy_001"], progress=False)
        assert root == cache
        got = cache / "data" / "dataset-1_walk_happy_001.bvh"
        want = MIRROR / "data" / "dataset-1_walk_happy_001.bvh"
        assert got.read_bytes() == want.read_bytes()
        assert (cache / "LICENSE").is_file()
        assert "CC BY-NC 4.0" in capsys.readouterr().out  # the licence, on first download
        n = len(srv.requests)
        assert n == 5  # licence, two label files, the BVH and its JSON
        assert datasets.bandai_clip("walk_happy_001") == got
        datasets.fetch_bandai(["walk_happy_001"], progress=False)
        assert len(srv.requests) == n  # cached: no request
        assert "CC BY-NC" not in capsys.readouterr().out  # said once
        import mrlib

        m = mrlib.load_motion(got)
        assert m.label == "walk_happy" and m.num_frames > 100
    finally:
        srv.close()


def test_a_corrupted_file_is_refused_and_not_kept(cache, monkeypatch):
    files, reg = _fake_files()
    monkeypatch.setattr(datasets, "bandai_registry", lambda: reg)
    bad = dict(files)
    bad["data/dataset-1_walk_happy_001.bvh"] = b"HIERARCHY but not the same\n"
    srv = _Server(files=bad)
    try:
        monkeypatch.setenv("MRLIB_DATA_URL", srv.url)
        with pytest.raises(DataFetchError) as err:
            datasets.fetch_bandai(["walk_happy_001"], progress=False)
    finally:
        srv.close()
    msg = str(err.value)
    assert "\n" not in msg and "SHA-256" in msg and "dataset-1_walk_happy_001.bvh" in msg
    assert srv.url in msg
    assert not (cache / "data" / "dataset-1_walk_happy_001.bvh").exists()
    leftovers = [p for p in cache.rglob("*") if p.is_file() and "walk_happy" in p.name]
    assert leftovers == []  # no partial or temporary file either


def test_a_good_fake_fetch_then_a_corrupted_cache_file_is_fetched_again(cache, monkeypatch):
    files, reg = _fake_files()
    monkeypatch.setattr(datasets, "bandai_registry", lambda: reg)
    srv = _Server(files=files)
    try:
        monkeypatch.setenv("MRLIB_DATA_URL", srv.url)
        datasets.fetch_bandai(["walk_happy_001"], progress=False)
        p = cache / "data" / "dataset-1_walk_happy_001.bvh"
        assert p.read_bytes() == files["data/dataset-1_walk_happy_001.bvh"]
        p.write_bytes(b"HIER")  # a truncated file, as an interrupted copy leaves
        n = len(srv.requests)
        datasets.fetch_bandai(["walk_happy_001"], progress=False)
        assert len(srv.requests) == n + 1
        assert p.read_bytes() == files["data/dataset-1_walk_happy_001.bvh"]
    finally:
        srv.close()


def test_a_dead_server_is_one_line_naming_the_file_and_url(cache, monkeypatch):
    srv = _Server(files={})
    url = srv.url
    srv.close()  # nothing listens there now
    monkeypatch.setenv("MRLIB_DATA_URL", url)
    with pytest.raises(DataFetchError) as err:
        datasets.fetch_bandai(["walk_happy_001"], progress=False)
    msg = str(err.value)
    assert "\n" not in msg and url in msg and "MRLIB_DATA_URL" in msg
    assert not any(p.is_file() for p in cache.rglob("*")) if cache.exists() else True


def test_a_missing_file_on_the_server_is_one_line(cache, monkeypatch):
    srv = _Server(files={})
    try:
        monkeypatch.setenv("MRLIB_DATA_URL", srv.url)
        with pytest.raises(DataFetchError, match="HTTP 404") as err:
            datasets.fetch_bandai(["walk_happy_001"], progress=False)
        assert "\n" not in str(err.value)
    finally:
        srv.close()


@pytest.mark.skipif(os.geteuid() == 0, reason="root writes into read-only folders")
def test_a_read_only_cache_is_one_line(tmp_path, monkeypatch):
    ro = tmp_path / "ro"
    ro.mkdir()
    ro.chmod(0o500)
    monkeypatch.setenv("MRLIB_CACHE_DIR", str(ro))
    monkeypatch.setenv("MRLIB_DATA_DIR", str(tmp_path / "none"))
    with pytest.raises(DataFetchError, match="MRLIB_CACHE_DIR"):
        datasets.fetch_bandai(["walk_happy_001"], progress=False)


def test_a_read_only_cache_is_one_line_as_root_too(cache, monkeypatch):
    """As root a read-only mode does not stop writes, so the cache is a file instead."""
    cache.parent.parent.mkdir(parents=True, exist_ok=True)
    cache.parent.write_text("not a folder")
    monkeypatch.setenv("MRLIB_DATA_URL", "http://127.0.0.1:9/x")
    with pytest.raises(DataFetchError) as err:
        datasets.fetch_bandai(["walk_happy_001"], progress=False)
    assert "\n" not in str(err.value)


def test_an_unknown_clip_name_is_refused(cache):
    with pytest.raises(DataFetchError, match="not a clip"):
        datasets.fetch_bandai(["walk_flying_001"], progress=False)


def test_a_local_folder_wins_over_the_cache(tmp_path, monkeypatch):
    local = tmp_path / "bandai"
    (local / "data").mkdir(parents=True)
    (local / "data" / "dataset-1_walk_happy_001.bvh").write_text("x")
    monkeypatch.setenv("MRLIB_DATA_DIR", str(local))
    monkeypatch.setenv("MRLIB_DATA_URL", "http://127.0.0.1:9/never-asked")
    assert datasets.bandai_dir() == local
    assert datasets.bandai_clip("walk_happy_001") == local / "data" / "dataset-1_walk_happy_001.bvh"


def test_no_network_falls_back_to_the_samples_and_says_so(cache, monkeypatch, capsys):
    monkeypatch.setenv("MRLIB_DATA_URL", "http://127.0.0.1:9/nothing-listens")
    src = datasets.tutorial_clips(["walk_normal_001", "walk_happy_001", "walk_angry_001"])
    out = capsys.readouterr().out.strip().splitlines()
    assert src.synthetic and src.data_dir is None and len(out) == 1 and "synthetic" in out[0]
    assert [p.stem for p in src.paths] == ["walk_normal", "walk_happy", "walk_sad"]
    assert all(p.is_file() for p in src.paths)


@needs_mirror
def test_the_cli_fetches_ahead_of_time(cache, monkeypatch):
    srv = _Server(root=MIRROR)
    try:
        env = dict(os.environ, MRLIB_DATA_URL=srv.url)
        r = subprocess.run(
            [sys.executable, "-m", "mrlib", "data", "fetch", "bandai"],
            env=env, capture_output=True, text=True, timeout=300,
        )  # fmt: skip
        assert r.returncode == 0, r.stderr
        for c in datasets.NOTEBOOK_CLIPS:
            assert (cache / "data" / f"dataset-1_{c}.bvh").is_file()
        assert "CC BY-NC 4.0" in r.stdout
    finally:
        srv.close()


def test_the_cli_reports_a_dead_server_in_one_line(cache):
    env = dict(os.environ, MRLIB_DATA_URL="http://127.0.0.1:9/x")
    r = subprocess.run(
        [sys.executable, "-m", "mrlib", "data", "fetch", "bandai"],
        env=env, capture_output=True, text=True, timeout=120,
    )  # fmt: skip
    assert r.returncode != 0
    errors = [ln for ln in r.stderr.splitlines() if "error" in ln.lower()]
    assert len(errors) == 1 and errors[0].startswith("error: ") and "Traceback" not in r.stderr
    assert "127.0.0.1:9/x/" in errors[0]


@needs_mirror
def test_a_failed_fetch_beside_a_local_copy_says_the_copy_is_read(cache):
    # the error's advice (set $MRLIB_DATA_DIR to a copy) is already followed: say so
    env = dict(os.environ, MRLIB_DATA_URL="http://127.0.0.1:9/x", MRLIB_DATA_DIR=str(MIRROR))
    r = subprocess.run(
        [sys.executable, "-m", "mrlib", "data", "fetch", "bandai"],
        env=env, capture_output=True, text=True, timeout=120,
    )  # fmt: skip
    assert r.returncode != 0 and "Traceback" not in r.stderr
    assert f"meanwhile mrlib reads the local copy at {MIRROR}" in r.stderr


def _run_notebook(path: Path, env: dict) -> dict:
    """Execute a notebook in a fresh kernel with ``env`` and return it."""
    import nbformat
    from nbclient import NotebookClient

    nb = nbformat.read(path, as_version=4)
    old = dict(os.environ)
    os.environ.update(env)
    try:
        NotebookClient(
            nb,
            timeout=600,
            kernel_name="python3",
            resources={"metadata": {"path": str(path.parent)}},
        ).execute()
    finally:
        os.environ.clear()
        os.environ.update(old)
    return nb


def _text(nb: dict) -> str:
    return "".join(
        o.get("text", "") for c in nb["cells"] if c["cell_type"] == "code" for o in c["outputs"]
    )


@needs_mirror
def test_notebook_01_runs_on_clips_fetched_from_a_server(tmp_path):
    """A fresh clone with the network: no local copy, an empty cache, the dataset served
    on 127.0.0.1; the notebook fetches its clip and runs top to bottom."""
    srv = _Server(root=MIRROR)
    try:
        env = {
            "MRLIB_DATA_DIR": str(tmp_path / "none"),
            "MRLIB_CACHE_DIR": str(tmp_path / "cache"),
            "MRLIB_DATA_URL": srv.url,
        }
        nb = _run_notebook(ROOT / "notebooks" / "01_representation_and_contacts.ipynb", env)
    finally:
        srv.close()
    assert any("walk_happy_001.bvh" in r for r in srv.requests)
    assert (tmp_path / "cache" / "bandai-namco-motion-1" / "data").is_dir()
    assert "synthetic" not in _text(nb)


def test_notebook_01_runs_with_no_network_on_the_samples(tmp_path):
    """A fresh clone with no network and no data: one line says so, the samples stand in."""
    env = {
        "MRLIB_DATA_DIR": str(tmp_path / "none"),
        "MRLIB_CACHE_DIR": str(tmp_path / "cache"),
        "MRLIB_DATA_URL": "http://127.0.0.1:9/nothing-listens",
    }
    nb = _run_notebook(ROOT / "notebooks" / "01_representation_and_contacts.ipynb", env)
    lines = [ln for ln in _text(nb).splitlines() if "data_samples" in ln]
    assert len(lines) == 1 and "synthetic" in lines[0] and "127.0.0.1:9" in lines[0]
