"""Open-loop model error: (6) agrees with MuJoCo to integration accuracy, (11) does not."""
import numpy as np
import pytest

from twolink.arm import dynamics
from twolink.arm.integrate import integration_error
from twolink.arm.parameters import STATE_NAMES, TABLE_I
from twolink.studies.mismatch.model_error import PREDICTIONS, one_step_error

pytestmark = pytest.mark.robustness


@pytest.fixture(scope="module")
def err():
    return one_step_error(TABLE_I, nthread=2)


def test_every_bin_centre_and_action_is_compared(err):
    assert err.centers.shape == (7056, 4) and err.actions.shape == (9, 2)
    for name in PREDICTIONS:
        assert err.errors[name].shape == (7056, 9, 4)
        assert np.all(np.isfinite(err.errors[name]))


def test_full_model_agrees_with_mujoco_to_integration_accuracy(err):
    x = err.centers[::49, None, :].repeat(9, 1)
    tau = np.broadcast_to(err.actions[None], x.shape[:-1] + (2,))
    integ = max(integration_error(dynamics.full_acceleration, TABLE_I, x, tau,
                                  reference_substeps=100)["max"])
    s = err.summary()["full"]
    worst = max(v["max"] for v in s.values())
    assert worst < 1e-12                 # same RK4 step: round-off only
    assert worst < integ                 # and far inside the integration error itself


def test_simplified_model_is_measurably_wrong(err):
    s = err.summary()["simplified"]
    assert s["dtheta2"]["max"] > 1.0 and s["dtheta1"]["max"] > 0.5
    assert s["dtheta2"]["rms"] > 0.1


def test_agent2_assumption_matches_mujoco_when_link1_is_at_rest(err):
    e = err.errors["agent2_assumption"]
    at_rest = (err.centers[:, 2] == 0.0)[:, None] & (err.actions[:, 0] == 0.0)[None, :]
    assert np.abs(e[at_rest][:, [1, 3]]).max() < 1e-12
    assert np.abs(e[~at_rest][:, [1, 3]]).max() > 0.5
    assert set(err.summary()["agent2_assumption"]) == {"theta2", "dtheta2"}


def test_heat_maps_cover_the_link_bins(err):
    for name in PREDICTIONS:
        for link in (1, 2):
            h = err.heat(name, link)
            assert h.shape == (12, 7) and np.all(h >= 0)
    assert err.heat("full", 2).max() < 1e-12 < err.heat("simplified", 2).min()
    with pytest.raises(ValueError, match="link"):
        err.heat("full", 3)
    assert STATE_NAMES[3] == "dtheta2"
