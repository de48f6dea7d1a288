"""pytest configuration for running the notebooks under nbmake.

nbmake executes each notebook with nbclient, whose kernel client waits for replies with
``await socket.poll(timeout)`` on pyzmq's asyncio sockets. Those sockets are driven by
an edge-triggered file descriptor, and now and then a wake-up is lost: the reply has
arrived, but the poll only notices it when its timeout expires and it checks the socket
once more (pyzmq issue 1558 describes the same symptom). With nbmake's per-cell timeout
that turned a 2-second cell of notebook 03 into a 600-900 s stall in about one run in
ten; the cell then passed, because the late check finds the reply.

The patch below polls in slices of at most ``POLL_SLICE_S`` seconds until the caller's
deadline, so a lost wake-up costs at most one slice. Replies, timeouts and errors are
otherwise unchanged: ``Empty`` is still raised when the whole timeout passes with
nothing to read.
"""

from __future__ import annotations

import time
from queue import Empty

from jupyter_client.channels import AsyncZMQSocketChannel

POLL_SLICE_S = 1.0


async def _get_msg_in_slices(self, timeout: float | None = None) -> dict:
    assert self.socket is not None
    deadline = None if timeout is None else time.monotonic() + float(timeout)
    while True:
        left = None if deadline is None else max(0.0, deadline - time.monotonic())
        step = POLL_SLICE_S if left is None else min(POLL_SLICE_S, left)
        if await self.socket.poll(int(step * 1000)):
            return await self._recv()
        if left is not None and left <= step:
            raise Empty


AsyncZMQSocketChannel.get_msg = _get_msg_in_slices
