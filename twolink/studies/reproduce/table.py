"""The comparison table of ``twolink reproduce``: ours beside the paper's figures.

Presentation only: every number comes from :meth:`twolink.studies.reproduce.measure.Reproduction.report`;
the paper's own figures come from :mod:`twolink.studies.reproduce.paper`.
"""
from __future__ import annotations

import math

from twolink.policy.registry import SHIPPED
from twolink.studies.reproduce import paper
from twolink.viz.formatting import format_rate


def _fmt(v, unit=""):
    if v is None or (isinstance(v, float) and not math.isfinite(v)):
        return "never"
    if isinstance(v, float):
        return f"{v:.3g}{unit}"
    return f"{v}{unit}"


def table(report: dict) -> str:
    """The comparison table of a :meth:`Reproduction.report`, ours beside the paper's."""
    s, r = report["synthesis"], report["rollouts"]
    names = list(s)
    first = {}                    # the first policy of each kind gives the Table II rows
    for name in names:
        first.setdefault(SHIPPED[name].kind, name)
    agents = [(agent, name) for name in first.values() for agent in sorted(s[name]["agents"])]
    rows = [("quantity", "paper", "ours")]
    for agent, name in agents:
        rows.append((f"Q-table size, {agent}", paper.Q_SIZES[agent],
                     s[name]["agents"][agent]["q_size"]))
    for agent, name in agents:
        rows.append((f"iterations, {agent}", paper.ITERATIONS[agent],
                     s[name]["agents"][agent]["iterations"]))
    others = [name for name in names      # the other readings of agent 1's context
              if name not in first.values() and SHIPPED[name].context
              and "agent1" in s[name]["agents"]]
    for name in others:
        rows.append((f"iterations, agent1 ({SHIPPED[name].context} context)",
                     paper.ITERATIONS["agent1"], s[name]["agents"]["agent1"]["iterations"]))
    for agent, name in agents:
        if "serial" in s[name]:
            rows.append((f"iterations, {agent} (serial sweeps)", paper.ITERATIONS[agent],
                         s[name]["serial"][agent]["iterations"]))
    for name in others:
        if "serial" in s[name]:
            rows.append((f"iterations, agent1 ({SHIPPED[name].context} context, serial sweeps)",
                         paper.ITERATIONS["agent1"], s[name]["serial"]["agent1"]["iterations"]))
    for agent, name in agents:
        star = "*" if agent != "centralized" else ""
        rows.append((f"synthesis CPU time [s], {agent}", f"~{paper.CPU_SECONDS[agent]:g}{star}",
                     _fmt(s[name]["agents"][agent]["cpu_seconds"])))
    for name in names:
        for plant, res in r[name].items():
            ref = paper.SETTLE_TIME.get(name) if plant == "simplified" else None
            rows.append((f"settle time [s], {name}, {plant}", ref or "-",
                         _fmt(res["settle_time"])))
            off = ", ".join(f"{v:+.2f}" for v in res["final_offsets_deg"])
            rows.append((f"final offsets [deg], {name}, {plant}",
                         f"|.| <= {paper.OFFSET_BOUND_DEG:g}" if plant == "simplified" else "-",
                         off))
    for name in names:
        for plant, ev in report["evaluation_set"][name].items():
            rows.append((f"evaluation-set success, {name}, {plant}", "-",
                         f"{format_rate(ev['successes'], ev['states'])} (edge stalls: "
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


def verdict(report: dict) -> str:
    """One line: whether each fresh synthesis has the shipped file's Q-tables bit for bit."""
    parts = []
    for name, s in report["synthesis"].items():
        match = s.get("matches_shipped_policy")
        parts.append(f"{name} {'yes' if match else 'no' if match is False else 'not shipped'}")
    return "fresh synthesis equals the shipped policy bit for bit: " + ", ".join(parts)
