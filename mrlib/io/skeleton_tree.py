"""The view of a source skeleton's tree that skeleton recognition (``mrlib.io.recognize``)
and torso placement (``mrlib.io.torso``) share: ``SkeletonTree`` - bone lengths from the
rest offsets, chains that pass over end markers and dangling helper joints (step 1 of
recognition), long branches, forks and paths.
"""

from __future__ import annotations

import numpy as np

from mrlib.io.name_rules import is_end_marker, is_helper_core, name_parts

__all__ = ["SkeletonTree"]


class SkeletonTree:
    """One view of a source skeleton's tree for recognition: children, bone lengths (from
    the rest offsets), the parts of every name (``name_parts``), the helper joints, the
    joints passed over when following chains (end markers, and helpers with no body
    joint below), each joint's longest chain down to a leaf and its depth.

    Lengths are in the file's unit; a *long* branch is one reaching at least ``length``.
    """

    def __init__(self, names, parents, offsets):
        self.names = list(names)
        self.parents = list(parents)
        self.n = len(self.names)
        self.children = [[] for _ in range(self.n)]
        for j, p in enumerate(self.parents):
            if p >= 0:
                self.children[p].append(j)
        self.bone = np.linalg.norm(np.asarray(offsets, np.float64), axis=-1)  # to the parent
        self.parts = [name_parts(n) for n in self.names]
        self.helper = [is_helper_core(core) for _, core in self.parts]
        end = [not self.children[j] and is_end_marker(self.parts[j][1]) for j in range(self.n)]
        # a body joint below: a joint that is neither a helper nor an end marker
        body_below = [False] * self.n
        for j in reversed(range(self.n)):  # parents precede children in a BVH
            body_below[j] = any(
                body_below[c] or not (self.helper[c] or end[c]) for c in self.children[j]
            )
        # end markers, and helper joints with no body joint below them, are passed over
        # when following chains; a helper on the way to a body joint is part of its bone
        self.skip = [end[j] or (self.helper[j] and not body_below[j]) for j in range(self.n)]
        # longest chain (bone length) from each joint down to a leaf
        self.down = np.zeros(self.n)
        for j in reversed(range(self.n)):  # parents precede children in a BVH
            kids = [c for c in self.children[j] if not self.skip[c]]
            self.down[j] = max((self.bone[c] + self.down[c] for c in kids), default=0.0)
        self.depth = np.zeros(self.n, int)
        for j in range(self.n):
            if self.parents[j] >= 0:
                self.depth[j] = self.depth[self.parents[j]] + 1

    def reach(self, parent: int, child: int) -> float:
        return self.bone[child] + self.down[child]

    def long_children(self, j: int, length: float) -> list[int]:
        return [c for c in self.children[j] if not self.skip[c] and self.reach(j, c) >= length]

    def chain(self, start: int) -> list[int]:
        """``start`` and its descendants along the longest path (end markers dropped)."""
        out = [start]
        while True:
            kids = [c for c in self.children[out[-1]] if not self.skip[c]]
            if not kids:
                return out
            out.append(max(kids, key=lambda c: self.bone[c] + self.down[c]))

    def path(self, a: int, b: int) -> list[int]:
        """Joints from ancestor ``a`` down to ``b``, both included."""
        out = [b]
        while out[-1] != a:
            if self.parents[out[-1]] < 0:
                raise ValueError("not an ancestor")
            out.append(self.parents[out[-1]])
        return out[::-1]

    def long_forks(self, j: int, length: float) -> int:
        """Number of joints in the subtree of ``j`` (itself included) with two or more
        long branches (the chest with the arms; a leg has none)."""
        total, stack = 0, [j]
        while stack:
            k = stack.pop()
            total += len(self.long_children(k, length)) >= 2
            stack += [c for c in self.children[k] if not self.skip[c]]
        return total

    def first_fork(self, start: int, length: float) -> tuple[int | None, float]:
        """Down from ``start`` along single long branches: the first joint with two or
        more long branches and the bone length on the way there (None if none)."""
        j, way = start, 0.0
        while True:
            kids = self.long_children(j, length)
            if len(kids) >= 2:
                return j, way
            if not kids:
                return None, way
            j = kids[0]
            way += self.bone[j]

    def branches(self, j: int) -> int:
        """Number of long branches in the subtree of ``j``."""
        total, stack = 0, [j]
        while stack:
            k = stack.pop()
            kids = [c for c in self.children[k] if not self.skip[c]]
            if len(kids) >= 2:
                total += len(kids) - 1
            stack += kids
        return total

    def alike(self, a: int, b: int, parent: int) -> float:
        """How alike two branches are: 0 for the same length, growing with the ratio."""
        la, lb = self.reach(parent, a), self.reach(parent, b)
        return abs(np.log(max(la, 1e-9) / max(lb, 1e-9)))

    def pick_pair(self, kids: list[int], parent: int) -> tuple[int, int]:
        """The two of ``kids`` (children of ``parent``) whose branches are most alike."""
        pairs = [(a, b) for i, a in enumerate(kids) for b in kids[i + 1 :]]
        return min(pairs, key=lambda p: self.alike(p[0], p[1], parent))
