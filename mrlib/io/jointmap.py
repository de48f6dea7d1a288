"""Joint maps: which source joint drives each SMPL joint.

A joint map is ``{SMPL joint name: source joint name}``. Maps ship for known skeletons
(``joint_maps/*.json``); users may pass their own (a dict, a JSON file, or the name of a
shipped map), and a skeleton whose joint names are SMPL's own (what
``mrlib.io.save_motion`` writes) maps onto itself. ``validate_map`` checks a map against
a skeleton: every source joint exists, and the map keeps ancestry (a mapped SMPL
ancestor maps to a source ancestor).
"""

from __future__ import annotations

import json
import os
from collections.abc import Mapping
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path
from typing import Any

import numpy as np

from mrlib.errors import ArgumentError, JointMapError, shown
from mrlib.io.paths import read_text_bounded
from mrlib.representation.skeleton import JOINT_NAMES, NUM_JOINTS, PARENTS

__all__ = [
    "JointMap",
    "JOINT_MAP_DIR",
    "SMPL_JOINT_MAP",
    "load_joint_map",
    "joint_map_from_json",
    "check_joint_map",
    "shipped_joint_maps",
    "detect_joint_map",
    "validate_map",
    "mapped_ancestor",
    "mapped_targets",
]

JOINT_MAP_DIR = Path(__file__).parent / "joint_maps"


# Joint maps
# ----------------------------------------------------------------------------------------
@dataclass(frozen=True)
class JointMap:
    """Which source joint drives each SMPL joint.

    Attributes:
        name: short identifier (``"bandai_namco"``, ``"cmu"``, ``"smpl"``, ``"custom"``).
        mapping: SMPL joint name -> source joint name; SMPL joints left out are unmapped.
        description: free text.
        refit_torso: the map names joints of a family of skeletons whose spines differ
            (CMU's subjects): retargeting also tries SMPL's spine and neck placed by the
            skeleton's own geometry and keeps the better fit (``mrlib.io.recognize.
            refit_torso``). JSON key ``"refit_torso": true``.
    """

    name: str
    mapping: Mapping[str, str]
    description: str = ""
    refit_torso: bool = False

    def __post_init__(self) -> None:
        if not isinstance(self.name, str):
            raise JointMapError(None, f"a joint map's name must be text, got {shown(self.name)}")
        if not isinstance(self.mapping, Mapping):
            raise JointMapError(
                None,
                f"joint map '{self.name}' must be an object {{smpl_joint: source_joint}}, "
                f"got {shown(self.mapping)}",
            )
        for k, v in self.mapping.items():
            if not isinstance(k, str) or not isinstance(v, str) or not v:
                raise JointMapError(
                    None,
                    f"joint map '{self.name}': each entry maps an SMPL joint name to a source "
                    f"joint name (text), got {shown(k)}: {shown(v)}",
                )
        if not isinstance(self.description, str):
            raise JointMapError(
                None,
                f"joint map '{self.name}': 'description' must be text, got {shown(self.description)}",
            )
        if not isinstance(self.refit_torso, bool):
            raise JointMapError(
                None,
                f"joint map '{self.name}': 'refit_torso' must be true or false, got "
                f"{shown(self.refit_torso)}",
            )
        bad = [k for k in self.mapping if k not in JOINT_NAMES]
        if bad:
            raise JointMapError(
                None, f"joint map '{self.name}': {bad} are not SMPL joint names {list(JOINT_NAMES)}"
            )
        if "pelvis" not in self.mapping:
            raise JointMapError(None, f"joint map '{self.name}' must map SMPL's 'pelvis'")
        srcs = list(self.mapping.values())
        dup = sorted({s for s in srcs if srcs.count(s) > 1})
        if dup:
            raise JointMapError(
                None, f"joint map '{self.name}': source joints {dup} are used twice"
            )

    def to_json(self, path: str | Path, *, overwrite: bool = True) -> Path:
        """Write ``{"name", "description", "map"}`` (what ``joint_map_from_json`` and
        ``load_motion(..., joint_map=path)`` read), in SMPL's joint order; atomically,
        never through a symbolic link, and refusing an existing file unless
        ``overwrite`` (``mrlib.io.outputs``)."""
        from mrlib.io.outputs import write_text

        data = {
            "name": self.name,
            "description": self.description,
            **({"refit_torso": True} if self.refit_torso else {}),
            "map": {k: self.mapping[k] for k in JOINT_NAMES if k in self.mapping},
        }
        return write_text(Path(path), json.dumps(data, indent=2) + "\n", overwrite=overwrite)

    def source_indices(self, names: tuple[str, ...] | list[str]) -> np.ndarray:
        """``(24,)`` source joint index per SMPL joint, -1 where unmapped."""
        return np.array(
            [names.index(self.mapping[n]) if n in self.mapping else -1 for n in JOINT_NAMES]
        )


