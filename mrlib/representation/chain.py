"""Forward kinematics of a joint tree, one tree depth at a time.

``rigid_transforms`` gives what ``smplx.lbs.batch_rigid_transform`` gives (posed joints
and the skinning transforms of linear blend skinning), as 3x3 rotations and translations
rather than 4x4 matrices, and composes every joint of one depth of the tree in one
batched product (SMPL's 24 joints sit at 9 depths) instead of one joint after another.
The training losses pose a few thousand frames per step; there this is several times
faster, forward and backward (``tests/test_body.py`` checks it against smplx's).
"""

from __future__ import annotations

import functools

import torch

__all__ = ["rigid_transforms"]


@functools.lru_cache(maxsize=8)
def _depth_plan(parents: tuple[int, ...], device: torch.device) -> tuple:
    """Index tensors on ``device``, built once per tree: every joint's parent; per depth
    ``d >= 1``, its joints and their parents' positions in depth ``d - 1``'s joint list;
    the order that puts the concatenated depths back in joint order."""
    depth = [0] * len(parents)
    for j, p in enumerate(parents):
        if j == 0:
            continue
        if not 0 <= p < j:
            raise ValueError(f"parents must list every parent before its child, got {parents}")
        depth[j] = depth[p] + 1
    levels = [[j for j in range(len(parents)) if depth[j] == d] for d in range(max(depth) + 1)]
    where = {j: i for lv in levels for i, j in enumerate(lv)}
    joints = [torch.tensor(lv, device=device) for lv in levels[1:]]
    parent_pos = [torch.tensor([where[parents[j]] for j in lv], device=device) for lv in levels[1:]]
    flat = [j for lv in levels for j in lv]
    order = torch.tensor([flat.index(j) for j in range(len(parents))], device=device)
    return torch.tensor(parents[1:], device=device), joints, parent_pos, order


def _matmul3(a: torch.Tensor, b: torch.Tensor) -> torch.Tensor:
    """``a @ b`` for stacks of 3x3 matrices ``(k, 3, 3, N)`` (or ``b (k, 3, N)``, vectors),
    the batch last: three products and sums of contiguous rows vectorise where a batched
    3x3 product would not."""
    if b.ndim == a.ndim - 1:  # vectors
        return a[:, :, 0] * b[:, None, 0] + a[:, :, 1] * b[:, None, 1] + a[:, :, 2] * b[:, None, 2]
    return (
        a[:, :, 0, None] * b[:, None, 0]
        + a[:, :, 1, None] * b[:, None, 1]
        + a[:, :, 2, None] * b[:, None, 2]
    )


def rigid_transforms(
    rotmat: torch.Tensor, rest: torch.Tensor, parents: tuple[int, ...]
) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """Posed joints and skinning transforms of a tree.

    Args:
        rotmat: ``(N, J, 3, 3)`` local rotations, ``rotmat[:, 0]`` the root's.
        rest: ``(N, J, 3)`` or ``(1, J, 3)`` rest-pose joint positions.
        parents: ``J`` parent indices, ``parents[0]`` the root's (ignored), every
            parent listed before its children.
    Returns:
        ``joints (N, J, 3)``; the skinning transforms ``x -> R_j x + t_j`` of each joint
        (a rest-pose point moved as joint ``j`` moves it): ``R (N, J, 3, 3)`` (the global
        rotations) and ``t (N, J, 3)``.
    """
    par, joints_at, parent_pos, order = _depth_plan(tuple(map(int, parents)), rotmat.device)
    N = rotmat.shape[0]
    rest_n = rest.permute(1, 2, 0)  # (J, 3, N|1): the batch last from here on
    rot = rotmat.permute(1, 2, 3, 0)  # (J, 3, 3, N)
    offsets = torch.cat([rest_n[:1], rest_n[1:] - rest_n[par]], 0)  # (J, 3, N|1)
    rots, poss = [rot[:1]], [offsets[:1].expand(1, 3, N)]
    for idx, pp in zip(joints_at, parent_pos, strict=True):
        g_par, p_par = rots[-1][pp], poss[-1][pp]  # the parents, one depth up
        rots.append(_matmul3(g_par, rot[idx]))
        poss.append(p_par + _matmul3(g_par, offsets[idx]))
    R = torch.cat(rots, 0)[order]  # (J, 3, 3, N)
    joints = torch.cat(poss, 0)[order]  # (J, 3, N)
    t = joints - _matmul3(R, rest_n)
    return joints.permute(2, 0, 1), R.permute(3, 0, 1, 2), t.permute(2, 0, 1)
