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
