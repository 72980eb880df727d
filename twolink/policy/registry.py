"""The registry of shipped policies: one table that the CLI, reports, tests and README read.

A Q-table is stored once, in ``policies/<stem>.npz`` named by its synthesis settings
(:func:`table_stem` of :meth:`ShippedPolicy.table_options`); policies whose settings differ
only in the read-out share that file (:attr:`ShippedPolicy.table`), and each entry's
read-out is applied when it is loaded (:func:`twolink.policy.fuzzy_policy.load_policy`).

Each entry says how the committed file under ``policies/`` is synthesised (kind (16) or
(18), the model the transitions come from, agent 1's context, the sweeps of Alg. 1:
synchronous as printed for all of them, docs/conventions.md; for the robust ones the worst case over
K parameter draws, their spread and seed) and whether it is one of the paper's policies or
one of ours synthesised on the full model (6).
"""
from __future__ import annotations

import dataclasses
import re
from pathlib import Path
from typing import Optional

from twolink.validate import real, whole


@dataclasses.dataclass(frozen=True)
class ShippedPolicy:
    """One committed policy: its name, how it is synthesised and what it stands for."""

    name: str
    kind: str                       # "centralized" (16) or "decentralized" (18)
    model: str                      # synthesis model: "simplified" (11) or "full" (6)
    context: Optional[str]          # agent 1's context, decentralized only
    paper: bool                     # one of the paper's policies (synthesised on (11))
    description: str
    sweeps: str = "synchronous"     # Alg. 1's sweeps (twolink.synthesis.problems.SWEEPS)
    robust: Optional[str] = None    # robust synthesis: "worst" or "mean" over the draws
    draws: int = 1                  # K models: the centre and K - 1 joint draws
    spread: float = 0.0             # each physical parameter uniform in +-spread (relative)
    seed: int = 0                   # seed of the draws (twolink.synthesis.problems.parameter_draws)
    links: int = 2                  # links of the arm (arm.parameters.links_parameters beyond 2)
    rule: str = "tapered"           # how links beyond the second are made (links > 2 only)
    levels: int = 3                 # torque levels per joint (twolink.arm.task.action_levels)
    bins: str = "paper"             # bin layout (twolink.fqi.fuzzy.BIN_LAYOUTS)
    speed_dead_zone: float = 0.0    # read-out dead zone on the speeds, rad/s (policy.readout)
    argmax_beyond_deg: Optional[float] = None  # read-out: argmax of Q beyond this angle
    near_gain: float = 1.0          # read-out: torque gain at the goal (1: off)
    near_deg: Optional[float] = None  # read-out: the angle (deg) of full torque again
    agent2_link1: str = "free"      # agent 2's reading of link 1 (problems.LINK1_READINGS)
    tuned: bool = False             # a design chosen on tuning seeds (TUNING_SEEDS)

    @property
    def table(self) -> str:
        """The name of this entry's stored Q-tables: :func:`table_stem` of
        :meth:`table_options`, the stem of its committed file. Entries that differ only in
        their read-out have the same table and share one file; the read-out is each
        entry's data (:meth:`readout`)."""
        return table_stem(self.table_options())

    @property
    def table_owner(self) -> str:
        """The first entry of :data:`SHIPPED` with this one's :attr:`table`: the entry whose
        settings, read-out included, the committed file's header records (what ``twolink
        synthesize --ship`` synthesises for the table)."""
        mine = self.table
        return next(p.name for p in SHIPPED.values() if p.table == mine)

    @property
    def file(self) -> Path:
        """The committed file of :attr:`table`: ``policies/<table>.npz`` (the Q-tables;
        its read-out is :attr:`table_owner`'s)."""
        from twolink.resources import shipped_policy_dir
        return shipped_policy_dir() / f"{self.table}.npz"

    def readout(self):
        """This entry's read-out (:class:`twolink.policy.readout.Readout`; off when it
        names none)."""
        from twolink.policy.readout import Readout
        return self.synthesis_options().get("readout", Readout())

    def table_options(self) -> dict:
        """:meth:`synthesis_options` without the read-out: what the Q-tables depend on."""
        opts = self.synthesis_options()
        opts.pop("readout", None)
        return {"kind": self.kind, "links": self.links, **opts}

    def synthesis_options(self) -> dict:
        """Keyword arguments of :func:`twolink.synthesis.synthesize.synthesize` that rebuild it."""
        opts = {"model": self.model, "sweeps": self.sweeps}
        if self.context is not None:
            opts["context"] = self.context
        if self.robust is not None:
            opts.update(robust=self.robust, draws=self.draws, spread=self.spread,
                        seed=self.seed)
        if self.links > 2:
            opts.update(links=self.links, rule=self.rule)
        if self.levels != 3:
            opts["levels"] = self.levels
        if self.bins != "paper":
            opts["bins"] = self.bins
        if self.agent2_link1 != "free":
            opts["agent2_link1"] = self.agent2_link1
        if self.speed_dead_zone or self.argmax_beyond_deg is not None or self.near_gain < 1:
            from twolink.policy.readout import Readout
            opts["readout"] = Readout(speed_dead_zone=self.speed_dead_zone,
                                      argmax_beyond_deg=self.argmax_beyond_deg,
                                      near_gain=self.near_gain, near_deg=self.near_deg)
        return opts


