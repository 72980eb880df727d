"""twolink.arm.task.inner_excursion: how far the inner joints swing away from the goal,
on hand-made paths (wrapped angles, the outer joint ignored, overshoot counted) and bad
shapes or values as one line."""
import math

import numpy as np
import pytest

from twolink.arm.task import inner_excursion


def test_a_path_straight_home_reads_zero_and_a_swing_reads_its_size():
    home = np.linspace([1.0, -2.0, 3.0], [0.0, 0.0, 0.0], 9)        # (K+1, N)
    assert inner_excursion(home) == 0.0
    swing = home.copy()
    swing[3, 1] = -2.6                                               # joint 2 out by 0.6
    assert inner_excursion(swing) == pytest.approx(0.6)
    outer = home.copy()
    outer[3, 2] = 3.1                                                # the outer joint: ignored
    assert inner_excursion(outer) == 0.0


def test_angles_are_wrapped_and_batches_keep_their_shape():
    path = np.zeros((2, 4, 5, 3))
    path[0, 1, :, 0] = [3.0, 3.1, -3.1 + 2 * math.pi, 2.0, 0.0]    # 3.1 read as 3.1
    path[1, 2, :, 1] = [0.5, -0.9, 0.2, 0.0, 0.0]                    # overshoot past 0
    out = inner_excursion(path)
    assert out.shape == (2, 4)
    assert out[0, 1] == pytest.approx(0.1) and out[1, 2] == pytest.approx(0.4)
    assert np.count_nonzero(out) == 2


@pytest.mark.parametrize("bad, message", [
    (np.zeros(3), "angles must have shape"),
    (np.zeros((4, 1)), "with N >= 2"),
    (np.full((4, 3), np.nan), "angles must be finite"),
])
def test_bad_paths_are_one_line(bad, message):
    with pytest.raises(ValueError, match=message):
        inner_excursion(bad)
