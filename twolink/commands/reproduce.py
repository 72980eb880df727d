"""``twolink reproduce``: the paper's experiment end to end, beside the paper's figures.

Synthesises the centralized policy and the decentralized agents (both readings of agent
1's context) on the simplified model (11), runs them from x0 = [-1, -3, 0, 0] on the
simplified plant and on MuJoCo, prints the comparison table and writes the Fig. 3
counterpart under renders/.
"""
from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np

from twolink import dynamics, paper
from twolink.integrate import SUBSTEPS, integration_error
from twolink.artifacts import provenance, write_json
from twolink.resources import output_dir
from twolink.metrics import evaluation_set, stalled_at_band_edge, success, summary
from twolink.parameters import HORIZON, PAPER_X0, TABLE_I
from twolink.plants import make_plant
from twolink.plots import fig3
from twolink.policy import Policy
from twolink.registry import SHIPPED
from twolink.rollout import rollout
from twolink.synthesis import centralized_problem, synthesize

_VARIANTS = (("centralized", "centralized", "frozen"),
             ("decentralized", "decentralized", "frozen"),
             ("decentralized_propagated", "decentralized", "propagated"))
_PLANTS = ("simplified", "mujoco")


def add_parser(sub):
    p = sub.add_parser("reproduce", help="reproduce the paper's experiment (the main job)",
                       description=__doc__.split("\n\n")[1].replace("\n", " "))
    p.add_argument("--duration", type=float, default=HORIZON,
                   help=f"rollout horizon in seconds (default {HORIZON})")
    p.add_argument("--figure", type=Path, default=None,
                   help="Fig. 3 counterpart to write (default renders/fig3.png)")
    p.add_argument("--report", type=Path, default=None, help="also write the JSON report here")
    p.add_argument("--json", action="store_true", help="print the report as JSON")
    return p


def _shipped_matches(name: str, policy: Policy) -> bool | None:
    path = SHIPPED[name].file
    if not path.is_file():
        return None
    shipped = Policy.load(path)
    return len(shipped.agents) == len(policy.agents) and all(
        np.array_equal(a.q, b.q) for a, b in zip(shipped.agents, policy.agents))


#: RK4 substeps of the fine reference the chosen SUBSTEPS are compared against.
REFERENCE_SUBSTEPS = 100


def integration_report() -> dict:
    """One-step error of SUBSTEPS RK4 substeps against REFERENCE_SUBSTEPS, for both numpy
    models, over every centralized bin centre and joint action (63504 transitions)."""
    prob = centralized_problem(TABLE_I)
    x = prob.grid.centers()[:, None, :]
    u = prob.actions[None, :, :]
    return {name: integration_error(dynamics.MODELS[name], TABLE_I, x, u, substeps=SUBSTEPS,
                                    reference_substeps=REFERENCE_SUBSTEPS)
            for name in ("simplified", "full")}


def reproduce(duration: float = HORIZON, *, progress: bool = True) -> tuple[dict, dict]:
    """Run the experiment; returns the JSON-ready report and the trajectories."""
    x0 = np.asarray(PAPER_X0)
    report = {"x0": list(PAPER_X0), "duration": duration, "synthesis": {}, "rollouts": {},
              "evaluation_set": {},
              "paper": {"iterations": paper.ITERATIONS, "q_sizes": paper.Q_SIZES,
                        "cpu_seconds": paper.CPU_SECONDS, "settle_time": paper.SETTLE_TIME},
              "provenance": provenance()}
    trajs = {}
    report["integration_error"] = integration_report()
    for name, kind, context in _VARIANTS:
        policy = synthesize(kind, TABLE_I, context=context, progress=progress)
        report["synthesis"][name] = {
            "agents": {a.name: {k: a.info[k] for k in ("q_size", "iterations", "seconds",
                                                       "cpu_seconds", "transition_seconds",
                                                       "sweep_seconds")}
                       for a in policy.agents},
            "matches_shipped_policy": _shipped_matches(name, policy)}
        report["rollouts"][name] = {}
        report["evaluation_set"][name] = {}
        for plant_name in _PLANTS:
            plant = make_plant(plant_name)
            tr = rollout(policy, plant, x0, duration=duration)
            report["rollouts"][name][plant_name] = summary(tr)
            trajs[(name, plant_name)] = tr
            ev = rollout(policy, plant, evaluation_set(), duration=duration)
            ok, stalled = success(ev), stalled_at_band_edge(ev)
            report["evaluation_set"][name][plant_name] = {
                "states": int(len(ok)), "success_rate": float(ok.mean()),
                "failures": int((~ok).sum()),
                "failures_stalled_at_band_edge": int(stalled.sum())}
    return report, trajs


