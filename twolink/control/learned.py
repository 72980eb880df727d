"""The learned agents shipped in the repository, by name.

:data:`LEARNED` holds each one: its file, a path relative to the repository root (a
source checkout's ``renders/``; a wheel does not hold them), whether it is centralized (a
Stable-Baselines3 save, :class:`twolink.control.sb3_agent.SB3Agent`) or decentralized (an
IPPO/MAPPO ``.marl.pt``, :class:`twolink.control.marl_agent.MarlController`), its arm
(links, rule) and what it is. :data:`LEARNED_AGENTS` is the name -> file view.
:func:`twolink.control.controllers.resolve_controller` accepts these names, so
``twolink evaluate ppo_medium`` runs the committed agent. No command loads a saved agent that it was
not given by name or path: the leaderboard's default rows hold the agents of this table
whose file exists (:func:`default_learned_agents`), never a folder's ``*.zip``.
"""
from __future__ import annotations

import dataclasses
from pathlib import Path

from twolink.sim.controller import ControllerError


@dataclasses.dataclass(frozen=True)
class Learned:
    """A shipped learned agent: its file (relative to the repository root), kind, arm and
    what it is."""

    path: str
    kind: str = "centralized"
    links: int = 2
    rule: str | None = None
    description: str = ""
    #: The learning-curve JSONs of every seed trained for this entry (``twolink train``'s
    #: ``*.json``, relative to the repository root), the chosen one among them.
    curves: tuple = ()


#: The Stable-Baselines3 learners of ``docs/studies/challenge_agents.py``, by file prefix.
CHALLENGE_ALGOS = {"ppo": "PPO", "sac": "SAC"}


#: How the entries' names spell what they were trained under (``mixed``: the study's
#: ``--levels mixed``).
TRAINED_UNDER = {"medium": "under medium", "hard": "under hard",
                 "mixed": "under none, medium and hard side by side (--challenge "
                          "none+medium+hard) on the shaped_time reward"}


#: The action gain (``twolink train --action-gain``, :mod:`twolink.control.action_gain`)
#: of the study's mixed runs, by algorithm (absent: 1): SAC's squashed actions stay off
#: the torque limit without one. ``docs/studies/challenge_agents.py`` trains with it.
MIXED_GAIN = {"sac": 1.3}


def challenge_stem(algo: str, level: str) -> str:
    """The name of the study's runs of ``algo`` under ``level`` before ``_seed<S>``:
    ``<algo>_<level>``, with ``_ag<G>`` for a mixed run with an action gain
    (:data:`MIXED_GAIN`)."""
    gain = f"_ag{MIXED_GAIN[algo]:g}" if level == "mixed" and algo in MIXED_GAIN else ""
    return f"{algo}_{level}{gain}"


def _challenge(algo: str, level: str) -> Learned:
    """The ``algo`` agent of ``docs/studies/challenge_agents.py`` for ``level``: seeds 1-3
    trained, the best on the training side's plants shipped."""
    gain = (f", action gain {MIXED_GAIN[algo]:g}"
            if level == "mixed" and algo in MIXED_GAIN else "")
    return Learned(f"renders/challenge_agents/{algo}_{level}.zip",
                   description=f"{CHALLENGE_ALGOS[algo]} trained {TRAINED_UNDER[level]}: "
                               f"history 3, action rate 1{gain}, the best of seeds 1-3 on "
                               f"training plants (docs/studies/challenge_agents.py)",
                   curves=tuple(f"renders/challenge_agents/{challenge_stem(algo, level)}"
                                f"_seed{s}.json" for s in (1, 2, 3)))


