"""What the learners' study runs: arms x learners x seeds, each a ``twolink train`` run.

The study is Table II for today's learners: on each arm of :data:`ARMS` (N = 2..6 tapered
links and copied N = 3, 4) every learner of :data:`LEARNERS` (centralized PPO from
Stable-Baselines3; IPPO and MAPPO from skrl with the ``local`` and ``neighbours``
observation models) is trained with each seed of :data:`SEEDS` for :data:`STEPS` [N]
environment steps, with the hyperparameters ``twolink train`` states once per algorithm
(:mod:`twolink.training.config`, :mod:`twolink.training.marl`): nothing is tuned per arm
or per seed.

:func:`plan` lists the runs cheapest seed first: seed 0 of every row, then seed 1, then
seed 2, and within a seed the arms by size, so a study cut short holds whole seeds of the
small arms first and ``--seeds 0`` is the one-seed version. :data:`SMOKE` is the
end-to-end check CI runs (a few thousand steps, learning quality not judged).

Scoring (:mod:`.measure`): the final agent, never one picked by its curve, on
:data:`POSES` random poses at rest of the scaling table (``random_poses(N, 256, 20061122
+ N)``, the poses of the reach study's ceiling; the training curve reads its first 64)
and on :data:`POSES` fresh poses of seed :data:`FRESH_SEED` + N, which no training, curve
or selection reads: the target is judged on those.
"""
from __future__ import annotations

import dataclasses

from twolink.arm.parameters import LINK_RULES, MAX_LINKS, MIN_LINKS
from twolink.validate import choice, whole

#: The multi-agent observation models (:data:`twolink.training.marl.OBSERVE`).
OBSERVE = ("local", "neighbours", "global")

#: Schema and version of the study's JSON.
SCHEMA, VERSION = "twolink.learners", 1
#: The arms: (links, rule).
ARMS = ((2, "tapered"), (3, "tapered"), (4, "tapered"), (5, "tapered"), (6, "tapered"),
        (3, "copied"), (4, "copied"))
#: The learners: (algo, observe, base, plant); PPO is centralized and observes the whole
#: arm; base ``pd``: the action is a residual over the tuned per-joint PD (``twolink train
#: --base pd``, 3 to 6 links; each joint's PD reads only its own joint, so IPPO/MAPPO over
#: it stay decentralized); plant ``model``: trained on the rigid-body model (6) instead of
#: MuJoCo (``twolink train --plant model``, PPO only), for the transfer gap: every final
#: agent is also scored on the model (:mod:`.measure`).
LEARNERS = (("ppo", "global", "none", "mujoco"), ("ippo", "local", "none", "mujoco"),
            ("ippo", "neighbours", "none", "mujoco"), ("mappo", "local", "none", "mujoco"),
            ("mappo", "neighbours", "none", "mujoco"), ("ppo", "global", "pd", "mujoco"),
            ("ippo", "local", "pd", "mujoco"), ("mappo", "local", "pd", "mujoco"),
            ("ppo", "global", "none", "model"))
#: What a run trains on: ``twolink train --plant``.
TRAIN_PLANTS = ("mujoco", "model")
#: Seeds of the learners and their arms.
SEEDS = (0, 1, 2)
#: Environment steps of a run, by links.
STEPS = {2: 300_000, 3: 600_000, 4: 1_500_000, 5: 2_000_000, 6: 2_000_000}
#: Environment steps between the curve's evaluations (64 poses of the scaling table).
EVAL_EVERY = {2: 50_000, 3: 100_000, 4: 150_000, 5: 200_000, 6: 200_000}
#: Poses the final agent is scored on, per pose set.
POSES = 256
#: The scaling table's pose seed (poses of N links: this + N).
TABLE_SEED = 20061122
#: The fresh poses' seed (this + N): no training run, curve, tuning or selection reads it
#: (the curve's and the table's are 20061122 + N, the per-joint PD's tuning 7100 + N, the
#: leaderboard's 2026).
FRESH_SEED = 4_180_000
#: The smoke plan CI runs: two arms, one step budget of a few updates, few poses.
SMOKE = dict(arms=((2, "tapered"), (3, "tapered")),
             learners=(("ppo", "global", "none", "mujoco"), ("ippo", "local", "none", "mujoco"),
                       ("ippo", "local", "pd", "mujoco"), ("ppo", "global", "none", "model")),
             seeds=(0,), steps=4096, poses=8)


