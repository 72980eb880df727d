"""A saved multi-agent (IPPO/MAPPO) arm as one decentralized controller, read as data.

``twolink train --algo ippo|mappo`` (:mod:`twolink.training.marl`) saves its agents as
one file ``<run>.marl.pt`` (:data:`SUFFIX`): a ``torch.save`` of ``{"header": <JSON
text>, "policies": {"link1": {<tensor name>: tensor}, ..}}``, read back with
``torch.load(weights_only=True)`` (tensors and plain containers only: nothing is
unpickled). The header (:data:`SCHEMA`, :data:`VERSION`) names the algorithm, the arm
(``links``, ``rule``), the observation model (``observe``, ``observation``), the hidden
sizes and activation of the policy networks, and per agent the state columns it reads
and which of them are angles (seen as cos, sin), so the controller needs nothing of the
environment layer to rebuild each agent's observation.

:class:`MarlController` is a controller of :mod:`twolink.sim.controller`: states (n, 2N)
-> torques (n, N), joint I's torque being agent ``linkI``'s deterministic action (the
mean of its Gaussian policy) on its own observation of the state, clipped to [-1, 1] and
scaled by the arm's tau_max (``actions='normalized'``); with a ``base`` in the header
(``"pd"`` and its ``base_gains``, :mod:`twolink.control.residual`) that action is a
residual over joint I's own PD: clip(PD_I + tau_max_I a_I, +-tau_max_I). Nothing is shared between the
agents at run time: the controller is decentralized whatever critic trained it. With a
``history`` K > 1 in the header (``twolink train --history K``), agent I's policy sees
the last K of its own observations and its own K - 1 last actions
(:mod:`twolink.training.marl_history`, the layout of :mod:`twolink.control.history`,
recorded per agent as ``observation_layouts``): the controller keeps one
:class:`~twolink.control.history.ObservationHistory` per agent, started afresh (zeros) by
``reset(n)``, which a rollout calls first, so it is stateful across calls within an
episode, as :class:`twolink.control.sb3_agent.SB3Agent` is. The header also records the
``challenge`` level and ``action_rate`` the agents trained under (None and 0 if absent).

:func:`load_marl_agent` checks everything before building (size cap :data:`MAX_BYTES`,
schema and version, links and rule, columns in range, the history length and each
agent's recorded observation layout against its columns, the tensors' names and shapes
against the header's sizes, finite weights); a truncated, foreign or inconsistent file
is one :class:`ControllerError` line. torch is imported only here; without it, one line
naming the extra to install.
"""
from __future__ import annotations

import io
import json
import math
import warnings
from pathlib import Path

import numpy as np

from twolink.arm.parameters import LINK_RULES, MAX_LINKS, MIN_LINKS, TABLE_I, links_parameters
from twolink.control.history import MAX_HISTORY, ObservationHistory, history_layout, \
    history_size
from twolink.control.residual import base_of, residual_torques
from twolink.sim.controller import ControllerError

#: File suffix ``resolve_controller`` reads as a multi-agent save.
SUFFIX = ".marl.pt"
#: Schema and version of the header.
SCHEMA, VERSION = "twolink.marl_agent", 1
#: Algorithms a save may name.
ALGOS = ("ippo", "mappo")
#: Activations the policy networks may use (by ``torch.nn`` class name).
ACTIVATIONS = ("Tanh", "ReLU", "ELU")
#: Largest file read (a six-link save of 256x256 policies is about 2 MB).
MAX_BYTES = 64 * 2**20
#: Message of a missing torch.
NEEDS_TORCH = "needs torch: install the marl extras (scripts/install-rl-extras.sh, or pip " \
              "install 'twolink[marl]')"


def _torch():
    try:
        import torch
    except ImportError:
        raise ControllerError(f"a multi-agent agent {NEEDS_TORCH}") from None
    return torch


def policy_net(obs_dim: int, hidden, activation: str = "Tanh"):
    """The policy network of one agent: Linear/activation layers of ``hidden`` sizes, then
    one Linear output (the mean action), as a ``torch.nn.Sequential`` (the layout of the
    tensor names ``0.weight``, ``0.bias``, ``2.weight``, ..)."""
    torch = _torch()
    layers, d = [], obs_dim
    for h in hidden:
        layers += [torch.nn.Linear(d, h), getattr(torch.nn, activation)()]
        d = h
    layers.append(torch.nn.Linear(d, 1))
    return torch.nn.Sequential(*layers)


def obs_dim(angles) -> int:
    """Size of an agent's cos/sin observation of the columns whose angle flags are
    ``angles``."""
    return sum(2 if a else 1 for a in angles)


