"""docs/results/reproduction.md, from ``docs/data/reproduce.json`` and the iteration-norm
study ``renders/iteration_norms/iteration_norms.json`` (:func:`reproduction_page`).
"""
from __future__ import annotations

from .common import _duration, _load, _machine, _never, SCHEMAS, _sci, _seconds, _stamp, _table


def _iteration_norms_block(norms: dict) -> str:
    """The sweep counts of docs/studies/iteration_norms.py: per model and problem, under
    each norm of the stopping test, and serial."""
    cols = norms["norms"]
    rows = [(r["model"], r["problem"], r["paper"],
             *("-" if r["norms"][n] is None else r["norms"][n] for n in cols), r["serial_inf"])
            for r in norms["rows"]]
    return _table(("model", "problem", "paper", *(f"{n}-norm" for n in cols),
                   "serial, inf-norm"), rows)


def reproduction_page(report: dict) -> str:
    from twolink.studies.reproduce.table import table, verdict, verdict_block
    from twolink.viz.formatting import format_rate

    src = "docs/data/reproduce.json"
    x0 = ", ".join(f"{v:g}" for v in report["x0"])
    paper, syn, ro, ev = (report["paper"], report["synthesis"], report["rollouts"],
                          report["evaluation_set"])

    def agent(policy, name, serial=False):
        return syn[policy]["serial" if serial else "agents"][name]
    ours_q = {"centralized": agent("centralized", "centralized")["q_size"],
              "agent1": agent("decentralized", "agent1")["q_size"],
              "agent2": agent("decentralized", "agent2")["q_size"]}
    it = {"centralized": agent("centralized", "centralized")["iterations"],
          "agent1": agent("decentralized", "agent1")["iterations"],
          "agent2": agent("decentralized", "agent2")["iterations"]}
    it_serial = {"centralized": agent("centralized", "centralized", True)["iterations"],
                 "agent1": agent("decentralized", "agent1", True)["iterations"],
                 "agent2": agent("decentralized", "agent2", True)["iterations"]}
    prop = agent("decentralized_propagated", "agent1")["iterations"]
    prop_serial = agent("decentralized_propagated", "agent1", True)["iterations"]
    pi = paper["iterations"]
    text = [
        _stamp(src), "# Reproduction: the paper's experiment\n\n",
        f"`twolink reproduce` synthesises the paper's policies with fuzzy Q-iteration "
        f"(Alg. 1) on the simplified model (11), runs them from x0 = [{x0}] for "
        f"{report['duration']:g} s on the simplified plant and on MuJoCo, and prints this "
        "table beside the paper's figures (Table II, Fig. 3). Every success rate is k/n with "
        "its 95 % Wilson interval over the evaluation set (x0 and the 8x8 grid of angle "
        "pairs at rest); *edge stalls* count the failures that are arms at rest a hair "
        "outside the 5° band. Why the results differ where they do: "
        "[What matches, what differs](../findings/reproduction.md).\n\n",
        "```text\n", table(report), "\n", verdict(report), "\n\n", verdict_block(report),
        "\n```\n\n",
        "![Fig. 3 counterpart: solid, the simplified plant; dashed, MuJoCo]"
        "(../renders/fig3.png)\n\n## What matches, what differs\n\n"]
    same_q = all(ours_q[k] == paper["q_sizes"][k] for k in ours_q)
    text.append("- **Q-table sizes** " + (
        "match Table II exactly (" + ", ".join(str(ours_q[k]) for k in ours_q) + ")."
        if same_q else "differ from Table II: " + ", ".join(
            f"{k} {ours_q[k]} (paper {paper['q_sizes'][k]})" for k in ours_q) + ".") + "\n")
    c_s, p_s, d_s = (ro[p]["simplified"] for p in ("centralized", "decentralized_propagated",
                                                   "decentralized"))
    line = ("- **Stabilisation from x0.** On the simplified plant the centralized policy "
            f"settles in {_seconds(c_s['settle_time'])} (paper: about "
            f"{paper['settle_time']['centralized']:g} s) and the decentralized agents with "
            f"the propagated context in {_seconds(p_s['settle_time'])}")
    if not _never(p_s["settle_time"]) and not _never(c_s["settle_time"]) \
            and p_s["settle_time"] < c_s["settle_time"]:
        line += ("; the paper notes that the decentralized agents bring link 1 in faster "
                 "because they are rewarded separately (17), and so do these")
    th1, th2 = d_s["final_offsets_deg"]
    line += ". The default decentralized policy (frozen context) "
    if _never(d_s["settle_time"]):
        line += (f"brings link 2 to {th2:.2f}° and link 1 to rest at θ1 = {th1:.7f}°"
                 + (f", {_sci(abs(th1) - 5)}° outside the band, so by the metric it never "
                    "settles" if abs(th1) > 5 else ", and never settles by the metric")
                 + ". Under a plain `argmax`, which lets round-off decide its ties, it "
                 "ends elsewhere ([round-off and ties](round-off.md) has both rollouts).\n")
    else:
        line += f"settles in {_seconds(d_s['settle_time'])}.\n"
    text.append(line)
    cpu = {k: agent(p, k)["cpu_seconds"] for p, k in (("centralized", "centralized"),
                                                      ("decentralized", "agent1"),
                                                      ("decentralized", "agent2"))}
    pc = paper["cpu_seconds"]
    text.append(
        f"- **Synthesis time.** {cpu['centralized']:.2f} s of CPU for the centralized "
        f"policy against about {pc['centralized']:g} s in the paper (Matlab 7.1, 2006), "
        f"{pc['centralized'] / cpu['centralized']:,.0f}× less. That is a warm synthesis; "
        + (f"the process's first one, which also loads the compiled kernels, took "
           f"{syn['centralized']['first_call']['centralized']['cpu_seconds']:.2f} s "
           if "first_call" in syn["centralized"] else "the process's first one also loads "
           "the compiled kernels ")
        + "([performance](performance.md) times them). Table II's CPU times of agent 1 "
        f"(about {pc['agent1']:g} s) and agent 2 (about {pc['agent2']:g} s) are almost "
        f"certainly swapped: agent 2's table is {ours_q['agent1'] / ours_q['agent2']:.0f}× "
        "smaller" + (" and converges in fewer sweeps" if it["agent2"] < it["agent1"] else "")
        + ".\n")
    exact = it_serial["agent1"] == pi["agent1"] and it_serial["agent2"] == pi["agent2"]
    line = ("- **Iteration counts" + (": serial sweeps reproduce both agents exactly.** "
                                      if exact else ".** ")
            + f"With synchronous sweeps (Alg. 1 as printed and as the "
            "[conventions](../conventions.md) fix it; the shipped policies) agent 1 (frozen "
            f"context) takes {it['agent1']} sweeps (paper: {pi['agent1']}) and agent 2 "
            f"{it['agent2']} (paper: {pi['agent2']}). With *serial* sweeps (each Q(m, u) "
            "overwritten as soon as it is computed, in Matlab's order; the \"(serial sweeps)\" "
            f"rows of the table) agent 1 takes {it_serial['agent1']} and agent 2 "
            f"{it_serial['agent2']}. The centralized problem converges in "
            f"{it['centralized']} synchronous or {it_serial['centralized']} serial sweeps "
            f"against the paper's {pi['centralized']}.")
    norms = _load("renders/iteration_norms/iteration_norms.json",
                  SCHEMAS["renders/iteration_norms/iteration_norms.json"])
    if norms is not None:
        rows = {(r["model"], r["problem"]): r for r in norms["rows"]}
        cen = [rows[m, "centralized"] for m in ("simplified", "full") if (m, "centralized") in rows]
        counts = sorted({v for r in cen for v in (*r["norms"].values(), r["serial_inf"])
                         if v is not None})
        hit = pi["centralized"] in counts
        line += (" Neither another norm in the stopping test nor the full model (6) "
                 "explains it" if not hit else
                 " One reading below reaches it") + (
            f": over both models, every norm and both sweeps the centralized counts span "
            f"{counts[0]}–{counts[-1]} (`python docs/studies/iteration_norms.py --json "
            "renders/iteration_norms/iteration_norms.json`, "
            f"{_duration(norms['seconds'])}; the last column is serial with the infinity "
            "norm):\n\n")
        full = {k: rows.get(("full", k)) for k in ("centralized", "agent1 (frozen)", "agent2")}
        tail = ""
        if all(full.values()):
            keeps = (full["agent1 (frozen)"]["serial_inf"] == pi["agent1"]
                     and full["agent2"]["serial_inf"] == pi["agent2"])
            tail = (f"\n\n    On the full model the centralized counts are "
                    f"{full['centralized']['norms']['inf']} synchronous and "
                    f"{full['centralized']['serial_inf']} serial, and the agents "
                    + ("keep" if keeps else "lose") + " their match ("
                    f"{full['agent2']['serial_inf']} and {full['agent1 (frozen)']['serial_inf']} "
                    "serial sweeps for agent 2 and agent 1).")
        block = _iteration_norms_block(norms)
        line += "    " + block.replace("\n", "\n    ") + tail + "\n"
    else:
        line += "\n"
    text.append(line)
    text.append(
        f"- **Agent 1's context.** The frozen reading (the default) takes "
        f"{it_serial['agent1']} serial sweeps"
        + (", the paper's count," if it_serial["agent1"] == pi["agent1"] else "")
        + f" and the propagated one {prop_serial} ({prop} synchronous); see "
        "[agent 1's context](../concepts/agents.md#agent-1s-context-frozen-or-propagated).\n")
    labels = {"centralized": "centralized", "decentralized": "decentralized",
              "decentralized_propagated": "propagated context"}
    sims = {p: ev[p]["simplified"] for p in labels if p in ev}
    line = ("- **Beyond x0: the evaluation set.** On the simplified plant the paper's "
            "policies succeed from " + ", ".join(
                f"{format_rate(v['successes'], v['states'])} ({labels[p]})"
                for p, v in sims.items()) + ". ")
    if all(v["failures"] == v["failures_stalled_at_band_edge"] for v in sims.values()):
        line += ("*Every* failure there is an edge stall: the arm at rest a hair outside "
                 "the 5° band with zero torque, so it never \"settles\" by the metric.")
    else:
        line += ("Edge stalls among the failures: " + ", ".join(
            f"{v['failures_stalled_at_band_edge']}/{v['failures']} ({labels[p]})"
            for p, v in sims.items()) + ".")
    muj = {p: ev[p]["mujoco"] for p in labels if p in ev}
    stalled = sum(v["failures_stalled_at_band_edge"] for v in muj.values())
    fails = sum(v["failures"] for v in muj.values())
    line += (f" On MuJoCo {stalled} of the {fails} failures are edge stalls: "
             + ("most failures there are real.\n" if 2 * stalled < fails else
                "most are edge stalls there too.\n"))
    text.append(line)
    c_m, d_m = ro["centralized"]["mujoco"], ro["decentralized"]["mujoco"]
    text.append(
        "- **On MuJoCo** (the full rigid-body dynamics, which the simplified model leaves "
        "out), from x0 the centralized policy "
        + ("never settles" if _never(c_m["settle_time"])
           else f"still settles ({_seconds(c_m['settle_time'])})")
        + " and the decentralized one "
        + ("never settles" if _never(d_m["settle_time"])
           else f"settles in {_seconds(d_m['settle_time'])}")
        + " (the dashed lines of Fig. 3(b) above). [Model mismatch](mismatch.md) measures "
        "this over many initial states.\n\n")
    text.append(
        f"Machine: {_machine(report['provenance'])}. Synthesis CPU times are those of a "
        "second, warm synthesis in the process; the first one also loads the compiled "
        "kernels.\n\n"
        f"Re-create the data with `twolink reproduce --report {src}` (about 20 s; it also "
        "writes `renders/fig3.png`)"
        + (", and the sweep counts with `python docs/studies/iteration_norms.py --json "
           "renders/iteration_norms/iteration_norms.json`" if norms is not None else "")
        + ", then `python docs/generate.py`.\n")
    return "".join(text)
