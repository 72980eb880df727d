"""The committed leaderboard is reproduced bit for bit: rows re-measured with the saved
plants, seed, states and limits give the same successes, settle ratios, torques and
Wilson intervals as renders/leaderboard/leaderboard.json (the evaluation path may get
faster, never different). Level ``medium`` exercises every part of a row: drawn plants,
noise, the actuation delay, and (compensated) the observer and delay predictor.

The mean torque is held to 1e-12 relative: the committed rows of ``lqr`` plain were
measured before controllers were handed read-only copies of their readings, and their
torque sums differ from today's in the 16th digit (the other rows equal it bit for bit)."""
import json
from pathlib import Path

import numpy as np
import pytest

from twolink.sim.cells import states_of
from twolink.studies.leaderboard.limits import state_limits
from twolink.studies.leaderboard.measure import measure_row

SAVED = Path(__file__).resolve().parents[2] / "renders" / "leaderboard" / "leaderboard.json"
#: Everything a row records but its wall time and mean torque, held bit for bit.
KEYS = ("successes", "n", "rate", "wilson_95", "median_settle", "worst_plant",
        "worst_plant_successes", "settle_ratio_median", "settle_ratio_worst")


def _same(got: dict, want: dict) -> None:
    for key in KEYS:
        assert got[key] == want[key], (key, got[key], want[key])
    assert got["mean_abs_torque"] == pytest.approx(want["mean_abs_torque"], rel=1e-12, abs=0)


def _saved() -> dict:
    return json.loads(SAVED.read_text())


def remeasured(controller: str, level: str, mode: str, saved: dict) -> tuple[dict, dict]:
    """The saved row of (controller, level, mode) and the same row measured now, as dicts."""
    x0 = states_of("full")
    assert len(x0) == saved["states"]
    limits, source = state_limits(x0)
    assert source == saved["limits"]
    want = next(r for r in saved["rows"] if (r["controller"], r["level"], r["mode"])
                == (controller, level, mode))
    got = measure_row(controller, controller, level, mode, x0, limits, saved["plants"],
                      saved["seed"]).as_dict()
    # Through JSON, as the saved file went, so that tuples and None compare alike.
    return want, json.loads(json.dumps(got))


@pytest.mark.slow
@pytest.mark.parametrize("controller,mode", [("lqr", "plain"), ("lqr", "compensated"),
                                             ("pd", "plain"), ("pd", "compensated")])
def test_medium_rows_equal_the_committed_ones_bit_for_bit(controller, mode):
    want, got = remeasured(controller, "medium", mode, _saved())
    _same(got, want)
    assert got["n"] == 32 * 65


def test_nominal_row_equals_the_committed_one_bit_for_bit():
    want, got = remeasured("lqr", "none", "plain", _saved())
    _same(got, want)
    assert got["successes"] == want["successes"] > 0
    assert np.isfinite(got["settle_ratio_median"])