#: The shipped learned agents, by name.
LEARNED = {
    "ppo_seed0": Learned("renders/deep_rl/ppo_seed0.zip",
                         description="PPO trained on the nominal arm (renders/deep_rl/)"),
    **{f"{algo}_{level}": _challenge(algo, level)
       for algo in CHALLENGE_ALGOS for level in ("medium", "hard")},
    **{f"{algo}_mixed": _challenge(algo, "mixed") for algo in CHALLENGE_ALGOS},
    "ippo_medium": Learned(
        "renders/challenge_agents/ippo_medium.marl.pt", kind="decentralized",
        description="IPPO trained under medium: one agent per joint reading only its own "
                    "joint (local), history 3, action rate 1, policy noise held at 0.2 or "
                    "more (--std-floor), the best of seeds 1-3 on training plants "
                    "(docs/studies/challenge_agents.py)",
        curves=tuple(f"renders/challenge_agents/ippo_medium_seed{s}.json" for s in (1, 2, 3))),
    "ippo_mixed": Learned(
        "renders/challenge_agents/ippo_mixed.marl.pt", kind="decentralized",
        description="IPPO trained under none, medium and hard side by side (--challenge "
                    "none+medium+hard): one agent per joint reading only its own joint "
                    "(local), history 3, action rate 1, policy noise held at 0.2 or more "
                    "(--std-floor), the best of seeds 1-3 on training plants "
                    "(docs/studies/challenge_agents.py)",
        curves=tuple(f"renders/challenge_agents/ippo_mixed_seed{s}.json" for s in (1, 2, 3))),
    "mappo_local_medium": Learned(
        "renders/challenge_agents/mappo_local_medium.marl.pt", kind="decentralized",
        description="MAPPO trained under medium: one actor per joint reading only its own "
                    "joint (local; the critics see the whole arm while training), history 3, "
                    "action rate 1, policy noise held at 0.2 or more (--std-floor), the best "
                    "of seeds 1-3 on training plants (docs/studies/challenge_agents.py)",
        curves=tuple(f"renders/challenge_agents/mappo_local_medium_seed{s}.json"
                     for s in (1, 2, 3))),
    "mappo_medium": Learned(
        "renders/challenge_agents/mappo_medium.marl.pt", kind="decentralized",
        description="MAPPO trained under medium: one actor per joint, each observing the whole "
                    "arm (global), history 3, action rate 1, the best of seeds 1-3 on training "
                    "plants (local observations did not learn: the training guide)",
        curves=tuple(f"renders/challenge_agents/mappo_2links_global_medium_h3_ar1_seed{s}.json"
                     for s in ("1", "2", "3_steps1.2e6"))),
    "ppo_pd_6link_tapered": Learned(
        "renders/learners/agents/ppo_pd_6link_tapered.zip", links=6, rule="tapered",
        description="PPO as a residual over the per-joint PD on 6 tapered links, the "
                    "learners study's ppo-pd recipe, seed 0, 2 M steps (twolink train --base pd)",
        curves=("renders/learners/agents/ppo_pd_6link_tapered.json",)),
    "mappo_4link_copied": Learned(
        "renders/learners/agents/mappo_4link_copied.marl.pt", kind="decentralized", links=4,
        rule="copied",
        description="MAPPO on 4 copied links, one actor per joint reading its own and the "
                    "next joint (neighbours), 6 M steps: seed 1, the better final curve "
                    "point of seeds 0, 1 and 2 (the learners page's lever runs "
                    "mappo-neighbours-6m_4c)",
        curves=tuple(f"renders/learners/levers/mappo-neighbours-6m_4c_seed{s}.json"
                     for s in (0, 1, 2))),
    "mappo_6link_tapered": Learned(
        "renders/learners/agents/mappo_6link_tapered.marl.pt", kind="decentralized", links=6,
        rule="tapered",
        description="MAPPO on 6 tapered links, one actor per joint reading its own and the "
                    "next joint (neighbours), policy noise held at 0.2 or more "
                    "(--std-floor 0.2), 2 M steps: seed 0, the best final curve point of "
                    "seeds 0, 1 and 2 (tied with seed 2; the lower seed; the learners "
                    "page's lever runs mappo-neighbours-sf0.2_6t)",
        curves=tuple(f"renders/learners/levers/mappo-neighbours-sf0.2_6t_seed{s}.json"
                     for s in (0, 1, 2))),
}
#: Name -> the agent's file, relative to the repository root.
LEARNED_AGENTS = {name: a.path for name, a in LEARNED.items()}


def learned_agent_names() -> tuple:
    """The names of :data:`LEARNED_AGENTS`."""
    return tuple(LEARNED_AGENTS)


def _file_of(name: str) -> Path | None:
    """The file of the learned agent ``name`` in the source checkout, or None when the
    package runs without one or the file is missing."""
    from twolink.resources import source_checkout

    root = source_checkout()
    if root is None:
        return None
    path = root / LEARNED_AGENTS[name]
    return path if path.is_file() else None


