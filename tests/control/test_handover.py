"""The handover (twolink.control.handover): the approach design acts until the arm is in
the enter region, the hold design until it leaves the exit region; the timed handover
switches on the rollout's clock; its parts must drive one arm on one model; the shipped
entries are catalogue controllers."""
from __future__ import annotations

import importlib.util
import math
from pathlib import Path

import numpy as np
import pytest

from twolink.control.handover import (
    HANDOVERS,
    Handover,
    Regions,
    TimedHandover,
    handover_policy,
)
from twolink.sim.controller import ControllerError


class Const:
    def __init__(self, value, meta=None, links=2, kind="centralized"):
        self.value, self.meta, self.links, self.resets = value, meta or {}, links, 0
        self.name, self.kind = f"const{value}", kind

    def reset(self, n):
        self.resets += 1

    def __call__(self, x):
        return np.full((len(x), self.links), float(self.value))


def _x(deg, speed):
    return np.array([[math.radians(deg), math.radians(deg), speed, speed]])


def test_the_hold_acts_from_the_band_until_the_exit_region():
    h = Handover(Const(1.0), Const(-1.0))                  # in: goal band; out: 10 deg, 0.3
    h.reset(1)
    seq = [(30, 0.0, 1.0), (4, 0.2, 1.0),      # near but too fast: still the approach
           (4, 0.05, -1.0), (8, 0.25, -1.0),   # settled: the hold, kept inside the exit
           (12, 0.0, 1.0), (8, 0.0, 1.0),      # beyond 10 deg: the approach again
           (2, 0.0, -1.0), (2, 0.5, 1.0)]      # in again; out by speed
    for deg, speed, want in seq:
        np.testing.assert_array_equal(h(_x(deg, speed)), [[want, want]])


def test_a_rescue_hands_a_cycle_near_the_goal_to_the_hold_until_it_settles():
    h = Handover(Const(1.0), Const(-1.0), Regions(rescue_deg=15.0, rescue_s=0.1))
    assert h.regions.rescue_samples == 2
    h.reset(1)
    seq = [(12, 2.0, 1.0), (20, 2.0, 1.0),     # near once, then out: the dwell restarts
           (12, 2.0, 1.0), (-9, 2.5, -1.0),    # two samples near: rescued
           (14, 3.0, -1.0), (30, 3.0, -1.0),   # held while rescued, whatever the reading
           (3, 0.05, -1.0), (12, 0.0, 1.0),    # settled: the plain hold, left beyond 10 deg
           (12, 0.0, -1.0)]                    # (that was near once) near twice: rescued
    for deg, speed, want in seq:
        np.testing.assert_array_equal(h(_x(deg, speed)), [[want, want]], err_msg=str(deg))


def test_without_a_rescue_a_cycle_near_the_goal_keeps_the_approach():
    h = Handover(Const(1.0), Const(-1.0))
    h.reset(1)
    for _ in range(100):
        np.testing.assert_array_equal(h(_x(8, 2.0)), [[1.0, 1.0]])


def test_every_joint_must_be_in_the_band_and_rows_switch_alone():
    h = Handover(Const(1.0), Const(-1.0))
    x = np.array([[0.01, 0.5, 0.0, 0.0],            # joint 2 far: approach
                  [0.01, -0.02, 0.05, 0.0],          # both in: hold
                  [2 * math.pi - 0.01, 0.0, 0.0, 0.0]])   # wrapped angle: in
    np.testing.assert_array_equal(h(x)[:, 0], [1.0, -1.0, -1.0])


def test_reset_releases_every_row_and_resets_both_designs():
    a, b = Const(1.0), Const(-1.0)
    h = Handover(a, b)
    h(_x(1, 0.0))
    h.reset(1)
    assert a.resets == b.resets == 2 and not h.held.any()
    np.testing.assert_array_equal(h(_x(8, 0.0)), [[1.0, 1.0]])


@pytest.mark.parametrize("kwargs, match", [
    ({"exit_deg": 3.0}, "exit_deg must be"),
    ({"enter_speed": 0.0}, "enter_speed must be"),
    ({"enter_deg": float("nan")}, "enter_deg must be"),
    ({"exit_speed": 0.05}, "exit_speed must be"),
    ({"rescue_deg": 4.0}, "rescue_deg must be"),
    ({"rescue_deg": 15.0, "rescue_s": 0.0}, "rescue_s must be"),
    ({"rescue_deg": 15.0, "rescue_s": 1e9}, "rescue_s must be")])
def test_bad_regions_are_one_line(kwargs, match):
    with pytest.raises(ValueError, match=match):
        Regions(**kwargs)
    with pytest.raises(ControllerError, match=f"handover h: {match}"):
        handover_policy("centralized_9levels", "lqr", kwargs, name="h")
    with pytest.raises(ControllerError, match="handover h: regions: .*unexpected keyword"):
        handover_policy("centralized_9levels", "lqr", {"enter": 1}, name="h")