@dataclasses.dataclass(frozen=True)
class Run:
    """One training run of the study."""

    algo: str
    observe: str
    links: int
    rule: str
    seed: int
    steps: int
    eval_every: int
    base: str = "none"
    plant: str = "mujoco"

    @property
    def learner(self) -> str:
        """The learner's name: ``ppo``, ``ippo-local``, ... (``-pd`` over the PD,
        ``-model`` trained on the model)."""
        return learner_id(self.algo, self.observe, self.base, self.plant)

    @property
    def id(self) -> str:
        """The run's name: learner, arm, seed (its folder and its key in the JSON)."""
        return f"{self.learner}_{self.links}{self.rule[0]}_seed{self.seed}"

    @property
    def row(self) -> tuple:
        """The row of the study's table the run belongs to (seeds pooled)."""
        return (self.links, self.rule, self.algo, self.observe, self.base, self.plant)

    def train_args(self) -> list:
        """The ``twolink train`` options of the run."""
        args = ["--algo", self.algo, "--links", str(self.links), "--rule", self.rule,
                "--steps", str(self.steps), "--seed", str(self.seed),
                "--eval-every", str(self.eval_every)]
        if self.algo != "ppo":
            args += ["--observe", self.observe]
        if self.base != "none":
            args += ["--base", self.base]
        if self.plant != "mujoco":
            args += ["--plant", self.plant]
        return args

    def as_dict(self) -> dict:
        return dataclasses.asdict(self)


def plan(*, arms=ARMS, learners=LEARNERS, seeds=SEEDS, steps=None) -> list:
    """The runs of the study, seed by seed, small arms first (see the module docstring);
    ``steps`` overrides :data:`STEPS` (and the evaluation period) for every run."""
    for links, rule in arms:
        whole(links, "links", MIN_LINKS, MAX_LINKS)
        choice(rule, "rule", LINK_RULES)
    for algo, observe, base, plant in learners:
        choice(algo, "algo", ("ppo", "ippo", "mappo"))
        choice(observe, "observe", ("global",) if algo == "ppo" else OBSERVE)
        choice(base, "base", ("none", "pd"))
        choice(plant, "plant", TRAIN_PLANTS if algo == "ppo" else ("mujoco",))
    for s in seeds:
        whole(s, "seed", 0, 2**31 - 1)
    if steps is not None:
        whole(steps, "steps", 1, 10**9)
    runs = []
    for seed in seeds:
        for links, rule in sorted(arms, key=lambda a: (a[0], a[1] != "tapered")):
            for algo, observe, base, plant in learners:
                if base == "pd" and links == 2:        # the PD is tuned for 3 to 6 links
                    continue
                n = steps or STEPS[links]
                runs.append(Run(algo, observe, links, rule, seed, n,
                                steps or EVAL_EVERY[links], base, plant))
    return runs


def learner_id(algo: str, observe: str, base: str = "none", plant: str = "mujoco") -> str:
    """``ppo``, ``ippo-local``, ``mappo-neighbours-pd``, ``ppo-model``...: a learner's name."""
    who = "ppo" if algo == "ppo" else f"{algo}-{observe}"
    return (who + ("" if base == "none" else f"-{base}")
            + ("" if plant == "mujoco" else f"-{plant}"))


def parse_learner(text: str) -> tuple:
    """``ppo``, ``ippo-local``, ``mappo-neighbours-pd``, ``ppo-model``... -> (algo,
    observe, base, plant); one line naming the choices otherwise."""
    names = {learner_id(a, o, b, p): (a, o, b, p) for a in ("ppo", "ippo", "mappo")
             for o in (("global",) if a == "ppo" else OBSERVE) for b in ("none", "pd")
             for p in (TRAIN_PLANTS if a == "ppo" else ("mujoco",))}
    if text not in names:
        raise ValueError(f"unknown learner {text!r}; choose one of {', '.join(names)}")
    return names[text]


def parse_arm(text: str) -> tuple:
    """``6`` (tapered) or ``4copied`` / ``4c`` -> (links, rule); one line otherwise."""
    import re

    m = re.fullmatch(r"(\d+)(t|c|tapered|copied)?", str(text).strip())
    if not m:
        raise ValueError(f"unknown arm {text!r}: give N (tapered) or Nc / Ncopied")
    links = whole(int(m.group(1)), "links", MIN_LINKS, MAX_LINKS)
    rule = {"c": "copied", "copied": "copied"}.get(m.group(2) or "", "tapered")
    if links == 2 and rule == "copied":
        raise ValueError("the two-link arm is Table I's: it has no copied rule")
    return links, rule
