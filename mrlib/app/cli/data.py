"""``mrlib data``: fetch or locate the public motion data the notebooks use."""

from __future__ import annotations

import argparse

from mrlib.app.cli.common import progress_option


def add_data(sub) -> argparse.ArgumentParser:
    p = sub.add_parser(
        "data",
        help="fetch or locate the public motion data the notebooks use",
        description="The Bandai Namco Research Motion Dataset 1 (CC BY-NC 4.0) is read from "
        "$MRLIB_DATA_DIR or ../shared when such a folder exists, else fetched on first use "
        "into mrlib's cache ($MRLIB_CACHE_DIR, default ~/.cache/mrlib) and checked against "
        "SHA-256 hashes. 'fetch' downloads ahead of time; 'where' says which folder is used.",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog="examples:\n  mrlib data fetch bandai          # the clips the notebooks use\n"
        "  mrlib data fetch bandai --all    # all 174 clips (40 MB)\n  mrlib data where bandai",
    )
    p.add_argument("action", choices=["fetch", "where", "list"])
    p.add_argument("dataset", choices=["bandai"])
    p.add_argument("--all", action="store_true", help="fetch: every clip, not only the notebooks'")
    p.add_argument(
        "--clips", nargs="+", default=None, metavar="CLIP", help="fetch: these clips only"
    )
    progress_option(p)
    return p


def _cache_dir(datasets):
    """The dataset's cache folder, refused (one line) where no folder can be: a file in
    its place, or a file above it (``$MRLIB_CACHE_DIR`` set to a file)."""
    from mrlib.errors import MrlibError
    from mrlib.io.paths import CACHE_ENV, folder_problem

    cache = datasets.bandai_cache_dir()
    problem = folder_problem(cache)
    if problem is not None:
        raise MrlibError(f"mrlib's cache folder {cache}: {problem}; set ${CACHE_ENV} to a folder")
    return cache


def cmd_data(args) -> int:
    from mrlib.datasets import bandai as datasets

    if args.action == "list":
        for name in datasets.bandai_registry():
            if name.endswith(".bvh"):
                print(name[len("data/dataset-1_") : -len(".bvh")])
        return 0
    if args.action == "where":
        local = datasets.bandai_local_dir()
        print(local if local is not None else f"{_cache_dir(datasets)} (cache)")
        return 0
    _cache_dir(datasets)  # refused before any download
    local = datasets.bandai_local_dir()
    if local is not None:
        print(f"note: a local copy at {local} is read first; fetching into the cache anyway")
    from mrlib.io.transaction import outside_transactions

    # the cache is no output of this command: each file is kept once it arrives and its
    # hash is checked (the downloader reads it back), not held for the command's end
    with outside_transactions():
        root = datasets.fetch_bandai(
            args.clips or datasets.NOTEBOOK_CLIPS, everything=args.all,
            progress=not args.no_progress,
        )  # fmt: skip
    n = len(list((root / "data").glob("*.bvh")))
    print(f"{n} clips in {root}")
    return 0