def agent_observation(x: np.ndarray, columns, angles) -> np.ndarray:
    """One agent's observation of states ``x`` (n, 2N): its columns in order, each angle
    as (cos, sin) (the env's ``observation='cos_sin'``,
    :func:`twolink.envs.multi_agent.agent_observations`)."""
    parts = []
    for c, a in zip(columns, angles):
        v = x[:, c]
        parts += [np.cos(v), np.sin(v)] if a else [v]
    return np.stack(parts, -1)


class MarlController:
    """The decentralized controller of N agents' policies (see the module docstring).
    ``nets``: N ``torch.nn`` modules observation -> mean action; ``columns``/``angles``:
    per agent the state columns it reads and the angle flags; ``tau_max``: (N,);
    ``base``: None, or the base controller (states -> torques) the actions add to;
    ``history``: K, each agent's history length (1: its present observation)."""

    def __init__(self, nets, columns, angles, tau_max, *, name: str = "marl",
                 meta: dict | None = None, base=None, history: int = 1):
        self.nets = list(nets)
        self.columns = [tuple(int(c) for c in cols) for cols in columns]
        self.angles = [tuple(bool(a) for a in flags) for flags in angles]
        self.tau_max = np.asarray(tau_max, dtype=float)
        self.links = len(self.nets)
        self.name = name
        self.meta = dict(meta or {})
        self.base = base
        self.history = int(history)
        self._buffers = None

    def reset(self, n: int) -> None:
        """Start ``n`` rows afresh: with a history K > 1, every agent's buffers of zeros."""
        if self.history > 1:
            self._buffers = [ObservationHistory(int(n), obs_dim(a), 1, self.history)
                             for a in self.angles]

    def __call__(self, x) -> np.ndarray:
        torch = _torch()
        x = np.asarray(x, dtype=np.float64)
        if x.ndim != 2 or x.shape[1] != 2 * self.links:
            raise ControllerError(f"{self.name} drives an arm of {self.links} links; it got "
                                  f"states of shape {x.shape} (give --links {self.links})")
        a = np.empty((len(x), self.links))
        if self.history > 1 and (self._buffers is None or self._buffers[0].rows != len(x)):
            self.reset(len(x))
        with torch.no_grad():
            for i, net in enumerate(self.nets):
                o = agent_observation(x, self.columns[i], self.angles[i])
                if self.history > 1:
                    o = self._buffers[i].observe(o)
                out = net(torch.as_tensor(o, dtype=torch.float32))
                a[:, i] = out.reshape(-1).double().numpy()
                if self.history > 1:
                    self._buffers[i].act(np.clip(a[:, i:i + 1], -1.0, 1.0))
        return residual_torques(self.base, x, a, self.tau_max)


def arm_tau_max(links: int, rule: str | None) -> np.ndarray:
    """tau_max (N,) of the arm: Table I's for two links, :func:`links_parameters`'s beyond."""
    if links == 2:
        return np.asarray(TABLE_I.tau_max, dtype=float)
    return np.asarray(links_parameters(links, rule).tau_max, dtype=float)


def save_marl_agent(path, header: dict, policies: dict) -> Path:
    """Write ``{"header": JSON, "policies": {agent: state_dict}}`` at ``path`` atomically
    (``header`` gets :data:`SCHEMA` and :data:`VERSION`)."""
    from twolink.artifacts import atomic_path

    torch = _torch()
    text = json.dumps(dict(header, schema=SCHEMA, version=VERSION))
    state = {a: {k: v.detach().cpu().clone() for k, v in sd.items()}
             for a, sd in policies.items()}
    with atomic_path(path) as tmp:
        torch.save({"header": text, "policies": state}, tmp)
    return Path(path)


def _bad(path, why: str):
    return ControllerError(f"{path} is not a usable twolink multi-agent save: {why}")


def read_marl_file(path) -> tuple[dict, dict]:
    """(header, policies) of the save at ``path``, checked as data (schema, version,
    size); a one-line ControllerError otherwise."""
    torch = _torch()
    path = Path(path)
    if not path.is_file():
        raise ControllerError(f"no multi-agent save {path}")
    if path.stat().st_size > MAX_BYTES:
        raise _bad(path, f"{path.stat().st_size:,} bytes, more than {MAX_BYTES:,}")
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            obj = torch.load(io.BytesIO(path.read_bytes()), weights_only=True,
                             map_location="cpu")
    except Exception as exc:
        why = " ".join(str(exc).split())[:80]
        raise _bad(path, f"truncated or foreign ({type(exc).__name__}: {why})") from None
    header = None
    if isinstance(obj, dict) and isinstance(obj.get("header"), str) \
            and isinstance(obj.get("policies"), dict):
        try:
            header = json.loads(obj["header"])
        except ValueError:
            header = None
    if not isinstance(header, dict) or header.get("schema") != SCHEMA:
        raise _bad(path, f"no {SCHEMA} header")
    if header.get("version") != VERSION:
        raise _bad(path, f"version {header.get('version')!r}; this twolink reads {VERSION}")
    return header, obj["policies"]