#: The synthesis settings a stored Q-table depends on (the keys of
#: :meth:`ShippedPolicy.table_options`), with their defaults: the entry's.
#: kind and model have none (required); agent 1's context is None unless decentralized.
_TABLE_DEFAULTS = {f.name: None if f.default is dataclasses.MISSING else f.default
                   for f in dataclasses.fields(ShippedPolicy)
                   if f.name in ("kind", "model", "context", "sweeps", "robust", "draws",
                                 "spread", "seed", "links", "rule", "levels", "bins",
                                 "agent2_link1")}
#: The settings that may be None: the context (centralized) and robust (not robust).
_OPTIONAL = ("context", "robust")
_WORD = re.compile(r"[a-z]+")


def table_stem(options: dict) -> str:
    """The file stem of the Q-tables synthesised with ``options`` (the settings of
    :meth:`ShippedPolicy.table_options`; a setting left out or at its default is not
    named)::

        <kind>_<model>[_<context>][_<links><rule>][_<sweeps>]
            [_<robust><draws>-<spread>-seed<seed>][_levels<L>][_bins-<layout>][_link1-<reading>]

    ``context`` is agent 1's (decentralized only, always named); ``<links><rule>`` beyond
    two links (``3tapered``); ``<sweeps>`` when not synchronous; the robust part when
    robust (``<spread>`` as Python writes the float); ``levels<L>`` when not three torque
    levels per joint; ``bins-<layout>`` when not the paper's bins; ``link1-<reading>`` when
    agent 2 does not read link 1 free. E.g. ``centralized_simplified``,
    ``decentralized_full_propagated_3tapered``, ``centralized_full_worst8-0.2-seed2006``,
    ``centralized_full_levels5_bins-goal``.

    Every word setting is lowercase letters only, so each part has its own shape and the
    stem is unique per distinct settings. A setting that is unknown, missing (kind, model;
    context of the decentralized agents), out of place (a context of the centralized
    policy, draws/spread/seed without robust, a rule of two links) or not of the
    grammar's form is one ValueError line."""
    if not isinstance(options, dict):
        raise ValueError(f"table settings must be a dict, got {type(options).__name__}")
    unknown = sorted(set(map(str, options)) - set(_TABLE_DEFAULTS))
    if unknown:
        raise ValueError(f"unknown table setting(s) {', '.join(unknown)}; known: "
                         f"{', '.join(_TABLE_DEFAULTS)}")
    o = {**_TABLE_DEFAULTS, **options}
    for key in ("kind", "model", "context", "sweeps", "robust", "rule", "bins",
                "agent2_link1"):
        value = o[key]
        if value is None and key in ("kind", "model"):
            raise ValueError(f"table settings need a {key}")
        if not (isinstance(value, str) and _WORD.fullmatch(value)
                or value is None and key in _OPTIONAL):
            raise ValueError(f"table setting {key} must be a word of lowercase letters, "
                             f"got {value!r}")
    if (o["kind"] == "decentralized") != (o["context"] is not None):
        raise ValueError(f"agent 1's context names the decentralized agents' tables, and "
                         f"only theirs: kind {o['kind']!r} with context {o['context']!r}")
    links = whole(o["links"], "links", 2)
    levels = whole(o["levels"], "levels", 2)
    parts = [o["kind"], o["model"]] + ([o["context"]] if o["context"] else [])
    if links > 2:
        parts.append(f"{links}{o['rule']}")
    elif o["rule"] != _TABLE_DEFAULTS["rule"]:
        raise ValueError(f"rule makes the links beyond the second; two links take none "
                         f"(got {o['rule']!r})")
    if o["sweeps"] != _TABLE_DEFAULTS["sweeps"]:
        parts.append(o["sweeps"])
    if o["robust"] is not None:
        parts.append(f"{o['robust']}{whole(o['draws'], 'draws', 1)}-"
                     f"{real(o['spread'], 'spread', 0.0)!r}-seed{whole(o['seed'], 'seed', 0)}")
    elif (o["draws"], o["spread"], o["seed"]) != tuple(_TABLE_DEFAULTS[k] for k in
                                                       ("draws", "spread", "seed")):
        raise ValueError("draws, spread and seed name a robust table only: give robust too")
    if levels != _TABLE_DEFAULTS["levels"]:
        parts.append(f"levels{levels}")
    if o["bins"] != _TABLE_DEFAULTS["bins"]:
        parts.append(f"bins-{o['bins']}")
    if o["agent2_link1"] != _TABLE_DEFAULTS["agent2_link1"]:
        parts.append(f"link1-{o['agent2_link1']}")
    return "_".join(parts)