def learned_agent_path(name: str) -> Path:
    """The file of the learned agent ``name`` (:data:`LEARNED_AGENTS`), resolved against
    the repository root; a one-line ControllerError for an unknown name or a missing file."""
    if name not in LEARNED_AGENTS:
        raise ControllerError(f"unknown learned agent {name!r}; the shipped ones are "
                              f"{', '.join(LEARNED_AGENTS)}")
    path = _file_of(name)
    if path is None:
        from twolink.resources import source_checkout

        if source_checkout() is not None:
            raise ControllerError(f"learned agent {name}: its file {LEARNED_AGENTS[name]} is "
                                  f"missing from this checkout")
        raise ControllerError(f"learned agent {name} is the file {LEARNED_AGENTS[name]} of a "
                              f"source checkout of the repository, and this one has none")
    return path


def learned_agent(name: str):
    """The controller of the learned agent ``name`` (an SB3 save's
    :class:`~twolink.control.sb3_agent.SB3Agent` or a ``.marl.pt``'s
    :class:`~twolink.control.marl_agent.MarlController`), labelled ``name``."""
    path = learned_agent_path(name)
    if path.name.endswith(".marl.pt"):
        from twolink.control.marl_agent import load_marl_agent

        agent = load_marl_agent(path)
        agent.name = name
        return agent
    from twolink.control.sb3_agent import sb3_agent

    return sb3_agent(path, name)


def default_learned_agents(exclude=()) -> list:
    """The learned agents a default leaderboard runs: the names of :data:`LEARNED_AGENTS`
    whose file exists, where Stable-Baselines3 imports (none otherwise, silently). A name
    in ``exclude``, or whose file an ``exclude`` ``.zip`` path names, is left out."""
    present = [n for n, a in LEARNED.items() if a.links == 2 and _file_of(n) is not None]
    if not present:
        return []
    try:
        import stable_baselines3  # noqa: F401
    except ImportError:
        return []
    given = {str(Path(s).resolve()) for s in exclude if isinstance(s, str) and s.endswith(".zip")}
    return [n for n in present
            if n not in exclude and str(_file_of(n).resolve()) not in given]


def learning_cost(name: str) -> dict | None:
    """What learning the shipped agent ``name`` cost, from its curves (:attr:`Learned.curves`,
    ``twolink train``'s JSON of each seed): ``seeds`` (each seed's environment steps, CPU
    and wall seconds, successes of n on its curve's evaluation of the seed's candidate:
    its best point where the run kept a best agent, else its final one), the totals over the
    seeds (every seed trained is paid for, not only the chosen one) and ``chosen_seed``
    (the seed of the agent file, read from its ``twolink.json``). None when the entry has no
    curves or a file is missing (a wheel); a curve that is not ``twolink train``'s is a
    one-line ControllerError."""
    import json

    from twolink.resources import source_checkout

    entry, root = LEARNED.get(name), source_checkout()
    if entry is None or not entry.curves or root is None:
        return None
    seeds = []
    for rel in entry.curves:
        path = root / rel
        if not path.is_file():
            return None
        try:
            d = json.loads(path.read_text())
            pick = d.get("best") or d["curve"][-1]      # the seed's candidate's score
            seeds.append({"seed": int(d["config"]["seed"]), "steps": int(d["steps"]),
                          "cpu_s": float(d["cpu_s"]), "wall_s": float(d["wall_s"]),
                          "successes": int(pick["successes"]), "n": int(pick["n"])})
        except (ValueError, KeyError, IndexError, TypeError) as exc:
            raise ControllerError(f"learned agent {name}: {rel} is not a twolink train "
                                  f"curve ({type(exc).__name__}: {exc})") from None
    chosen = None
    agent = _file_of(name)
    if agent is not None and agent.name.endswith(".marl.pt"):
        from twolink.control.marl_agent import read_marl_file

        chosen = read_marl_file(agent)[0].get("seed")
    elif agent is not None and agent.suffix == ".zip":
        from twolink.control.agent_meta import AGENT_MEMBER
        from twolink.control.sb3_agent import read_save

        raw = read_save(agent, members=(), optional=(AGENT_MEMBER,)).get(AGENT_MEMBER)
        chosen = json.loads(raw).get("seed") if raw else None
    return {"seeds": seeds, "steps": sum(s["steps"] for s in seeds),
            "cpu_s": sum(s["cpu_s"] for s in seeds), "wall_s": sum(s["wall_s"] for s in seeds),
            "chosen_seed": chosen}
