"""Test-session settings shared by ``tests/`` and ``notebooks/``.

``make test`` runs the suite on every core with pytest-xdist (``-n auto``), scheduled by
:class:`GroupScheduling`: each test file goes whole to one worker, so a model a file
trains once (a module fixture) is trained on one worker only; files that share a trained
model go together (``SHARED_GROUPS``); the notebooks go together, run one after another,
because each reuses the model the one before it cached.
"""

from __future__ import annotations

try:
    from xdist.scheduler import LoadScopeScheduling
except ImportError:  # pytest-xdist not installed: the suite runs in one process
    LoadScopeScheduling = None

# files whose tests share a trained model (tests/trained_models.py caches it per process)
SHARED_GROUPS = {"test_control.py": "detail model", "test_restyle.py": "detail model"}


def group_of(nodeid: str) -> str:
    """The worker group of a test: its file, a shared group, or ``notebooks``."""
    path = nodeid.split("::", 1)[0]
    if path.endswith(".ipynb"):
        return "notebooks"
    return SHARED_GROUPS.get(path.rsplit("/", 1)[-1], path)


if LoadScopeScheduling is not None:

    class GroupScheduling(LoadScopeScheduling):
        """pytest-xdist's scope scheduling with :func:`group_of` as the scope."""

        def _split_scope(self, nodeid: str) -> str:
            return group_of(nodeid)

    def pytest_xdist_make_scheduler(config, log):
        return GroupScheduling(config, log)