def test_its_designs_drive_one_arm_on_one_model():
    with pytest.raises(ControllerError, match="its designs drive arms of 2 and 3 links"):
        Handover(Const(1.0), Const(1.0, links=3), name="h")
    with pytest.raises(ControllerError, match="name the models full and simplified"):
        Handover(Const(1.0, {"model": "full"}), Const(1.0, {"model": "simplified"}), name="h")
    h = Handover(Const(1.0, {"model": "full"}), Const(1.0), name="h")
    assert h.meta["model"] == "full"
    assert h.meta["handover"]["enter_deg"] == pytest.approx(5.0)


def test_the_shipped_handover_is_a_catalogue_controller():
    from twolink.control.controllers import resolve_controller
    from twolink.sim.evaluation import evaluate

    c = resolve_controller("centralized_handover")
    h = HANDOVERS["centralized_handover"]
    assert c.meta["handover"]["approach"] == h.approach
    assert c.meta["handover"]["hold"] == h.hold
    assert c.meta["model"] == "full"                 # --compensate predicts with (6)
    e = evaluate(c)                                  # the 65 states, nominal
    assert e.score.successes == 65


def test_the_study_s_rule_reads_the_targets():
    path = Path(__file__).resolve().parents[2] / "docs/studies/handover.py"
    spec = importlib.util.spec_from_file_location("handover_study", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    cells = {"none": 48, "n_none": 48, "ratio_median": 1.25, "medium": 254,
             "n_challenge": 256, "hard compensated": 200}
    assert module.meets(cells)
    assert not module.meets(dict(cells, ratio_median=1.26))
    assert not module.meets(dict(cells, medium=253))          # 98.8 %
    assert not module.meets(dict(cells, none=47))
    assert not module.meets(dict(cells, ratio_median=None))


def test_the_timed_handover_switches_at_its_sample_in_a_rollout():
    from twolink.arm.parameters import TS
    from twolink.sim.plants import MujocoPlant
    from twolink.sim.rollout import rollout

    h = TimedHandover(Const(0.5, kind="decentralized"), Const(-0.5, kind="decentralized"),
                      after_s=0.5)
    assert h.kind == "decentralized" and h.switch_sample == round(0.5 / TS) == 10
    for _ in range(2):                                    # the clock restarts each rollout
        traj = rollout(h, MujocoPlant(), np.zeros((2, 4)), duration=1.0)
        u = np.asarray(traj.u)
        assert (u[:, :10] == 0.5).all() and (u[:, 10:] == -0.5).all()
    assert TimedHandover(Const(1.0), Const(1.0, kind="decentralized"), 1.0).kind \
        == "centralized"


def test_a_timed_handover_is_checked_in_one_line():
    with pytest.raises(ControllerError, match="handover h: after_s must be"):
        TimedHandover(Const(1.0), Const(1.0), after_s=float("nan"), name="h")
    with pytest.raises(ControllerError, match="handover h: after_s must be"):
        TimedHandover(Const(1.0), Const(1.0), after_s=600.0, name="h")
    with pytest.raises(ControllerError, match="drive arms of 2 and 3 links"):
        TimedHandover(Const(1.0), Const(1.0, links=3), after_s=1.0, name="h")
    with pytest.raises(ControllerError, match="a timed handover .after_s. has no regions"):
        handover_policy("decentralized_edge_locked", "decentralized_edge_gain", {},
                        name="h", after_s=1.0)


def test_the_shipped_timed_handover_is_a_decentralized_catalogue_controller():
    from twolink.control.catalogue import shipped_entries
    from twolink.control.controllers import resolve_controller

    h = HANDOVERS["decentralized_handover"]
    c = resolve_controller("decentralized_handover")
    assert isinstance(c.controller, TimedHandover) and c.kind == "decentralized"
    assert c.meta["handover"] == {"approach": h.approach, "hold": h.hold,
                                  "after_s": h.after_s}
    assert c.switch_sample == round(h.after_s / 0.05)
    entry = {e.name: e for e in shipped_entries()}["decentralized_handover"]
    assert entry.kind == "decentralized" and entry.data["after_s"] == h.after_s
    assert "regions" not in entry.data


@pytest.mark.parametrize("name", sorted(HANDOVERS))
def test_every_shipped_handover_s_kind_is_its_controller_s(name):
    from twolink.control.catalogue import shipped_entries
    from twolink.control.controllers import resolve_controller

    entry = {e.name: e for e in shipped_entries()}[name]
    assert entry.kind == HANDOVERS[name].kind == resolve_controller(name).kind
