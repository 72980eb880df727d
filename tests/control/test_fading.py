"""The fading gain (twolink.control.fading): a hold region with hysteresis, per joint."""
import math

import numpy as np
import pytest

from twolink.control.fading import Fade, FadingGain, fading_policy


def _ones(x):
    return np.ones((len(x), 2))


def _state(deg1, deg2, w1=0.0, w2=0.0):
    return np.array([[math.radians(deg1), math.radians(deg2), w1, w2]])


def test_a_settled_joint_fades_to_the_floor_and_leaves_at_once():
    c = FadingGain(_ones, Fade(exit_deg=10.0, exit_speed=0.3, floor=0.4, fade_samples=3))
    c.reset(1)
    assert np.allclose(c(_state(30, 30)), [[1, 1]])                 # far: full torque
    gains = [c(_state(2, 30))[0, 0] for _ in range(5)]               # joint 1 settles
    assert np.allclose(gains, [0.8, 0.6, 0.4, 0.4, 0.4])             # -0.2 a sample
    assert np.allclose(c(_state(8, 30)), [[0.4, 1.0]])               # 8 deg: still held
    assert np.allclose(c(_state(11, 30)), [[1.0, 1.0]])              # beyond 10 deg: free
    c(_state(2, 2))
    assert np.allclose(c(_state(2, 2, w2=0.5)), [[0.6, 1.0]])        # joint 2's speed


def test_reset_releases_every_row_and_the_wrapped_policy_is_reset():
    calls = []

    class Inner:
        def __call__(self, x):
            return np.ones((len(x), 2))

        def reset(self, n):
            calls.append(n)

    c = FadingGain(Inner(), {"floor": 0.0, "fade_samples": 1})
    c.reset(2)
    assert np.allclose(c(np.vstack([_state(1, 1), _state(40, 1)])), [[0, 0], [1, 0]])
    c.reset(2)
    assert calls == [2, 2] and np.all(c.gain == 1) and not c.held.any()


@pytest.mark.parametrize("fields, message", [
    ({"exit_deg": 3.0}, "exit_deg must be a number in [5"),
    ({"floor": 1.5}, "floor must be a number in [0, 1]"),
    ({"fade_samples": 0}, "fade_samples must be a whole number from 1"),
    ({"exit_speed": float("nan")}, "exit_speed"),
])
def test_bad_settings_are_one_line(fields, message):
    with pytest.raises(ValueError, match=message.replace("[", r"\[")):
        Fade(**fields)


def test_a_bad_fade_argument_names_it():
    with pytest.raises(ValueError, match="fade: .*unexpected keyword argument 'gain'"):
        FadingGain(_ones, {"gain": 0.5})
    with pytest.raises(TypeError, match="fade must be a Fade"):
        FadingGain(_ones, 0.5)


def test_a_fading_design_is_data_over_a_table():
    c = fading_policy("decentralized_locked", {"floor": 0.5, "fade_samples": 1},
                      readout={"speed_dead_zone": 0.1, "argmax_beyond_deg": 30.0})
    assert c.meta["fade"]["floor"] == 0.5 and c.meta["table"] == "decentralized_locked"
    x = np.vstack([_state(1, 1), _state(40, -60, 1.0, 0.0)])
    c.reset(2)
    plain = c.policy(x)
    assert np.allclose(c(x), plain * np.array([[0.5, 0.5], [1.0, 1.0]]))