SMPL_JOINT_MAP = JointMap(
    "smpl", {n: n for n in JOINT_NAMES}, "SMPL's own joint names (mrlib's BVH export)"
)


def _from_data(data: Any, default_name: str, path: Path | None) -> JointMap:
    """A map from what a joint map file holds (or the same as a dict): ``{"name",
    "description", "refit_torso", "map": {smpl: source}}`` or a flat ``{smpl: source}``."""
    layout = (
        'expected {"map": {smpl_name: source_name, ...}} or a flat {smpl_name: source_name} object'
    )
    if not isinstance(data, dict):
        raise JointMapError(path, f"{layout}, got {shown(data)}")
    try:
        if "map" in data:
            if not isinstance(data["map"], dict):
                raise JointMapError(
                    path,
                    f"'map' must be an object {{smpl_name: source_name}}, got {shown(data['map'])}",
                )
            extra = sorted(set(data) - {"name", "description", "refit_torso", "map"})
            if extra:
                raise JointMapError(
                    path, f"unknown keys {extra} beside 'map' (name, description, refit_torso)"
                )
            return JointMap(
                data.get("name", default_name),
                dict(data["map"]),
                data.get("description", ""),
                data.get("refit_torso", False),
            )
        return JointMap(default_name, dict(data))
    except JointMapError as e:
        if e.path is None and path is not None:
            raise JointMapError(path, e.problem) from None
        raise


def joint_map_from_json(path: Path) -> JointMap:
    """A map from ``{"name", "description", "map": {smpl: source}}`` (and optionally
    ``"refit_torso": true``) or a flat ``{smpl: source}`` JSON object. Anything else (a
    list, numbers or nested objects for joint names, unknown SMPL joints) is a one-line
    ``JointMapError`` naming the file."""
    path = Path(path)
    try:
        data = json.loads(read_text_bounded(path, 2**20, "a joint map", JointMapError))
    except json.JSONDecodeError as e:
        raise JointMapError(path, f"cannot read joint map: not valid JSON ({e})") from None
    except RecursionError:
        raise JointMapError(path, "cannot read joint map: nested too deeply for one") from None
    except UnicodeDecodeError:
        raise JointMapError(path, "cannot read joint map: not a UTF-8 text file") from None
    return _from_data(data, path.stem, path)


def check_joint_map(name: str, value: Any) -> Any:
    """``value`` if it can name a joint map (None, a shipped map's name or a JSON path, a
    ``{smpl: source}`` dict, a :class:`JointMap`), else an ``ArgumentError``."""
    if value is None or isinstance(value, (str, os.PathLike, Mapping, JointMap)):
        return value
    raise ArgumentError(
        f"{name} must be a shipped map's name, a JSON file, a {{smpl_joint: source_joint}} "
        f"dict or a JointMap, got {shown(value)}"
    )


@lru_cache(maxsize=1)
def shipped_joint_maps() -> dict[str, JointMap]:
    """The joint maps in ``mrlib/io/joint_maps/``, by name."""
    maps = {}
    for p in sorted(JOINT_MAP_DIR.glob("*.json")):
        m = joint_map_from_json(p)
        maps[m.name] = m
    return maps


