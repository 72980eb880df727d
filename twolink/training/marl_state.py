"""The learner of an IPPO/MAPPO run (:mod:`twolink.training.marl`) and its checkpoints.

:class:`Learner` holds skrl's agent (``IPPO`` or ``MAPPO`` of ``skrl.multi_agents.torch``,
one ``RandomMemory`` of one rollout per agent), the agents' policy and value networks
(skrl ``Model`` s: a Gaussian policy whose mean is
:func:`twolink.control.marl_agent.policy_net` with a state-independent log std, its
gradient carrying the bound loss of ``MarlConfig(bound_loss=C)``
(:func:`twolink.training.bound_loss.bounded`); a value
network of the same hidden sizes) and the batched env, and steps them itself: act,
clip the actions to [-1, 1] (with a base, ``MarlConfig(base='pd')``, turn them into
clip(PD_i + tau_max_i a_i, +-tau_max_i) per joint, :mod:`twolink.control.residual`,
scaled back to the env's normalized actions), step the env, record the transition (bootstrapping a
truncated episode from the env's ``final_observation``), ``post_interaction`` (which
updates after every ``n_steps`` vector steps). With a ``history`` K > 1 each agent acts
on its own history (:class:`twolink.training.marl_history.AgentHistories`); with an
``action_rate`` c > 0 the rewards recorded carry the penalty of
:func:`twolink.training.action_rate.agent_penalties`; under a ``challenge`` the arms
start from :meth:`MarlConfig.arm_seed` (the training stream).

Checkpoints are taken at the end of an update cycle only: skrl's memory has then been
consumed by the update and the next cycle overwrites every row of it before it is read,
so it need not be saved. What the rest of the run depends on is saved, and a resumed run
is bit for bit an uninterrupted one (on the CPU, the same torch and skrl, the same
threads):

* per agent the policy's and value's ``state_dict`` and the Adam optimizer's (and, with
  ``value_norm``, its value scaler's running statistics);
* skrl's rollout counter; torch's generator (Gaussian actions, minibatch permutations;
  CUDA's too on ``--device cuda``), numpy's and Python's global ones;
* the env: every arm's state, clock, last sample outside the band and generator, the last
  actions, and the observations the next step acts on; under a challenge, each arm's
  drawn plant, torques and readings in flight and faults
  (:func:`twolink.training.episodes.capture`); the agents' histories (K > 1) and last
  actions (an action-rate penalty).

The file is one ``torch.save`` of ``{"header": <JSON>, "state": <tensors and plain
containers>}`` of schema :data:`SCHEMA`, read with ``torch.load(weights_only=True)``; a
missing, truncated or foreign file, or one of a Stable-Baselines3 run, is one line.
"""
from __future__ import annotations

import random
from pathlib import Path

import numpy as np

from twolink.arm.parameters import links_parameters
from twolink.control.residual import residual_torques
from twolink.training import checkpoint, episodes
from twolink.training.action_rate import agent_penalties
from twolink.training.bound_loss import bounded
from twolink.training.marl_history import AgentHistories
from twolink.training.checkpoint import (
    generator_from_state,
    generator_state,
    to_array,
    to_tensor,
)

#: Schema and version of the checkpoint header.
SCHEMA, VERSION = "twolink.train.marl_checkpoint", 1
#: Largest checkpoint read.
MAX_BYTES = 2**30


def _models(torch, hidden, activation, log_std_init, min_log_std=-20.0, bound_loss=0.0):
    from skrl.models.torch import DeterministicMixin, GaussianMixin, Model

    from twolink.control.marl_agent import policy_net

    class Policy(GaussianMixin, Model):
        def __init__(self, observation_space, action_space, device):
            Model.__init__(self, observation_space=observation_space,
                           action_space=action_space, device=device)
            GaussianMixin.__init__(self, clip_actions=False, clip_log_std=True,
                                   min_log_std=float(min_log_std), max_log_std=2.0,
                                   reduction="sum")
            self.net = policy_net(observation_space.shape[0], hidden, activation)
            self.log_std = torch.nn.Parameter(torch.full((1,), float(log_std_init)))

        def compute(self, inputs, role=""):
            mean = bounded(self.net(inputs["observations"]), bound_loss)
            return mean, {"log_std": self.log_std}

    class Value(DeterministicMixin, Model):
        def __init__(self, space, key, device):
            Model.__init__(self, observation_space=space, action_space=space, device=device)
            DeterministicMixin.__init__(self, clip_actions=False)
            self.key = key
            self.net = policy_net(space.shape[0], hidden, activation)

        def compute(self, inputs, role=""):
            return self.net(inputs[self.key]), {}

    return Policy, Value


