"""The receding-horizon time-optimal MPC (twolink.control.mpc): a controller
of the protocol that settles the MuJoCo arm at the limit T*, re-planning every sample."""
import numpy as np
import pytest

from twolink.arm.task import in_goal_band
from twolink.sim.metrics import evaluation_set, settle_time
from twolink.sim.plants import MujocoPlant
from twolink.sim.rollout import rollout
from twolink.studies.leaderboard.limits import state_limits

pytest.importorskip("casadi")

X0 = evaluation_set()[30:31]        # [-10 deg, 45 deg] at rest: T* = 0.25 s, few horizons


def test_mpc_settles_at_the_limit_and_replans_every_sample():
    from twolink.control.controllers import resolve_controller
    from twolink.control.mpc import TimeOptimalMPC
    from twolink.sim.controller import checked

    spec = resolve_controller("twolink.control.mpc:TimeOptimalMPC")
    assert spec.name == "time_optimal_mpc" and spec.meta["model"] == "full"   # its name
    c = checked(TimeOptimalMPC(expand=False))      # quicker to build, the same problem
    with MujocoPlant(nthread=1) as plant:
        traj = rollout(c, plant, X0, duration=1.0)
    limit, _ = state_limits(X0)
    assert settle_time(traj)[0] == pytest.approx(limit[0])       # 5 samples, the limit
    assert np.all(in_goal_band(traj.x[0, 5:]))
    assert np.all(np.abs(traj.u) <= np.array([1.5, 0.1]) + 1e-12)
    mpc = c.controller
    assert len(mpc.timings) == 1 and len(mpc.timings[0]) == traj.steps   # one per sample
    assert mpc.plans[0] is not None and mpc.plans[0].n == 1              # in the band: hold
    mpc.reset(2)
    assert mpc.plans == [None, None] and mpc.timings == [[], []]


def test_a_row_out_of_reach_or_in_the_band_gets_zero_torque_and_no_more_searches():
    from twolink.control.mpc import UNREACHABLE, TimeOptimalMPC

    c = TimeOptimalMPC(expand=False, max_samples=2)        # x0 needs 18 samples
    x = np.array([[-1.0, -3.0, 0.0, 0.0], [0.01, 0.0, 0.0, 0.0]])
    assert np.array_equal(c(x), np.zeros((2, 2)))
    assert c.plans == [UNREACHABLE, None]
    solves = c.search_cache.solves + c.cache.solves
    assert np.array_equal(c(x), np.zeros((2, 2)))
    assert c.search_cache.solves + c.cache.solves == solves
