"""A checked controller cannot cheat or take the process down: it gets read-only copies
of the states, must return real torques, and sys.exit, a KeyboardInterrupt of its own, a
call past its time limit and its prints are kept inside one ControllerError line (or on
stderr)."""
import sys
import time

import numpy as np
import pytest

from twolink.sim.controller import ControllerError, check_timeout, checked, per_state
from twolink.sim.evaluation import evaluate

X = np.array([[-1.0, -3.0, 0.0, 0.0], [0.5, 0.2, 0.1, -0.1]])


def zero_the_state(x):
    x[...] = 0.0
    return np.zeros((len(x), 2))


def test_the_states_are_a_read_only_copy_and_a_write_is_one_line():
    x = X.copy()
    with pytest.raises(ControllerError, match=r"^controller zero_the_state raised ValueError: "
                       r"assignment destination is read-only \(the states a controller gets "
                       r"are read-only: copy them to change them\)$"):
        checked(zero_the_state)(x)
    np.testing.assert_array_equal(x, X)
    seen = []
    checked(lambda s: seen.append(s) or np.zeros((len(s), 2)))(x)
    assert seen[0] is not x and not seen[0].flags.writeable
    np.testing.assert_array_equal(seen[0], X)


def test_the_torques_are_a_new_array_the_controller_keeps_no_handle_to():
    kept = np.zeros((2, 2))
    u = checked(lambda s: kept)(X)
    kept[:] = 5.0
    assert u is not kept and np.all(u == 0.0) and u.dtype == np.float64


def test_a_state_zeroing_controller_no_longer_scores():
    with pytest.raises(ControllerError, match="controller zero_the_state raised ValueError: "
                                              "assignment destination is read-only"):
        evaluate(zero_the_state, x0=X, horizon=1.0)


@pytest.mark.parametrize("bad, what", [
    (lambda x: np.full((len(x), 2), "0.1"), "ndarray of dtype <U3"),
    (lambda x: np.zeros((len(x), 2)) + 0.1j, "ndarray of dtype complex128"),
    (lambda x: np.zeros((len(x), 2), dtype=bool), "ndarray of dtype bool"),
    (lambda x: np.zeros((len(x), 2), dtype=object), "ndarray of dtype object"),
    (lambda x: [["0.1", "0.2"]] * len(x), "list of dtype <U3"),
    (lambda x: "torques", "str"),
    (lambda x: [[0.0], [0.0, 1.0]], "list"),
])
def test_torques_that_are_not_real_numbers_are_refused(bad, what):
    with pytest.raises(ControllerError) as info:
        checked(bad, name="bad")(X)
    assert str(info.value) == (f"controller bad returned {what}, not an array of real "
                               f"torques of shape (2, 2)")


def test_integer_torques_are_taken_as_floats():
    u = checked(lambda x: np.ones((len(x), 2), dtype=np.int32))(X)
    assert u.dtype == np.float64 and np.all(u == 1.0)


def test_sys_exit_and_a_keyboard_interrupt_of_its_own_are_controller_errors():
    def leave(x):
        sys.exit(0)

    def stop(x):
        raise KeyboardInterrupt

    with pytest.raises(ControllerError, match=r"^controller leave called sys.exit\(0\); a "
                                              r"controller must return torques"):
        checked(leave)(X)
    with pytest.raises(ControllerError, match=r"^controller stop raised KeyboardInterrupt "
                                              r"\(no Ctrl-C was pressed\)$"):
        checked(stop)(X)

    class Stateful:
        def reset(self, n):
            sys.exit(3)

        def __call__(self, x):
            return np.zeros((len(x), 2))

    with pytest.raises(ControllerError, match=r"^controller Stateful called sys.exit\(3\) "
                                              r"in reset\(4\)"):
        checked(Stateful()).reset(4)


def test_a_multi_line_message_is_one_line():
    def boom(x):
        raise RuntimeError("first\nsecond")

    with pytest.raises(ControllerError) as info:
        checked(boom)(X[:1])
    assert str(info.value) == "controller boom raised RuntimeError: first second"


def test_prints_go_to_stderr(capsys):
    def chatty(x):
        print("hello from the controller")
        return np.zeros((len(x), 2))

    checked(chatty)(X)
    out, err = capsys.readouterr()
    assert out == "" and err == "hello from the controller\n"


def test_a_call_past_its_limit_ends_in_one_line():
    def spin(x):
        while True:
            pass

    t0 = time.monotonic()
    with pytest.raises(ControllerError) as info:
        checked(spin, timeout=0.2)(X)
    assert str(info.value) == "controller spin took longer than 0.2 s on one call"
    assert time.monotonic() - t0 < 5


def test_a_limit_outlives_an_except_exception_and_catches_a_swallowed_alarm():
    def stubborn(x):
        deadline = time.monotonic() + 0.6
        while time.monotonic() < deadline:
            try:
                time.sleep(0.01)
            except BaseException:
                pass                      # swallows the alarm, returns late
        return np.zeros((len(x), 2))

    with pytest.raises(ControllerError, match="took longer than 0.1 s on one call"):
        checked(stubborn, timeout=0.1)(X)


def test_the_timer_and_handlers_are_restored_after_each_call():
    import signal

    before = signal.getsignal(signal.SIGALRM), signal.getsignal(signal.SIGINT)
    c = checked(lambda x: np.zeros((len(x), 2)), timeout=0.05)
    for _ in range(50):
        np.testing.assert_array_equal(c(X), np.zeros((2, 2)))
    assert signal.getitimer(signal.ITIMER_REAL) == (0.0, 0.0)
    assert (signal.getsignal(signal.SIGALRM), signal.getsignal(signal.SIGINT)) == before
    time.sleep(0.1)                       # no stray alarm goes off


def test_wrapping_keeps_the_limit_and_per_state_rows_are_read_only():
    inner = checked(lambda x: np.zeros((len(x), 2)), timeout=2.0)
    assert checked(inner, name="outer").timeout == 2.0
    assert checked(inner, timeout=1.0).timeout == 1.0

    def one(s):
        s[0] = 0.0
        return np.zeros(2)

    with pytest.raises(ControllerError, match="read-only"):
        checked(per_state(one))(X)


@pytest.mark.parametrize("bad", [0, -1.0, float("nan"), float("inf"), 1e9, True, "1", 1e-6])
def test_bad_limits_are_one_line(bad):
    with pytest.raises(ValueError, match=r"^timeout must be a number of seconds from 0.001 "
                                         r"to 3600, got "):
        check_timeout(bad)
    with pytest.raises(ValueError, match="timeout must be a number of seconds"):
        checked(lambda x: x, timeout=bad)


def test_a_rollout_hands_even_an_unchecked_policy_a_read_only_copy():
    from twolink.sim.plants import make_plant
    from twolink.sim.rollout import rollout

    seen = []

    def spy(x):
        seen.append(x)
        return np.zeros((len(x), 2))

    x0 = X.copy()
    tr = rollout(spy, make_plant("simplified"), x0, duration=0.2)
    assert all(not s.flags.writeable for s in seen) and len(seen) == tr.steps
    assert all(s is not x0 for s in seen)
    with pytest.raises(ValueError, match="read-only"):
        rollout(zero_the_state, make_plant("simplified"), x0, duration=0.2)
    np.testing.assert_array_equal(x0, X)
