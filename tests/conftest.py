"""Shared fixtures. The test folders mirror the package's layers; the reference
implementations (``reference_*.py``) stay here, importable from every folder."""
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

import numpy as np
import pytest

from twolink.policy.fuzzy_policy import load_policy


@pytest.fixture(scope="session")
def centralized():
    return load_policy("centralized")


@pytest.fixture(scope="session")
def decentralized():
    return load_policy("decentralized")


@pytest.fixture
def rng():
    return np.random.default_rng(1234)


def load_study(name: str, monkeypatch):
    """The development study ``docs/studies/<name>.py`` as a module (registered under
    ``name`` for the test's duration, so its dataclasses and pickles resolve)."""
    import importlib.util

    path = Path(__file__).resolve().parents[1] / "docs" / "studies" / f"{name}.py"
    spec = importlib.util.spec_from_file_location(name, path)
    module = importlib.util.module_from_spec(spec)
    monkeypatch.setitem(sys.modules, name, module)
    spec.loader.exec_module(module)
    return module
