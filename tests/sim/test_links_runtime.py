"""The running layer for N-link arms: plants, policies, rewards, metrics, rollouts.

The batched MuJoCo plant is held bit for bit against a plain ``mj_step`` loop over rows
(written here, independently of :mod:`twolink.sim.plants`), as ``mujoco``'s rollout_test.py
holds ``rollout`` against ``py_rollout``.
"""
import math

import mujoco
import numpy as np
import pytest

from twolink.arm import mjcf
from twolink.arm.parameters import TABLE_I, TS, links_parameters
from twolink.arm.task import agent_reward, centralized_reward, in_goal_band
from twolink.fqi.fuzzy import Axis, Grid
from twolink.policy.fuzzy_policy import Agent, Policy, check_links_match, load_policy
from twolink.sim.metrics import (
    MAX_POSES,
    final_offsets_deg,
    random_poses,
    settle_time,
    success,
    trajectory_gap,
)
from twolink.sim.plants import (
    ModelPlant,
    MujocoPlant,
    check_states,
    check_torques,
    make_plant,
)
from twolink.sim.rollout import Trajectory, rollout, steps_for


def _step_loop(p, x, tau):
    """One sample period of the N-link MJCF, row by row with ``mj_step``, then the
    angles wrapped to [-pi, pi) and the speeds saturated (docs/conventions.md)."""
    model = mjcf.build_model(p)
    n = p.links
    out = np.empty_like(x)
    for i in range(len(x)):
        data = mujoco.MjData(model)
        for k in range(n):
            data.qpos[k], data.qvel[k] = x[i, k], x[i, n + k]
            data.ctrl[k] = min(max(tau[i, k], -p.torque_limits[k]), p.torque_limits[k])
        for _ in range(int(round(TS / model.opt.timestep))):
            mujoco.mj_step(model, data)
        for k in range(n):
            angle = math.fmod(data.qpos[k] + math.pi, 2 * math.pi)
            out[i, k] = (angle + 2 * math.pi if angle < 0 else angle) - math.pi
            limit = p.speed_limits[k]
            out[i, n + k] = min(max(data.qvel[k], -limit), limit)
    return out


def _states(rng, n, rows):
    x = np.empty((rows, 2 * n))
    x[:, :n] = rng.uniform(-4, 4, (rows, n))
    x[:, n:] = rng.uniform(-8, 8, (rows, n))       # beyond 2 pi rad/s: saturation too
    return x


@pytest.mark.parametrize("n,rule", [(3, "tapered"), (4, "copied")])
def test_mujoco_plant_equals_mj_step_loop(rng, n, rule):
    p = links_parameters(n, rule)
    x, tau = _states(rng, n, 6), rng.uniform(-0.3, 0.3, (6, n))
    with MujocoPlant(p, nthread=2) as plant:
        assert plant.links == n and plant.model.nq == n
        out = plant.step(x.reshape(2, 3, 2 * n), tau.reshape(2, 3, n))
    assert out.shape == (2, 3, 2 * n)
    np.testing.assert_array_equal(out.reshape(6, 2 * n), _step_loop(p, x, tau))


def test_per_row_mujoco_plant_of_three_links(rng):
    plist = [links_parameters(3), links_parameters(3, "copied")]
    x, tau = _states(rng, 3, 2), rng.uniform(-0.3, 0.3, (2, 3))
    with MujocoPlant(plist, nthread=1) as plant:
        out = plant.step(x, tau)
        with pytest.raises(ValueError, match="a 4-link parameter set for a plant of 3 links"):
            plant.set_row_params(0, links_parameters(4))
    for i, p in enumerate(plist):
        np.testing.assert_array_equal(out[i], _step_loop(p, x[[i]], tau[[i]])[0])
    with pytest.raises(ValueError, match="same number of links, got 2, 3"):
        MujocoPlant([TABLE_I, links_parameters(3)])


def test_full_model_agrees_with_mujoco_for_three_links(rng):
    # Both integrate one sample period with RK4 in SUBSTEPS substeps of the same
    # equations of motion (MuJoCo's RK4 at timestep Ts / SUBSTEPS), so they differ only
    # in round-off: measured 3.6e-15 over this batch (copied links 2.7e-15, N = 4
    # 2.9e-15, N = 6 5.3e-15); 1e-12 leaves room for another BLAS or libm, while a
    # modelling difference shows far above it (1 % more inertia or damping on link 3
    # moves this batch by 3e-2).
    p = links_parameters(3)
    x, tau = _states(rng, 3, 200), rng.uniform(-0.3, 0.3, (200, 3))
    with make_plant("full", p) as full, make_plant("mujoco", p, nthread=2) as mj:
        assert full.links == mj.links == 3
        d = full.step(x, tau) - mj.step(x, tau)
    d[:, :3] = (d[:, :3] + np.pi) % (2 * np.pi) - np.pi
    assert np.abs(d).max() < 1e-12


