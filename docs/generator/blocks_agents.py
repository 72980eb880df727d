"""The agents concept page's blocks (docs/concepts/agents.md): the context readings
(:func:`context_readings`) and agent 1's sweep counts under both readings
(:func:`context_sweeps`), from ``docs/data/reproduce.json`` and the tie-sensitivity runs.
"""
from __future__ import annotations

from .common import _load, _never, _overlap, REPRODUCE, SCHEMAS, _t, _times_ten, _wilson


def context_sweeps() -> str:
    """The agents concept page: agent 1's sweep counts under both readings of its context
    (``docs/data/reproduce.json``) against the paper's and the stopping rule's."""
    import math

    from twolink.arm.parameters import GAMMA, REWARD_OTHER
    from twolink.synthesis.problems import DELTA
    repro = _load(REPRODUCE, SCHEMAS[REPRODUCE])
    if repro is None:
        return "(no reproduction data: run `twolink reproduce`, then `python docs/generate.py`)"
    syn, paper = repro["synthesis"], repro["paper"]["iterations"]["agent1"]
    fs, fy = (syn["decentralized"][k]["agent1"]["iterations"] for k in ("serial", "agents"))
    ps, py = (syn["decentralized_propagated"][k]["agent1"]["iterations"]
              for k in ("serial", "agents"))
    rule = math.log(DELTA / abs(REWARD_OTHER)) / math.log(GAMMA)
    match = ("exactly" if fs == paper else f"{fs} against the paper's {paper}:")
    return (f"The default is frozen because it reproduces the paper's sweep count for agent "
            f"1: {match} {fs} with serial sweeps (the propagated reading gives {ps}), {fy} "
            f"with synchronous ones (propagated: {py}). A frozen context in which link 2 "
            f"keeps pushing can never be held inside the goal band, so those Q-values "
            f"converge to {REWARD_OTHER:g}/(1−γ) at the slowest rate γ^ℓ; the stopping rule "
            f"{abs(REWARD_OTHER):g}·γ^ℓ ≤ δ (γ = {GAMMA:g}, δ = {DELTA:g}) is met after "
            f"ℓ ≈ {rule:.1f} sweeps, which is where the frozen counts ({fs}, {fy}) lie.")


def context_readings() -> str:
    """The agents concept page: the frozen and the propagated context of agent 1 from x0
    and over the evaluation set (``docs/data/reproduce.json``), and from random states
    (``renders/tie_sensitivity/tie_sensitivity.json``), and what tells them apart."""
    repro = _load(REPRODUCE, SCHEMAS[REPRODUCE])
    if repro is None:
        return "(no reproduction data: run `twolink reproduce`, then `python docs/generate.py`)"
    ties_rel = "renders/tie_sensitivity/tie_sensitivity.json"
    ties = _load(ties_rel, SCHEMAS[ties_rel])
    fr, pr = (repro["rollouts"][p]["simplified"] for p in ("decentralized",
                                                           "decentralized_propagated"))
    ef, ep = (repro["evaluation_set"][p]["simplified"] for p in ("decentralized",
                                                                 "decentralized_propagated"))

    def x0(r):
        th1 = r["final_offsets_deg"][0]
        if not _never(r["settle_time"]):
            return f"settles in {_t(r['settle_time'])}"
        if abs(th1) > 5:
            return f"parks {_times_ten(abs(th1) - 5)} degrees outside the band"
        return "never settles"
    a, b = (ef["successes"], ef["states"]), (ep["successes"], ep["states"])
    same = _overlap(a, b)
    text = (f"The rollouts {'do not separate' if same else 'separate'} the two readings: from "
            f"x0 the propagated reading {x0(pr)} and the frozen one {x0(fr)}; over the "
            f"evaluation set the frozen reading succeeds from {a[0]}/{a[1]} states and the "
            f"propagated one from {b[0]}/{b[1]} (Wilson 95 %: {_wilson(*a)} and "
            f"{_wilson(*b)})")
    random_same = None
    if ties is not None:
        pairs = []
        for run in ties["runs"]:
            rows = {r["policy"]: (r["successes"], r["states"]) for r in run["rows"]
                    if r["variant"].startswith("shipped rule (tolerance")}
            if {"decentralized", "decentralized_propagated"} <= set(rows):
                pairs.append((rows["decentralized"], rows["decentralized_propagated"]))
        random_same = all(_overlap(f, g) for f, g in pairs) if pairs else None
    if random_same is not None:
        text += (", and on random states the intervals "
                 + ("overlap too" if random_same and same else
                    "overlap" if random_same else "do not overlap in every run"))
    text += (" (`docs/studies/tie_sensitivity.py`; the counts are on "
             "[round-off and ties](../results/round-off.md)).")
    if same and random_same is not False:
        serial = repro["synthesis"]["decentralized"]["serial"]["agent1"]["iterations"]
        text += (" So the sweep count is the only figure that tells them apart"
                 + (", and with serial sweeps it points at frozen without any slack"
                    if serial == repro["paper"]["iterations"]["agent1"] else "") + ".")
    return text
