"""Test-session settings shared by ``tests/`` and ``notebooks/``.

``make test`` runs the suite on every core with pytest-xdist (``-n auto --dist
loadgroup``). Each test file is one group, so a model a file trains once (a module
fixture) is trained on one worker only; files that share a trained model are one group
(``SHARED_GROUPS``), and the notebooks are one group, run one after another, because each
reuses the model the one before it cached.
"""

from __future__ import annotations

from pathlib import Path

import pytest

# files whose tests share a trained model (tests/trained_models.py caches it per process)
SHARED_GROUPS = {"test_control.py": "detail_model", "test_restyle.py": "detail_model"}


def pytest_collection_modifyitems(config, items):
    for item in items:
        if item.get_closest_marker("xdist_group"):
            continue
        path = Path(str(item.fspath))
        if path.suffix == ".ipynb":
            group = "notebooks"
        else:
            group = SHARED_GROUPS.get(path.name, path.name)
        item.add_marker(pytest.mark.xdist_group(group))
