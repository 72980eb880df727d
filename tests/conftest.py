import numpy as np
import pytest

from twolink.policy import load_policy


@pytest.fixture(scope="session")
def centralized():
    return load_policy("centralized")


@pytest.fixture(scope="session")
def decentralized():
    return load_policy("decentralized")


@pytest.fixture
def rng():
    return np.random.default_rng(1234)
