"""Package the Blender add-on: ``blender/mrlib_addon/`` -> ``dist/mrlib_addon.zip``.

Install the zip in Blender with Edit > Preferences > Add-ons > Install (Blender 4.2+:
the add-ons' drop-down menu > Install from Disk). The zip holds the one folder
``mrlib_addon/`` (Python files only, no caches), with fixed timestamps, so the same sources
give the same bytes. ``make blender-addon`` runs this; docs/blender.md explains the rest.

    python tools/make_blender_addon.py [--out dist/mrlib_addon.zip]
"""

from __future__ import annotations

import argparse
import sys
import zipfile
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
SOURCE = ROOT / "blender" / "mrlib_addon"
DEFAULT_OUT = ROOT / "dist" / "mrlib_addon.zip"
_EPOCH = (2024, 1, 1, 0, 0, 0)


def addon_files(source: Path = SOURCE) -> list[Path]:
    """The add-on's files to ship: every ``.py`` (and ``.json``/``.md``) under ``source``,
    caches left out, sorted."""
    keep = {".py", ".json", ".md", ".toml"}
    return sorted(
        p
        for p in source.rglob("*")
        if p.is_file() and p.suffix in keep and "__pycache__" not in p.parts
    )


def make_zip(out: Path = DEFAULT_OUT, source: Path = SOURCE) -> Path:
    """Write the add-on zip to ``out`` (atomically); returns ``out``."""
    files = addon_files(source)
    if not (source / "__init__.py").is_file():
        raise SystemExit(f"error: {source}: no __init__.py")
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = out.with_name(out.name + ".part")
    with zipfile.ZipFile(tmp, "w", zipfile.ZIP_DEFLATED) as z:
        for path in files:
            info = zipfile.ZipInfo(f"{source.name}/{path.relative_to(source).as_posix()}", _EPOCH)
            info.compress_type = zipfile.ZIP_DEFLATED
            info.external_attr = 0o644 << 16
            z.writestr(info, path.read_bytes())
    tmp.replace(out)
    return out


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--out", type=Path, default=DEFAULT_OUT, help="the zip to write")
    args = parser.parse_args(argv)
    out = make_zip(args.out)
    print(f"wrote {out} ({len(addon_files())} files, {out.stat().st_size} bytes)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