class Learner:
    """skrl's IPPO/MAPPO agent on the batched env of a :class:`MarlConfig` (see the
    module docstring)."""

    def __init__(self, config, torch):
        from gymnasium import spaces
        from skrl.memories.torch import RandomMemory
        from skrl.multi_agents.torch.base import ExperimentCfg
        from skrl.multi_agents.torch.ippo import IPPO
        from skrl.multi_agents.torch.mappo import MAPPO

        from twolink.arm.parameters import state_names
        from twolink.envs.multi_agent import agent_components
        from twolink.envs.pettingzoo_batched import batched_parallel_env
        if config.device == "cuda" and not torch.cuda.is_available():
            raise RuntimeError("--device cuda: torch sees no CUDA device here; train with "
                               "--device cpu")
        torch.set_num_threads(config.threads)
        torch.manual_seed(config.seed)
        np.random.seed(config.seed)
        random.seed(config.seed)
        self.config, self.torch = config, torch
        hp = self.hp = config.hyperparameters()
        self.env = batched_parallel_env(hp["n_envs"], **config.env_options())
        self.agents = list(self.env.possible_agents)
        names = state_names(config.links)
        parts = agent_components(config.links, config.observe)
        self.columns = [[names.index(c) for c in comp] for comp in parts]
        self.angles = [[c.startswith("theta") for c in comp] for comp in parts]
        n, device = hp["n_envs"], config.device
        self.histories = AgentHistories(self.agents, n, {
            a: self.env.observation_space(a).shape[0] for a in self.agents}, config.history)
        self.last = np.zeros((n, config.links))           # the action-rate penalty's
        obs_spaces = {a: spaces.Box(-np.inf, np.inf, (self.histories.size(a),), np.float32)
                      for a in self.agents}
        state = spaces.Box(-np.inf, np.inf, (3 * config.links,), np.float32)
        act = {a: spaces.Box(-1.0, 1.0, (1,), np.float32) for a in self.agents}
        Policy, Value = _models(torch, hp["hidden"], hp["activation"], hp["log_std_init"],
                                hp.get("min_log_std", -20.0), hp.get("bound_loss", 0.0))
        mappo = config.algo == "mappo"
        models = {a: {"policy": Policy(obs_spaces[a], act[a], device),
                      "value": Value(state if mappo else obs_spaces[a],
                                     "states" if mappo else "observations", device)}
                  for a in self.agents}
        memories = {a: RandomMemory(memory_size=hp["n_steps"], num_envs=n, device=device)
                    for a in self.agents}
        cfg = dict(rollouts=hp["n_steps"], learning_epochs=hp["learning_epochs"],
                   mini_batches=hp["mini_batches"], discount_factor=hp["gamma"],
                   gae_lambda=hp["gae_lambda"], learning_rate=hp["learning_rate"],
                   grad_norm_clip=hp["grad_norm_clip"], ratio_clip=hp["ratio_clip"],
                   value_clip=hp["value_clip"], value_loss_scale=hp["value_loss_scale"],
                   entropy_loss_scale=hp["entropy_loss_scale"], time_limit_bootstrap=True,
                   experiment=ExperimentCfg(write_interval=0, checkpoint_interval=0))
        # skrl 2.1.1 refuses its own empty-dict defaults (no key per agent): give one each
        for name in ("learning_rate_scheduler_kwargs", "observation_preprocessor_kwargs",
                     "state_preprocessor_kwargs", "value_preprocessor_kwargs"):
            cfg[name] = {a: {} for a in self.agents}
        if config.value_norm:
            from skrl.resources.preprocessors.torch import RunningStandardScaler

            cfg["value_preprocessor"] = {a: RunningStandardScaler for a in self.agents}
            cfg["value_preprocessor_kwargs"] = {a: {"size": 1, "device": device}
                                                for a in self.agents}
        cls = MAPPO if mappo else IPPO
        self.agent = cls(possible_agents=self.agents, models=models, memories=memories,
                         observation_spaces=obs_spaces, action_spaces=act,
                         state_spaces={a: state for a in self.agents}, device=device,
                         cfg=cfg)
        self.agent.init()
        self.agent.enable_training_mode(True)
        self.models = models
        from twolink.control.marl_agent import arm_tau_max
        from twolink.control.residual import base_controller, base_gains

        rule = config.rule if config.links > 2 else None
        params = links_parameters(config.links, rule) if config.links > 2 else None
        self.tau_max = arm_tau_max(config.links, rule)
        self.base = None if config.base == "none" else base_controller(config.base, params)
        self.gains = None if self.base is None else base_gains(config.base, params)
        self.steps = 0
        self.obs = None                                   # before the first reset

    # ------------------------------------------------------------------ stepping
    def _tensor(self, a):
        return self.torch.as_tensor(np.asarray(a, dtype=np.float32), device=self.config.device)

    def _state(self, x):
        from twolink.arm.observations import features

        return self._tensor(features(x, "cos_sin"))

    def learn(self, steps: int, total: int) -> None:
        """Step ``steps`` environment steps (whole update cycles) of a run of ``total``."""
        torch, n = self.torch, self.hp["n_envs"]
        c, team = self.config.action_rate, self.config.algo == "mappo"
        if self.obs is None:
            self.obs = self.histories.start(self.env.reset(seed=self.config.arm_seed())[0])
        for _ in range(steps // n):
            t, tt = self.steps // n, total // n
            obs = {a: self._tensor(self.obs[a]) for a in self.agents}
            x = self.env.state()
            s = self._state(x)
            states = {a: s for a in self.agents}
            with torch.no_grad():
                actions, _ = self.agent.act(obs, states, timestep=t, timesteps=tt)
            sent = {a: np.clip(actions[a].cpu().numpy().astype(np.float64), -1.0, 1.0)
                    for a in self.agents}
            self.histories.act(sent)
            own = np.concatenate([sent[a].reshape(n, 1) for a in self.agents], 1)
            fine = agent_penalties(own, self.last, c, team) if c > 0 else None
            if self.base is not None:         # joint i: its PD plus agent i's residual
                u = residual_torques(self.base, x, np.concatenate(
                    [sent[a].reshape(n, 1) for a in self.agents], 1), self.tau_max)
                sent = {a: (u[:, i] / self.tau_max[i]).reshape(sent[a].shape)
                        for i, a in enumerate(self.agents)}
            nxt, rewards, terms, truncs, infos = self.env.step(sent)
            ended = truncs[self.agents[0]]
            nxt, final = self.histories.step(
                nxt, {a: infos[a]["final_observation"] for a in self.agents}, ended)
            final = {a: self._tensor(final[a]) for a in self.agents}
            if fine is not None:
                rewards = {a: rewards[a] - fine[:, i] for i, a in enumerate(self.agents)}
                self.last = own
                self.last[ended] = 0.0                     # a new episode begins
            s2 = self._state(infos[self.agents[0]]["final_state"])
            b = lambda v: torch.as_tensor(v, device=self.config.device).reshape(n, 1)  # noqa
            self.agent.record_transition(
                observations=obs, states=states, actions=actions,
                rewards={a: self._tensor(rewards[a]).reshape(n, 1) for a in self.agents},
                next_observations=final, next_states={a: s2 for a in self.agents},
                terminated={a: b(terms[a]) for a in self.agents},
                truncated={a: b(truncs[a]) for a in self.agents},
                infos=infos, timestep=t, timesteps=tt)
            self.agent.post_interaction(timestep=t, timesteps=tt)
            self.obs = nxt
            self.steps += n

    # ------------------------------------------------------------------ the agent
    def policy_state(self) -> dict:
        """Per agent the policy network's tensors (``0.weight`` ..), copies."""
        return {a: {k: v.detach().cpu().clone() for k, v in
                    self.models[a]["policy"].net.state_dict().items()} for a in self.agents}

    def header(self) -> dict:
        c = self.config
        return {"algo": c.algo, "links": c.links, "rule": c.rule if c.links > 2 else None,
                "observe": c.observe, "observation": "cos_sin", "actions": "normalized",
                "reward": c.env_options()["reward"], "hidden": list(self.hp["hidden"]),
                "activation": self.hp["activation"], "agents": list(self.agents),
                "columns": self.columns, "angles": self.angles, "seed": c.seed,
                "steps": int(self.steps), "challenge": c.challenge, "history": c.history,
                "observation_layouts": [self.histories.layout(a) for a in self.agents],
                "action_rate": c.action_rate,
                **({} if self.base is None else {"base": c.base, "base_gains": self.gains})}

    def controller(self):
        """The decentralized controller of the policies as they are now."""
        from twolink.control.marl_agent import MarlController, arm_tau_max, policy_net

        nets = []
        for i, a in enumerate(self.agents):
            net = policy_net(self.histories.size(a), self.hp["hidden"], self.hp["activation"])
            net.load_state_dict(self.models[a]["policy"].net.state_dict())
            nets.append(net.eval())
        c = self.config
        return MarlController(nets, self.columns, self.angles,
                              arm_tau_max(c.links, c.rule if c.links > 2 else None),
                              name=f"{c.algo}_seed{c.seed}", meta={"algo": c.algo},
                              base=self.base, history=c.history)

    def save_agent(self, path) -> Path:
        from twolink.control.marl_agent import save_marl_agent

        return save_marl_agent(path, self.header(), self.policy_state())

    # ------------------------------------------------------------------ checkpoints
    def capture(self) -> tuple[dict, dict]:
        """(JSON-ready state, tensors) at the end of an update cycle."""
        torch = self.torch
        tensors = {"models": {a: {k: m.state_dict() for k, m in self.models[a].items()}
                              for a in self.agents},
                   "optimizers": {a: self.agent.optimizers[a].state_dict()
                                  for a in self.agents},
                   "torch_rng": torch.get_rng_state()}
        if self.config.value_norm:
            tensors["value_scalers"] = {a: self.agent._value_preprocessor[a].state_dict()
                                        for a in self.agents}
        if self.config.device == "cuda":
            tensors["cuda_rng"] = torch.cuda.get_rng_state_all()
        np_state = np.random.get_state(legacy=False)
        tensors["numpy_key"] = to_tensor(np_state["state"]["key"].astype(np.int64))
        py = random.getstate()
        started = self.obs is not None
        plain = {"started": started, "steps": int(self.steps),
                 "rollout": int(self.agent._rollout),
                 "numpy": {"pos": int(np_state["state"]["pos"]),
                           "has_gauss": int(np_state["has_gauss"]),
                           "gauss": float(np_state["gauss"])},
                 "python_random": [py[0], list(py[1]), py[2]]}
        if started:
            arms = self.env._live()
            tensors["arms"] = {"x": to_tensor(arms.x), "k": to_tensor(arms.k),
                               "last_out": to_tensor(arms.last_out),
                               "last": to_tensor(self.env._last)}
            tensors["obs"] = {a: to_tensor(o) for a, o in self.obs.items()}
            plain["arm_generators"] = [generator_state(r) for r in arms.rngs]
            if self.config.challenge is not None:
                tensors["episodes"] = episodes.capture(self.env)
            if self.config.history > 1:
                tensors["histories"] = {a: {k: to_tensor(v) for k, v in h.items()}
                                        for a, h in self.histories.state().items()}
            if self.config.action_rate > 0:
                tensors["last_actions"] = to_tensor(self.last)
        return plain, tensors

    def restore(self, plain: dict, tensors: dict) -> None:
        """Put the learner (just built for the same config) into the captured state."""
        torch = self.torch
        for a in self.agents:
            for k, m in self.models[a].items():
                m.load_state_dict(tensors["models"][a][k])
            self.agent.optimizers[a].load_state_dict(tensors["optimizers"][a])
            if self.config.value_norm:
                self.agent._value_preprocessor[a].load_state_dict(
                    tensors["value_scalers"][a])
        self.agent._rollout = plain["rollout"]
        self.steps = plain["steps"]
        if plain["started"]:
            arms = self.env._live()
            arms.x[:] = to_array(tensors["arms"]["x"])
            arms.k[:] = to_array(tensors["arms"]["k"])
            arms.last_out[:] = to_array(tensors["arms"]["last_out"])
            self.env._last = to_array(tensors["arms"]["last"])
            for i, state in enumerate(plain["arm_generators"]):
                arms.rngs[i] = generator_from_state(state)
                arms.sensors.set_generator(i, arms.rngs[i])
            self.env._started = True
            self.obs = {a: to_array(t).astype(np.float64) for a, t in tensors["obs"].items()}
            if "episodes" in tensors:
                episodes.restore(self.env, tensors["episodes"])
            if "histories" in tensors:
                self.histories.set_state({a: {k: to_array(v) for k, v in h.items()}
                                          for a, h in tensors["histories"].items()})
            if "last_actions" in tensors:
                self.last = to_array(tensors["last_actions"]).astype(float).reshape(
                    self.last.shape)
        version, key, gauss = plain["python_random"]
        random.setstate((version, tuple(key), gauss))
        np.random.set_state({"bit_generator": "MT19937",
                             "state": {"key": to_array(tensors["numpy_key"]).astype(np.uint32),
                                       "pos": plain["numpy"]["pos"]},
                             "has_gauss": plain["numpy"]["has_gauss"],
                             "gauss": plain["numpy"]["gauss"]})
        torch.set_rng_state(tensors["torch_rng"])
        if "cuda_rng" in tensors:
            torch.cuda.set_rng_state_all(tensors["cuda_rng"])

    def close(self) -> None:
        self.env.close()


def save(path, header: dict, tensors: dict) -> Path:
    """Write the checkpoint atomically (:func:`twolink.training.checkpoint.save`, this
    module's schema)."""
    return checkpoint.save(path, header, tensors, schema=SCHEMA, version=VERSION)


def load(path) -> tuple[dict, dict]:
    """(header, tensors) of the checkpoint at ``path``
    (:func:`twolink.training.checkpoint.read`, nothing unpickled); a one-line ValueError
    when it is missing, too large, truncated, foreign or a Stable-Baselines3 run's."""
    header, state = checkpoint.read(path, max_bytes=MAX_BYTES)
    if header.get("schema") == checkpoint.SCHEMA:
        algo = (header.get("config") or {}).get("algo")
        raise ValueError(f"{path} is a checkpoint of a {algo} run (Stable-Baselines3), not "
                         f"of an ippo or mappo run")
    if header.get("schema") != SCHEMA:
        raise ValueError(f"{path} is not a twolink training checkpoint")
    if header.get("version") != VERSION:
        raise ValueError(f"{path} is a multi-agent checkpoint of version "
                         f"{header.get('version')!r}; this twolink reads version {VERSION}")
    return header, state


def check_resume(header: dict, given, path: Path, mine: dict, cls):
    """The config of the checkpoint ``header`` with ``given`` applied (a MarlConfig, or a
    dict of the options given): every identity field given must be the checkpoint's,
    ``steps`` may change; this machine's skrl must be the checkpoint's. ``cls``: the
    config class (:class:`twolink.training.marl.MarlConfig`)."""
    MarlConfig = cls
    saved = MarlConfig.from_dict(header.get("config"))
    if isinstance(given, MarlConfig):
        given = given.as_dict()
    given = {k: v for k, v in (given or {}).items() if v is not None}
    for name in MarlConfig.IDENTITY:
        if name in given and given[name] != getattr(saved, name):
            raise ValueError(f"{path} is a checkpoint of a run with {name} "
                             f"{getattr(saved, name)!r}, not {given[name]!r}")
    if "steps" in given:
        saved = MarlConfig.from_dict(dict(saved.as_dict(), steps=given["steps"]))
    theirs = (header.get("versions") or {}).get("skrl")
    if theirs != mine["skrl"]:
        raise ValueError(f"{path} was written by skrl {theirs}, this is {mine['skrl']}: it "
                         f"cannot resume exactly")
    return saved