#: The seed of the shipped robust policies' parameter draws (fixed before any evaluation).
ROBUST_SEED = 2006

#: Seeds the tuned designs were chosen on (docs/studies/fuzzy_design.py): poses
#: ``random_poses(2, 48, seed=9301)``, plants, noise and faults from 9302. No figure is
#: reported on them.
TUNING_SEEDS = (9301, 9302)

#: Every shipped policy, in report order: the paper's three, the two on (6), the two
#: robust ones (worst case over K = 8 models within +-20 %, on (6)), the three-link
#: agents, then the tuned designs (more torque levels, other bins, a read-out dead zone),
#: among them designs on the edge bins (:data:`twolink.fqi.fuzzy.EDGE_ANGLE_BINS_DEG`) and
#: with agent 2 holding joint 1 (``agent2_link1="locked"``).
SHIPPED = {p.name: p for p in (
    ShippedPolicy("centralized", "centralized", "simplified", None, True,
                  "the centralized policy (16) on the simplified model (11)"),
    ShippedPolicy("decentralized", "decentralized", "simplified", "frozen", True,
                  "the decentralized agents (18) on (11), agent 1 with a frozen context"),
    ShippedPolicy("decentralized_propagated", "decentralized", "simplified", "propagated", True,
                  "the decentralized agents (18) on (11), agent 1 with a propagated context"),
    ShippedPolicy("centralized_full", "centralized", "full", None, False,
                  "the centralized policy (16) synthesised on the full model (6)"),
    ShippedPolicy("decentralized_full", "decentralized", "full", "frozen", False,
                  "the decentralized agents (18) synthesised on (6), frozen context"),
    ShippedPolicy("centralized_robust", "centralized", "full", None, False,
                  "the centralized policy (16) on (6), worst case over 8 models within "
                  "+-20 % (all physical parameters jointly)",
                  robust="worst", draws=8, spread=0.2, seed=ROBUST_SEED),
    ShippedPolicy("decentralized_robust", "decentralized", "full", "frozen", False,
                  "the decentralized agents (18) on (6), each the worst case over 8 models "
                  "within +-20 %, frozen context",
                  robust="worst", draws=8, spread=0.2, seed=ROBUST_SEED),
    ShippedPolicy("decentralized_3link", "decentralized", "full", "propagated", False,
                  "one agent per joint of the three-link tapered arm (twolink.synthesis.links_decentralized) "
                  "on its full model: the middle agent holds joint 1, propagated context "
                  "with the neighbour's speed", links=3, rule="tapered"),
    ShippedPolicy("centralized_tuned", "centralized", "full", None, False,
                  "the centralized policy (16) on (6) with 5 torque levels per joint, bins "
                  "concentrated at the goal band, a 0.08 rad/s dead zone on the speed "
                  "readings and the argmax of Q beyond 30 deg", levels=5, bins="goal",
                  speed_dead_zone=0.08, argmax_beyond_deg=30.0, tuned=True),
    ShippedPolicy("decentralized_tuned", "decentralized", "full", "propagated", False,
                  "the decentralized agents (18) on (6) with 7 torque levels per joint, "
                  "propagated context, a 0.06 rad/s dead zone on the speed readings and "
                  "the argmax of Q beyond 30 deg", levels=7, speed_dead_zone=0.06,
                  argmax_beyond_deg=30.0, tuned=True),
    ShippedPolicy("centralized_robust_tuned", "centralized", "full", None, False,
                  "centralized_robust's synthesis (worst case over 8 models within +-20 %) "
                  "read through a 0.04 rad/s dead zone on the speeds and the argmax of Q "
                  "beyond 30 deg", robust="worst", draws=8, spread=0.2, seed=ROBUST_SEED,
                  speed_dead_zone=0.04, argmax_beyond_deg=30.0, tuned=True),
    ShippedPolicy("centralized_robust_edge", "centralized", "full", None, False,
                  "centralized_robust_tuned's design on the edge bins (no bin centre on the "
                  "goal band's edge: 4 and 9 deg around it, the paper's angle bins halved "
                  "elsewhere)", robust="worst", draws=8, spread=0.2, seed=ROBUST_SEED,
                  bins="edge", speed_dead_zone=0.04, argmax_beyond_deg=30.0, tuned=True),
    ShippedPolicy("decentralized_edge", "decentralized", "full", "propagated", False,
                  "decentralized_tuned's design on the edge bins (no bin centre on the goal "
                  "band's edge: 4 and 9 deg around it, the paper's angle bins halved "
                  "elsewhere)", levels=7, bins="edge", speed_dead_zone=0.06,
                  argmax_beyond_deg=30.0, tuned=True),
    ShippedPolicy("centralized_9levels", "centralized", "full", None, False,
                  "the centralized policy (16) on (6) with 9 torque levels per joint, bins "
                  "concentrated at the goal band, a 0.04 rad/s dead zone on the speed "
                  "readings and the argmax of Q beyond 45 deg", levels=9, bins="goal",
                  speed_dead_zone=0.04, argmax_beyond_deg=45.0, tuned=True),
    ShippedPolicy("decentralized_edge_locked", "decentralized", "full", "propagated", False,
                  "the decentralized agents (18) on (6) with 7 torque levels per joint on "
                  "the edge bins, agent 2's transitions holding joint 1 fixed, propagated "
                  "context, a 0.02 rad/s dead zone on the speed readings and the argmax of "
                  "Q beyond 30 deg", levels=7, bins="edge", agent2_link1="locked",
                  speed_dead_zone=0.02, argmax_beyond_deg=30.0, tuned=True),
    ShippedPolicy("decentralized_locked", "decentralized", "full", "propagated", False,
                  "decentralized_tuned's design with agent 2's transitions holding joint 1 "
                  "fixed and a 0.1 rad/s dead zone on the speed readings",
                  levels=7, agent2_link1="locked", speed_dead_zone=0.1,
                  argmax_beyond_deg=30.0, tuned=True),
    ShippedPolicy("decentralized_edge_gain", "decentralized", "full", "propagated", False,
                  "decentralized_edge with the near-goal gain docs/studies/near_gain.py "
                  "chose on the tuning seeds: joint i's torque falls from full at 90 deg to "
                  "0.2 times (14)'s at the goal", levels=7, bins="edge",
                  speed_dead_zone=0.06, argmax_beyond_deg=30.0, near_gain=0.2,
                  near_deg=90.0, tuned=True),
    ShippedPolicy("decentralized_edge_locked_gain", "decentralized", "full", "propagated",
                  False, "decentralized_edge_locked read through the fading gain "
                  "docs/studies/joint_handover.py chose as the hold of "
                  "decentralized_handover on the tuning seeds: joint i's torque falls from "
                  "full at 180 deg to 0.2 times (14)'s at the goal",
                  levels=7, bins="edge", agent2_link1="locked", speed_dead_zone=0.02,
                  argmax_beyond_deg=30.0, near_gain=0.2, near_deg=180.0, tuned=True),
    ShippedPolicy("decentralized_locked_gain", "decentralized", "full", "propagated", False,
                  "decentralized_locked with the near-goal gain docs/studies/near_gain.py "
                  "chose on the tuning seeds: joint i's torque falls from full at 60 deg to "
                  "0.3 times (14)'s at the goal", levels=7, agent2_link1="locked",
                  speed_dead_zone=0.1, argmax_beyond_deg=30.0, near_gain=0.3, near_deg=60.0,
                  tuned=True),
    ShippedPolicy("decentralized_edge_gain_hard", "decentralized", "full", "propagated",
                  False, "decentralized_edge with the near-goal gain docs/studies/near_gain.py "
                  "chose for the hard level with compensation on the tuning seeds: joint "
                  "i's torque falls from full at 180 deg to 0.5 times (14)'s at the goal",
                  levels=7, bins="edge", speed_dead_zone=0.06, argmax_beyond_deg=30.0,
                  near_gain=0.5, near_deg=180.0, tuned=True),
    ShippedPolicy("decentralized_locked_gain_medium", "decentralized", "full", "propagated",
                  False, "decentralized_locked with the near-goal gain "
                  "docs/studies/near_gain.py chose for the medium level without "
                  "compensation on the tuning seeds (48 poses x 32 plants): joint i's "
                  "torque falls from full at 60 deg to 0.5 times (14)'s at the goal",
                  levels=7, agent2_link1="locked", speed_dead_zone=0.1,
                  argmax_beyond_deg=30.0, near_gain=0.5, near_deg=60.0, tuned=True),
    ShippedPolicy("centralized_robust_edge_gain_medium", "centralized", "full", None, False,
                  "centralized_robust_edge with the near-goal gain docs/studies/near_gain.py "
                  "chose for the medium level without compensation on the tuning seeds (48 "
                  "poses x 32 plants): joint i's torque falls from full at 60 deg to 0.2 "
                  "times (14)'s at the goal", robust="worst", draws=8, spread=0.2,
                  seed=ROBUST_SEED, bins="edge", speed_dead_zone=0.04,
                  argmax_beyond_deg=30.0, near_gain=0.2, near_deg=60.0, tuned=True),
    ShippedPolicy("centralized_robust_edge_gain", "centralized", "full", None, False,
                  "centralized_robust_edge with the near-goal gain docs/studies/near_gain.py "
                  "chose on the tuning seeds: joint i's torque falls from full at 90 deg to "
                  "0.1 times (14)'s at the goal", robust="worst", draws=8, spread=0.2,
                  seed=ROBUST_SEED, bins="edge", speed_dead_zone=0.04,
                  argmax_beyond_deg=30.0, near_gain=0.1, near_deg=90.0, tuned=True),
)}
#: The shipped policies of the paper's two-link arm (what two-link reports iterate over).
TWO_LINK = tuple(n for n, p in SHIPPED.items() if p.links == 2)
#: The paper's policies (synthesised on (11)).
PAPER_POLICIES = tuple(n for n, p in SHIPPED.items() if p.paper)
#: The two-link policies of the paper's designs (three levels, the paper's bins), which
#: the mismatch report studies by default.
PAPER_DESIGNS = tuple(n for n in TWO_LINK if not SHIPPED[n].tuned)
#: Which policy synthesised on (6) answers which paper policy.
COUNTERPART = {"centralized": "centralized_full", "decentralized": "decentralized_full",
               "decentralized_propagated": "decentralized_full"}


def shipped(name: str) -> ShippedPolicy:
    """The registry entry ``name``, or a ValueError listing the names."""
    try:
        return SHIPPED[name]
    except KeyError:
        raise ValueError(f"unknown shipped policy {name!r}; shipped policies: "
                         f"{', '.join(SHIPPED)}") from None