def _fmt(v, unit=""):
    if v is None or (isinstance(v, float) and not math.isfinite(v)):
        return "never"
    if isinstance(v, float):
        return f"{v:.3g}{unit}"
    return f"{v}{unit}"


def table(report: dict) -> str:
    """The comparison table, ours beside the paper's."""
    s = report["synthesis"]
    r = report["rollouts"]
    rows = [("quantity", "paper", "ours")]
    for agent, variant in (("centralized", "centralized"), ("agent1", "decentralized"),
                           ("agent2", "decentralized")):
        rows.append((f"Q-table size, {agent}", paper.Q_SIZES[agent],
                     s[variant]["agents"][agent]["q_size"]))
    for agent, variant in (("centralized", "centralized"), ("agent1", "decentralized"),
                           ("agent2", "decentralized")):
        rows.append((f"iterations, {agent}", paper.ITERATIONS[agent],
                     s[variant]["agents"][agent]["iterations"]))
    rows.append(("iterations, agent1 (propagated context)", paper.ITERATIONS["agent1"],
                 s["decentralized_propagated"]["agents"]["agent1"]["iterations"]))
    for agent, variant in (("centralized", "centralized"), ("agent1", "decentralized"),
                           ("agent2", "decentralized")):
        star = "*" if agent != "centralized" else ""
        rows.append((f"synthesis CPU time [s], {agent}", f"~{paper.CPU_SECONDS[agent]:g}{star}",
                     _fmt(s[variant]["agents"][agent]["cpu_seconds"])))
    for variant in ("centralized", "decentralized", "decentralized_propagated"):
        for plant in _PLANTS:
            res = r[variant][plant]
            ref = paper.SETTLE_TIME.get(variant) if plant == "simplified" else "-"
            rows.append((f"settle time [s], {variant}, {plant}", ref if ref else "-",
                         _fmt(res["settle_time"])))
            off = ", ".join(f"{v:+.2f}" for v in res["final_offsets_deg"])
            rows.append((f"final offsets [deg], {variant}, {plant}",
                         f"|.| <= {paper.OFFSET_BOUND_DEG:g}" if plant == "simplified" else "-",
                         off))
    for variant in ("centralized", "decentralized", "decentralized_propagated"):
        for plant in _PLANTS:
            ev = report["evaluation_set"][variant][plant]
            rows.append((f"evaluation-set success, {variant}, {plant}", "-",
                         f"{100 * ev['success_rate']:.1f} % (edge stalls: "
                         f"{ev['failures_stalled_at_band_edge']}/{ev['failures']})"))
    for model, err in report["integration_error"].items():
        rows.append((f"max one-step error, {model}, {err['substeps']} vs "
                     f"{err['reference_substeps']} RK4 substeps [rad, rad/s]", "-",
                     f"{max(err['max'][:2]):.1e}, {max(err['max'][2:]):.1e}"))
    w = [max(len(str(row[i])) for row in rows) for i in range(3)]
    lines = [f"{a!s:<{w[0]}}  {b!s:>{w[1]}}  {c!s:>{w[2]}}" for a, b, c in rows]
    lines.insert(1, "-" * (sum(w) + 4))
    lines.append("* Table II's CPU times of agent 1 and agent 2 are almost certainly swapped: "
                 "agent 2's Q-table is 36x smaller.")
    return "\n".join(lines)


def run(args) -> int:
    report, trajs = reproduce(args.duration, progress=not args.json)
    panels = {}
    for name, title in (("centralized", "(a) centralized"),
                        ("decentralized", "(b) decentralized")):
        panels[title] = {plant: trajs[(name, plant)] for plant in _PLANTS}
    args.figure = args.figure or output_dir() / "fig3.png"
    fig3(panels, args.figure, title="Fig. 3 from x0 = [-1, -3, 0, 0]: solid simplified (11), "
                                    "dashed MuJoCo")
    report["figure"] = str(args.figure)
    if args.report:
        write_json(args.report, report)
    if args.json:
        print(json.dumps(report, indent=2))
    else:
        print(table(report))
        print(f"\nwrote {args.figure}")
    return 0