def test_two_links_run_the_table_i_code(rng):
    x, tau = _states(rng, 2, 20), rng.uniform(-0.3, 0.3, (20, 2))
    for name in ("simplified", "full", "mujoco"):
        with make_plant(name, links_parameters(2)) as a, make_plant(name, TABLE_I) as b:
            assert a.params == TABLE_I
            np.testing.assert_array_equal(a.step(x, tau), b.step(x, tau))


def test_plants_refuse_what_they_cannot_run():
    with pytest.raises(ValueError, match=r"model \(11\) is the paper's two-link simplification"):
        make_plant("simplified", links_parameters(3))
    with pytest.raises(ValueError, match="gravity is modelled for two links only"):
        ModelPlant("full", links_parameters(3), gravity=True)
    with make_plant("full", links_parameters(3)) as plant:
        with pytest.raises(ValueError, match=r"state must have 6 components \[theta1, theta2, "
                                             r"theta3, dtheta1, dtheta2, dtheta3\]"):
            plant.step(np.zeros(4), np.zeros(3))
        with pytest.raises(ValueError, match=r"torque must have 3 components \[tau1, tau2, "
                                             r"tau3\], got shape \(2,\)"):
            plant.step(np.zeros(6), np.zeros(2))
    with pytest.raises(ValueError, match=r"x0 has a speed of magnitude 70 rad/s"):
        check_states([0, 0, 0, 0, 0, 70.0], what="x0", speed_max=links_parameters(3).speed_max,
                     links=3)
    with pytest.raises(ValueError, match="links must be a whole number from 2 to 6"):
        check_torques(np.zeros(7), links=7)


def _joint_agent(k: int, gain: float) -> Agent:
    """A PD-like agent of joint k: on a 3 x 3 grid of (theta_k, dtheta_k) its greedy
    torque opposes the angle and the speed."""
    grid = Grid((Axis(f"theta{k}", (-1.0, 0.0, 1.0)), Axis(f"dtheta{k}", (-1.0, 0.0, 1.0))))
    actions = np.array([[-gain], [0.0], [gain]])
    want = -np.sign(grid.centers().sum(-1))                  # -1, 0, +1 per bin
    q = -np.abs(actions[:, 0][None, :] / gain - want[:, None])
    return Agent(f"agent{k}", grid, actions, q, (f"tau{k}",))


def _three_link_policy() -> Policy:
    agents = [_joint_agent(k, g) for k, g in ((3, 0.05), (2, 0.1), (1, 0.2))]
    return Policy("decentralized", agents, {"links": 3})


def test_three_link_policy_maps_states_to_torques_and_round_trips(tmp_path, rng):
    policy = _three_link_policy()
    assert policy.links == 3
    x = rng.uniform(-2, 2, (4, 5, 6))
    u = policy(x)
    assert u.shape == (4, 5, 3)
    at = np.zeros(6)
    at[[0, 4]] = 1.0                 # theta1 = 1 (bin centre), dtheta2 = 1 (bin centre)
    np.testing.assert_allclose(policy(at), [-0.2, -0.1, 0.0])
    again = load_policy(policy.save(tmp_path / "three.npz"))
    assert again.links == 3 and again.meta["links"] == 3
    np.testing.assert_array_equal(again(x), u)


def test_policies_refuse_another_number_of_links():
    policy = _three_link_policy()
    with pytest.raises(ValueError, match=r"policy input must have shape \(\.\.\., 6\), got "
                                         r"\(4,\) \(a 3-link policy\)"):
        policy(np.zeros(4))
    with pytest.raises(ValueError, match="policy decentralized is for a 3-link arm, the arm "
                                         "has 2 links"):
        check_links_match(policy, 2)
    assert check_links_match(policy, 3) is policy
    with pytest.raises(ValueError, match="must output tau1, tau2 and tau3"):
        Policy("partial", policy.agents[:2], {"links": 3})
    with pytest.raises(ValueError, match=r"agent4 reads \['theta4', 'dtheta4'\]"):
        Policy("wide", [_joint_agent(4, 0.1)] + policy.agents, {"links": 3})
    with pytest.raises(ValueError, match="links must be a whole number from 2 to 6"):
        Policy("big", policy.agents, {"links": 7})
    with make_plant("full", TABLE_I) as plant:
        with pytest.raises(ValueError, match="policy mine is for a 3-link arm, the arm has 2"):
            rollout(policy, plant, np.zeros(4), duration=0.1, label="mine")


