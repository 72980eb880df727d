"""The MuJoCo plant skips the constraint stage only where it would find nothing, and
its states are then those of the arm's MJCF as built, bit for bit."""
import copy

import mujoco
import numpy as np
from mujoco import rollout as mj_rollout

from twolink.arm import mjcf
from twolink.arm.integrate import finish_sample
from twolink.arm.parameters import TABLE_I
from twolink.sim.challenges import LEVELS
from twolink.sim.plants import MujocoPlant, constraint_free, physics_state

OFF = mujoco.mjtDisableBit.mjDSBL_CONSTRAINT


def test_the_arm_is_constraint_free_and_a_limited_joint_is_not():
    model = mjcf.build_model(TABLE_I)
    assert constraint_free(model)
    limited = copy.copy(model)
    limited.jnt_limited[0] = True
    assert not constraint_free(limited)
    touching = copy.copy(model)
    touching.opt.disableflags &= ~int(mujoco.mjtDisableBit.mjDSBL_CONTACT)
    assert not constraint_free(touching)


def test_plant_steps_equal_the_mjcf_as_built_bit_for_bit():
    params = LEVELS["hard"].plants(3, 7)
    rng = np.random.default_rng(0)
    x = np.column_stack([rng.uniform(-3, 3, (3, 2)), rng.uniform(-5, 5, (3, 2))])
    tau = rng.uniform(-0.3, 0.3, (3, 2))          # beyond the limits too: clipped alike
    with MujocoPlant(params, nthread=2) as plant:
        assert all(m.opt.disableflags & OFF for m in plant.models)
        got = [plant.step(x, tau)]
        got.append(plant.step(got[0], -tau))
    built = [mjcf.build_model(p) for p in params]
    assert not any(m.opt.disableflags & OFF for m in built)
    want, state = [], physics_state(x)
    with mj_rollout.Rollout(nthread=0) as pool:
        for u in (tau, -tau):
            u = np.clip(u, -np.stack([p.tau_max for p in params]),
                        np.stack([p.tau_max for p in params]))
            out, _ = pool.rollout(built, [mujoco.MjData(built[0])], state,
                                  np.repeat(u[:, None], plant.nstep, 1))
            end = out[:, -1, 1:]
            nxt = finish_sample(params[0], end,
                                speed_max=np.stack([p.speed_max for p in params]))
            want.append(nxt)
            state = physics_state(nxt)
    for g, w in zip(got, want):
        assert np.array_equal(g, w)
        assert g.shape == (3, 4)
