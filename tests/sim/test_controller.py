"""The controller protocol: checked controllers, per-state adapters, one-line errors."""
import numpy as np
import pytest

from twolink.sim.controller import ControllerError, checked, controller_name, per_state

X = np.array([[-1.0, -3.0, 0.0, 0.0], [0.5, 0.2, 0.1, -0.1], [0.0, 0.0, 0.0, 0.0]])


def pd(x):
    return np.clip(-np.array([2.0, 0.5]) * x[:, :2] - np.array([0.5, 0.1]) * x[:, 2:],
                   [-1.5, -0.1], [1.5, 0.1])


def test_a_batched_function_passes_through_unchanged():
    c = checked(pd)
    np.testing.assert_array_equal(c(X), pd(X))
    assert c(X).shape == (3, 2) and c.name == "pd" and c.meta == {}


def test_a_single_state_function_is_named_with_the_remedy():
    def one(x):
        t1, t2, w1, w2 = x
        return np.array([-t1, -t2])

    with pytest.raises(ControllerError, match=r"controller one raised ValueError: (too many|not enough) "
                                              r"values to unpack.*twolink.per_state"):
        checked(one)(X)
    adapted = per_state(one)
    np.testing.assert_array_equal(checked(adapted)(X), -X[:, :2])
    assert controller_name(adapted) == "one"


@pytest.mark.parametrize("bad, match", [
    (lambda x: x, r"returned torques of shape \(3, 4\) for states of shape \(3, 4\); it "
                  r"must return \(3, 2\)"),
    (lambda x: np.array([0.0, 0.0]), r"shape \(2,\).*per_state"),
    (lambda x: np.full((len(x), 2), np.nan), "returned NaN or infinite torques"),
    (lambda x: "torques", "returned str, not an array"),
])
def test_broken_outputs_end_in_one_line(bad, match):
    with pytest.raises(ControllerError, match=match) as info:
        checked(bad, name="mine")(X)
    assert "\n" not in str(info.value) and "controller mine" in str(info.value)


def test_not_callable_is_refused_at_once():
    with pytest.raises(ControllerError, match="is not callable"):
        checked(3)


def test_reset_and_meta_pass_through():
    class Stateful:
        meta = {"model": "full"}

        def __init__(self):
            self.rows = None

        def reset(self, n):
            self.rows = n

        def __call__(self, x):
            return np.zeros((len(x), 2))

    inner = Stateful()
    c = checked(inner)
    c.reset(7)
    assert inner.rows == 7 and c.meta == {"model": "full"} and c.name == "Stateful"


def test_a_rollout_resets_a_stateful_controller_through_its_wrappers():
    """reset(rows) reaches the controller inside a checked wrapper and a delay line."""
    from twolink.sim.perturbations import ActuationDelay
    from twolink.sim.plants import make_plant
    from twolink.sim.rollout import rollout

    class Integrating:
        def __init__(self):
            self.resets, self.acc = [], None

        def reset(self, n):
            self.resets.append(n)
            self.acc = np.zeros((n, 2))

        def __call__(self, x):
            self.acc = self.acc + x[:, :2]
            return np.clip(-2.0 * x[:, :2] - 0.5 * x[:, 2:] - 0.01 * self.acc, -0.1, 0.1)

    inner = Integrating()
    with make_plant("full") as plant:
        rollout(ActuationDelay(checked(inner), 1), plant, X, duration=0.2)
        rollout(checked(inner), plant, X[:2], duration=0.1)
    assert inner.resets == [3, 2]


def test_evaluate_takes_any_controller_and_names_a_broken_one():
    from twolink.sim.evaluation import evaluate

    x0 = np.array([[-1.0, -3.0, 0.0, 0.0]])
    ev = evaluate(pd, x0=x0, horizon=2.0)
    assert ev.label == "pd" and not ev.compensated and ev.success.shape == (1, 1)

    def one(x):
        t1, t2, w1, w2 = x
        return np.zeros(2)

    with pytest.raises(ControllerError, match="controller one raised ValueError.*per_state"):
        evaluate(one, challenge="medium", count=2, x0=x0)
    with pytest.raises(ValueError, match="controller pd names no model for the compensator"):
        evaluate(pd, challenge="medium", count=2, x0=x0, compensate=True)
    for bad in (3, None):
        with pytest.raises(ControllerError, match=f"controller {bad} is not callable"):
            evaluate(bad, x0=x0)