def _trajectory(x: np.ndarray) -> Trajectory:
    k = x.shape[-2] - 1
    n = x.shape[-1] // 2
    return Trajectory(np.arange(k + 1) * TS, x, np.zeros(x.shape[:-2] + (k, n)),
                      centralized_reward(x[..., 1:, :]), np.zeros(x.shape[:-2] + (k, n)))


def test_rewards_and_success_of_hand_made_three_link_trajectories():
    band = math.radians(5.0)
    inside = np.array([0.0, band, -band, 0.1, -0.1, 0.0])
    outside = inside.copy()
    outside[2] = 1.1 * band                                   # link 3 out of its band
    assert in_goal_band(np.stack([inside, outside])).tolist() == [True, False]
    assert centralized_reward(outside) == -0.5
    assert [float(agent_reward(outside, k)) for k in (1, 2, 3)] == [0.0, 0.0, -0.5]
    with pytest.raises(ValueError, match="link must be 1 to 3, got 4"):
        agent_reward(outside, 4)
    with pytest.raises(ValueError, match="link must be 1 or 2, got 3"):
        agent_reward(np.zeros(4), 3)
    with pytest.raises(ValueError, match="states must have 2N components"):
        in_goal_band(np.zeros(5))
    # 101 samples (5 s): out of the band until sample 30 (1.5 s), then in it.
    x = np.repeat(inside[None], 101, 0)
    x[:30] = outside
    late = x.copy()
    late[90] = outside                                        # leaves again at 4.5 s
    traj = _trajectory(np.stack([x, late]))
    np.testing.assert_allclose(settle_time(traj), [1.5, 4.55])
    assert success(traj).tolist() == [True, False]
    assert final_offsets_deg(traj).shape == (2, 3)
    gap = trajectory_gap(traj, _trajectory(np.stack([x, x])))
    assert gap["angle_rms"][0] == 0.0 and gap["angle_rms"][1] > 0.0


def test_random_poses_shape_range_determinism_and_cap():
    poses = random_poses(4, 1000, 7)
    assert poses.shape == (1000, 8)
    assert np.all(poses[:, 4:] == 0.0)
    assert poses[:, :4].min() >= -math.pi and poses[:, :4].max() < math.pi
    assert poses[:, :4].min() < -3.0 and poses[:, :4].max() > 3.0      # covers the circle
    np.testing.assert_array_equal(poses, random_poses(4, 1000, 7))
    np.testing.assert_array_equal(poses[:10], random_poses(4, 10, 7))  # rows drawn in order
    assert not np.array_equal(poses, random_poses(4, 1000, 8))
    with pytest.raises(ValueError, match=f"count must be a whole number from 1 to {MAX_POSES}"):
        random_poses(3, MAX_POSES + 1, 0)
    with pytest.raises(TypeError, match="seed must be an int"):      # a type, not a value
        random_poses(3, 10, None)
    with pytest.raises(ValueError, match="links must be a whole number from 2 to 6"):
        random_poses(1, 10, 0)


def test_three_link_rollout_on_mujoco_has_the_documented_shapes():
    policy = _three_link_policy()
    x0 = random_poses(3, 4, 0)
    with make_plant("mujoco", links_parameters(3), nthread=1) as plant:
        traj = rollout(policy, plant, x0, duration=0.5)
    assert traj.x.shape == (4, 11, 6) and traj.u.shape == (4, 10, 3)
    assert traj.r.shape == (4, 10) and traj.r_links.shape == (4, 10, 3)
    assert traj.links == 3 and traj.plant == "mujoco"
    np.testing.assert_array_equal(traj.x[:, 0], x0)
    np.testing.assert_array_equal(traj.u[:, 0], policy(x0))
    np.testing.assert_array_equal(traj.r_links[..., 2], agent_reward(traj.x[:, 1:], 3))
    assert steps_for(1.0, rows=4, links=3) == 20
    with pytest.raises(ValueError, match=r"100000 states x 72000 sample periods need 1341\.1 GiB"):
        steps_for(3600.0, rows=100000, links=6)
