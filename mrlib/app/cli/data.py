"""``mrlib data``: fetch or locate the public data the notebooks and speech training use."""

from __future__ import annotations

import argparse

from mrlib.app.cli.common import add_command, progress_option
from mrlib.errors import MrlibError


def add_data(sub) -> argparse.ArgumentParser:
    p = add_command(
        sub,
        "data",
        "fetch or locate the public data the notebooks and speech training use",
        "bandai: the Bandai Namco Research Motion Dataset 1 (CC BY-NC 4.0), read "
        "from $MRLIB_DATA_DIR or ../shared when such a folder exists.\nbeat2: five files of the "
        "BEAT2 co-speech dataset (CC BY-NC 4.0; speaker 2: one clip with motion and audio, "
        "three with audio), read from $MRLIB_BEAT2_DIR or ../shared/data/beat2-sample; only "
        "the files of mrlib's registry can be fetched (no choice of speakers or minutes), and "
        "BEAT2's download address ($MRLIB_BEAT2_URL replaces it) is not verified.\nOtherwise "
        "fetched on first use into mrlib's cache ($MRLIB_CACHE_DIR, default ~/.cache/mrlib) "
        "and checked against SHA-256 hashes. 'fetch' downloads ahead of time; 'where' says "
        "which folder is used; 'list' names what can be fetched.",
        [
            "mrlib data fetch bandai          # the clips the notebooks use",
            "mrlib data fetch bandai --all    # all 174 clips (40 MB)",
            "mrlib data where bandai",
            "mrlib data fetch beat2           # the 5 BEAT2 files mrlib knows (13 MB)",
            "mrlib data list beat2",
        ],
    )
    p.add_argument("action", choices=["fetch", "where", "list"])
    p.add_argument("dataset", choices=["bandai", "beat2"])
    p.add_argument(
        "--all", action="store_true", help="fetch: every clip, not only the notebooks' (bandai)"
    )
    p.add_argument(
        "--clips", nargs="+", default=None, metavar="CLIP",
        help="fetch: these clips only (beat2: stems such as 2_scott_0_1_1; only the registry's "
        "files can be fetched, see 'list')",
    )  # fmt: skip
    progress_option(p)
    return p


def _cache_dir(cache):
    """The dataset's cache folder, refused (one line) where no folder can be: a file in
    its place, or a file above it (``$MRLIB_CACHE_DIR`` set to a file)."""
    from mrlib.io.paths import CACHE_ENV, folder_problem

    problem = folder_problem(cache)
    if problem is not None:
        raise MrlibError(f"mrlib's cache folder {cache}: {problem}; set ${CACHE_ENV} to a folder")
    return cache


def _act(args, names, local_dir, cache_dir, fetch) -> int:
    """``list`` / ``where`` / ``fetch`` of one dataset: ``names()`` its clips' lines,
    ``local_dir()`` a local copy or None, ``cache_dir()`` its cache, ``fetch()`` the
    download, returning the line that reports it."""
    if args.action == "list":
        for line in names():
            print(line)
        return 0
    if args.action == "where":
        local = local_dir()
        print(local if local is not None else f"{_cache_dir(cache_dir())} (cache)")
        return 0
    _cache_dir(cache_dir())  # refused before any download
    local = local_dir()
    if local is not None:
        print(f"note: a local copy at {local} is read first; fetching into the cache anyway")
    from mrlib.io.transaction import outside_transactions

    # the cache is no output of this command: each file is kept once it arrives and its
    # hash is checked (the downloader reads it back), not held for the command's end
    try:
        with outside_transactions():
            print(fetch())
    except MrlibError as e:
        if local is None:
            raise
        raise MrlibError(f"{e} (meanwhile mrlib reads the local copy at {local})") from None
    return 0


def cmd_data(args) -> int:
    progress = not args.no_progress
    if args.dataset == "beat2":
        from mrlib.datasets import beat2

        def fetch_beat2() -> str:
            root = beat2.fetch_beat2(args.clips, progress=progress)
            return f"{sum((root / f).is_file() for f in beat2.beat2_registry())} files in {root}"

        listing = lambda: [  # noqa: E731
            f"{stem}  {'motion + audio' if len(files) > 1 else 'audio'}"
            for stem, files in beat2.beat2_clips().items()
        ]
        return _act(args, listing, beat2.beat2_local_dir, beat2.beat2_cache_dir, fetch_beat2)
    from mrlib.datasets import bandai

    def fetch_bandai() -> str:
        clips = args.clips or bandai.NOTEBOOK_CLIPS
        root = bandai.fetch_bandai(clips, everything=args.all, progress=progress)
        return f"{len(list((root / 'data').glob('*.bvh')))} clips in {root}"

    listing = (
        lambda: [  # noqa: E731
            name[len("data/dataset-1_") : -len(".bvh")]
            for name in bandai.bandai_registry()
            if name.endswith(".bvh")
        ]
    )
    return _act(args, listing, bandai.bandai_local_dir, bandai.bandai_cache_dir, fetch_bandai)
