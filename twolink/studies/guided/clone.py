"""Behaviour cloning of demonstrations into a residual agent's policy (PPO over the PD).

The demonstrations (:mod:`.demos`) give states x_t and the solver's torques u_t. The
agent acts through the residual env (:class:`twolink.envs.residual.ResidualVecEnv`):
torque = clip(PD(x) + tau_max a), so the action that reproduces u_t is
a_t = clip((u_t - PD(x_t)) / tau_max, -1, 1), and the policy sees the cos/sin features of
x_t (:func:`twolink.arm.observations.features`). :func:`clone` starts from the policy of
a run's ``init`` agent (:func:`twolink.training.run.build`) and fits the mean of its
action distribution, by Adam on the mean squared error, to the demonstrations' actions
and, with weight ``keep``, to the init agent's own actions on the states its rollouts
from uniform poses pass (so what it already does well is kept). The value network is
left as it is; PPO fine-tuning (``twolink train --init``) follows.
"""
from __future__ import annotations

import numpy as np

from twolink.arm.observations import features


def demo_pairs(demos, params, base) -> tuple:
    """(observations (M, 3N) float32, actions (M, N)) of every demonstration's samples."""
    obs, act = [], []
    tau = np.asarray(params.tau_max, float)
    for d in demos:
        x = np.asarray(d["states"], float)
        u = np.asarray(d["torques"], float)
        obs.append(features(x, "cos_sin"))
        act.append(np.clip((u - base(x)) / tau, -1.0, 1.0))
    return np.concatenate(obs).astype(np.float32), np.concatenate(act).astype(np.float32)


def own_pairs(agent, params, *, poses: int, seed: int, duration: float = 8.0) -> tuple:
    """(observations, actions) of the agent ``agent`` (an
    :class:`twolink.control.sb3_agent.SB3Agent` over the PD) along its own rollouts from
    ``poses`` uniform poses of ``seed``: the mean of its action distribution at every
    state it passes (unclipped: what the clone's mean is fitted to)."""
    import torch

    from twolink.sim.metrics import random_poses
    from twolink.sim.plants import make_plant
    from twolink.sim.rollout import rollout

    x0 = random_poses(params.links, poses, seed)
    with make_plant("mujoco", params) as plant:
        traj = rollout(agent, plant, x0, duration=duration)
    x = traj.x[:, :-1].reshape(-1, 2 * params.links)
    obs = features(x, "cos_sin").astype(np.float32)
    with torch.no_grad():
        mean = _mean(agent.policy, torch.as_tensor(obs)).numpy()
    return obs, mean.astype(np.float32)


def _mean(policy, obs):
    """The mean of an SB3 PPO policy's action distribution at ``obs``."""
    feats = policy.extract_features(obs, policy.pi_features_extractor)
    return policy.action_net(policy.mlp_extractor.forward_actor(feats))


def clone(model, demo, keep, *, keep_weight: float = 1.0, epochs: int = 200,
          batch: int = 512, lr: float = 3e-4, seed: int = 0, log=print) -> dict:
    """Fit ``model``'s policy mean to ``demo`` = (obs, actions) and, weighted
    ``keep_weight``, to ``keep``; the losses before and after."""
    import torch

    torch.manual_seed(seed)
    policy = model.policy
    params = (list(policy.mlp_extractor.policy_net.parameters())
              + list(policy.action_net.parameters()))
    opt = torch.optim.Adam(params, lr=lr)
    d_obs, d_act = map(torch.as_tensor, demo)
    k_obs, k_act = map(torch.as_tensor, keep)

    def losses():
        with torch.no_grad():
            return (float(((_mean(policy, d_obs) - d_act) ** 2).mean()),
                    float(((_mean(policy, k_obs) - k_act) ** 2).mean()))

    before = losses()
    rng = np.random.default_rng(seed)
    policy.set_training_mode(True)
    for epoch in range(epochs):
        order_d = rng.permutation(len(d_obs))
        order_k = rng.permutation(len(k_obs))
        for start in range(0, len(order_d), batch):
            i = torch.as_tensor(order_d[start:start + batch])
            j = torch.as_tensor(order_k[rng.integers(0, len(order_k), len(i))])
            loss = (((_mean(policy, d_obs[i]) - d_act[i]) ** 2).mean()
                    + keep_weight * ((_mean(policy, k_obs[j]) - k_act[j]) ** 2).mean())
            opt.zero_grad()
            loss.backward()
            opt.step()
        if (epoch + 1) % max(1, epochs // 5) == 0:
            log(f"  epoch {epoch + 1}/{epochs}: demo {losses()[0]:.4f}, keep {losses()[1]:.4f}")
    policy.set_training_mode(False)
    return {"before": {"demo": before[0], "keep": before[1]},
            "after": dict(zip(("demo", "keep"), losses()))}