def _check_header(path, h: dict) -> tuple:
    links = h.get("links")
    if not isinstance(links, int) or isinstance(links, bool) or \
            not MIN_LINKS <= links <= MAX_LINKS:
        raise _bad(path, f"links {links!r} (must be {MIN_LINKS} to {MAX_LINKS})")
    rule = h.get("rule")
    if links > 2 and rule not in LINK_RULES:
        raise _bad(path, f"rule {rule!r} (one of {', '.join(LINK_RULES)})")
    if h.get("algo") not in ALGOS:
        raise _bad(path, f"algo {h.get('algo')!r}")
    if h.get("activation") not in ACTIVATIONS:
        raise _bad(path, f"activation {h.get('activation')!r}")
    hidden = h.get("hidden")
    if not isinstance(hidden, list) or not 1 <= len(hidden) <= 8 or not all(
            isinstance(v, int) and not isinstance(v, bool) and 1 <= v <= 4096 for v in hidden):
        raise _bad(path, f"hidden sizes {hidden!r}")
    agents, cols, angles = h.get("agents"), h.get("columns"), h.get("angles")
    if agents != [f"link{i}" for i in range(1, links + 1)]:
        raise _bad(path, f"agents {agents!r} for {links} links")
    if not (isinstance(cols, list) and isinstance(angles, list) and
            len(cols) == len(angles) == links):
        raise _bad(path, "columns and angles must list one entry per agent")
    for c, a in zip(cols, angles):
        if not (isinstance(c, list) and isinstance(a, list) and 1 <= len(c) == len(a)
                and all(isinstance(v, int) and not isinstance(v, bool) and
                        0 <= v < 2 * links for v in c)
                and all(isinstance(f, bool) for f in a)
                and all(not f or v < links for v, f in zip(c, a))):
            raise _bad(path, f"agent columns {c!r} / angles {a!r} out of the {links}-link "
                             f"state")
    k = h.get("history", 1)
    if not isinstance(k, int) or isinstance(k, bool) or not 1 <= k <= MAX_HISTORY:
        raise _bad(path, f"history {k!r} (a whole number of samples from 1 to {MAX_HISTORY})")
    layouts = h.get("observation_layouts")
    if layouts is not None:
        want = [history_layout(k, obs_dim(a), 1) for a in angles]
        if not isinstance(layouts, list) or len(layouts) != links:
            raise _bad(path, "observation_layouts must list one layout per agent")
        for agent, got, w in zip(h["agents"], layouts, want):
            if got != w:
                raise _bad(path, f"{agent}'s observation layout {json.dumps(got)[:80]} is not "
                                 f"that of history {k} over its {w['observation_size']} "
                                 f"observed numbers ({w['size']} numbers)")
    return links, rule if links > 2 else None, hidden, cols, angles, k


def load_marl_agent(path) -> MarlController:
    """The controller of the multi-agent save at ``path`` (see the module docstring)."""
    torch = _torch()
    header, policies = read_marl_file(path)
    links, rule, hidden, cols, angles, k = _check_header(path, header)
    nets = []
    for i, agent in enumerate(header["agents"]):
        sd = policies.get(agent)
        if not isinstance(sd, dict) or not all(isinstance(v, torch.Tensor) for v in sd.values()):
            raise _bad(path, f"no weights of {agent}")
        net = policy_net(history_size(k, obs_dim(angles[i]), 1), hidden, header["activation"])
        try:
            net.load_state_dict(sd, strict=True)
        except RuntimeError as exc:
            first = str(exc).strip().splitlines()
            raise _bad(path, f"weights of {agent} do not fit the header's sizes "
                             f"({' '.join(first[1:2] or first[:1]).strip()[:90]})") from None
        if not all(bool(torch.isfinite(p).all()) for p in net.parameters()):
            raise _bad(path, f"weights of {agent} hold NaN or infinite values")
        net.eval()
        nets.append(net)
    base_name, base = base_of(path, header,
                              TABLE_I if links == 2 else links_parameters(links, rule), "header")
    steps = header.get("steps")
    meta = {"algo": header["algo"], "links": links, "rule": rule, "base": base_name,
            "observe": header.get("observe"), "seed": header.get("seed"),
            "history": k, "challenge": header.get("challenge"),
            "action_rate": header.get("action_rate", 0.0),
            "steps": steps if isinstance(steps, int) and not math.isnan(steps) else None,
            "file": str(path)}
    name = Path(path).name[:-len(SUFFIX)] if str(path).endswith(SUFFIX) else Path(path).stem
    return MarlController(nets, cols, angles, arm_tau_max(links, rule), name=name, meta=meta,
                          base=base, history=k)