def load_joint_map(spec: str | Path | Mapping[str, str] | JointMap) -> JointMap:
    """A ``JointMap`` from a shipped map's name, a JSON file or a ``{smpl: bvh}`` dict."""
    check_joint_map("joint_map", spec)
    if isinstance(spec, JointMap):
        return spec
    if isinstance(spec, Mapping):
        return _from_data(dict(spec), "custom", None)
    if str(spec) == "smpl":
        return SMPL_JOINT_MAP
    shipped = shipped_joint_maps()
    if str(spec) in shipped:
        return shipped[str(spec)]
    if Path(spec).suffix.lower() == ".json" or Path(spec).exists():
        return joint_map_from_json(Path(spec))
    raise JointMapError(
        None,
        f"unknown joint map '{spec}'; shipped maps: {sorted(shipped)}, or a JSON file of "
        "{smpl_name: bvh_name} (a dict in Python)",
    )


def detect_joint_map(
    names: tuple[str, ...] | list[str], *, source: str | Path | None = None
) -> JointMap:
    """The map whose source joints all exist in ``names``: SMPL's own names first, then
    the shipped map covering the most SMPL joints.

    Raises:
        JointMapError: no map fits; lists the unmapped joints of the closest map.
    """
    if set(JOINT_NAMES) <= set(names):
        return SMPL_JOINT_MAP
    best = None
    for m in shipped_joint_maps().values():
        missing = [s for s in m.mapping.values() if s not in names]
        if not missing and (best is None or len(m.mapping) > len(best.mapping)):
            best = m
    if best is not None:
        return best
    closest = min(
        shipped_joint_maps().values(), key=lambda m: sum(s not in names for s in m.mapping.values())
    )
    missing = {k: v for k, v in closest.mapping.items() if v not in names}
    raise JointMapError(
        source,
        f"no joint map fits this skeleton. Closest shipped map '{closest.name}' leaves SMPL "
        f"joints {sorted(missing)} unmapped (BVH lacks {sorted(missing.values())}). BVH "
        f"joints: {list(names)}. Pass joint_map={{smpl_name: bvh_name, ...}}.",
    )


def validate_map(
    jmap: JointMap, names: tuple[str, ...], parents: tuple[int, ...], source
) -> np.ndarray:
    """Source index per SMPL joint after checking that the names exist and that the map
    preserves ancestry (a mapped SMPL ancestor maps to a source ancestor)."""
    missing = {k: v for k, v in jmap.mapping.items() if v not in names}
    if missing:
        raise JointMapError(
            source,
            f"joint map '{jmap.name}': BVH has no joints {sorted(missing.values())} (for SMPL "
            f"{sorted(missing)}); BVH joints: {list(names)}",
        )
    if len(jmap.mapping) < 2:
        raise JointMapError(
            source,
            f"joint map '{jmap.name}' maps only {sorted(jmap.mapping)}: retargeting needs at "
            "least two joints (a bone) to find the file's unit and pose; map the hips, knees, "
            "spine and arms",
        )
    src = jmap.source_indices(names)

    def ancestors(i: int) -> set[int]:
        out = set()
        while parents[i] >= 0:
            i = parents[i]
            out.add(i)
        return out

    for j in range(1, NUM_JOINTS):
        if src[j] < 0:
            continue
        a = mapped_ancestor(j, src)
        if src[a] not in ancestors(src[j]):
            raise JointMapError(
                source,
                f"joint map '{jmap.name}': SMPL {JOINT_NAMES[j]} -> {names[src[j]]} but its SMPL "
                f"ancestor {JOINT_NAMES[a]} -> {names[src[a]]}, which is not an ancestor of "
                f"{names[src[j]]} in the BVH",
            )
    return src


def mapped_ancestor(j: int, src: np.ndarray) -> int:
    """Nearest mapped SMPL ancestor of ``j`` (``src (24,)``: source index or -1)."""
    a = PARENTS[j]
    while a >= 0 and src[a] < 0:
        a = PARENTS[a]
    return a


def mapped_targets(j: int, src: np.ndarray) -> list[int]:
    """Nearest mapped SMPL descendants of ``j`` (through unmapped joints)."""
    out: list[int] = []
    stack = [k for k in range(NUM_JOINTS) if PARENTS[k] == j]
    while stack:
        k = stack.pop()
        if src[k] >= 0:
            out.append(k)
        else:
            stack += [c for c in range(NUM_JOINTS) if PARENTS[c] == k]
    return sorted(out)
