"""The scaling page's section "Does their reward pay for the swing?", from
``renders/learners/guided/returns.json`` (``docs/studies/swing_returns.py``): from each
demonstration pose beyond the own motors' reach, the returns the learners' rewards give the
time-optimal answer and each controller, and on how many poses the answer earns more."""
from __future__ import annotations

from .common import SCHEMAS, _load

#: The study's data.
RETURNS = "renders/learners/guided/returns.json"
#: The columns: (reward, window, gamma, title); ``links`` is each inner link's own shaped
#: reward (IPPO's agents), every other reward the team's.
COLUMNS = (("shaped", "8s", 0.98, "shaped (PPO, MAPPO), γ 0.98"),
           ("shaped", "16s", 1.0, "shaped, 16 s, no discount"),
           ("links", "8s", 0.98, "inner links' own shaped (IPPO), γ 0.98"),
           ("shaped_time", "8s", 0.98, "shaped_time, γ 0.98"),
           ("shaped_time", "16s", 1.0, "shaped_time, 16 s, no discount"),
           ("paper", "8s", 0.98, "(15), γ 0.98"))


def _name(controller: str) -> str:
    """A saved agent by its run's folder, a catalogue name as it is."""
    return controller.split("/")[-2] if "/" in controller else controller


def _more(answer: dict, record: dict, reward: str, window: str, g: int):
    """(count where the answer's return is higher, out of, the record's mean return)."""
    import numpy as np

    mine = np.asarray(record[f"returns_{window}"][reward])[:, g]
    theirs = np.asarray(answer[f"returns_{window}"][reward])[:, g]
    if reward == "links":                          # the inner links' agents, each pose
        mine, theirs = mine[:, :-1], theirs[:, :-1]
    return int((theirs > mine).sum()), int(mine.size), float(mine.mean())


def swing_returns_block() -> str:
    """The section (empty without the study's data): a row per controller, the time-optimal
    answers' first; each cell the mean return and, for a controller, on how many poses
    (link-poses for IPPO's) the answer earns more; and the finding for the learned
    agents."""
    data = _load(RETURNS, SCHEMAS[RETURNS])
    if not data:
        return ""
    answer, *others = data["records"]
    gammas = data["gammas"]
    n = data["poses"]
    head = "| controller | settled by 8 s | by 16 s | " + " | ".join(
        c[3] for c in COLUMNS) + " |\n|---|---|---|" + "---|" * len(COLUMNS) + "\n"
    rows = []
    for r in [answer] + others:
        cells = []
        for reward, window, gamma, _ in COLUMNS:
            more, size, mean = _more(answer, r, reward, window, gammas.index(gamma))
            cells.append(f"{mean:.1f}" if r is answer else
                         f"{mean:.1f}; the answer more on {more}/{size}")
        label = ("time-optimal answers (replayed)" if r is answer
                 else f"`{_name(r['controller'])}`")
        rows.append(f"| {label} | {sum(r['success_8s'])}/{n} | {sum(r['success_16s'])}/{n} "
                    f"| " + " | ".join(cells) + " |\n")
    counts = _learned_counts(data)
    finding = ""
    if counts:
        finding = (
            f"**Under the shaped reward the learned agents train on, the time-optimal "
            f"answer earns more than the agent's own trajectory on at most "
            f"{max(counts['shaped'])} of the {n} poses** (γ 0.98; with no discount over "
            f"16 s on at most {max(counts['whole'])}): the reward pays less for the "
            "manoeuvre that settles these poses in time than for the slow approach the "
            "agents take, so an agent that maximised it would have no reason to swing. "
            "Only the paper's (15) pays for it: the answer earns more there on "
            f"{_span(counts['paper'])} poses, the agents leave {_span(counts['unsettled'])} "
            "unsettled by 8 s.\n\n")
    return ("### Does their reward pay for the swing?\n\n"
            f"`python docs/studies/swing_returns.py AGENT ... --json {RETURNS}`: from each "
            f"of the {n} demonstration poses above (seed {data['demo_seed']}, every one "
            "beyond the own motors' reach), the time-optimal answer replayed open loop and "
            "each controller run for 16 s on MuJoCo; each reward's return over the first "
            "8 s (a training episode) or all 16 s, discounted from the start. Each cell: "
            "the controller's mean return and on how many poses the time-optimal answer "
            "earns more (for IPPO's per-link reward, link-poses of the inner links). Where "
            "that count is small the reward prefers what the controller does.\n\n"
            + head + "".join(rows) + "\n" + finding)


def _span(values) -> str:
    return f"{min(values)}" if min(values) == max(values) else f"{min(values)} to {max(values)}"


def _learned_counts(data: dict) -> dict:
    """Over the learned agents (every controller but the answers and the per-joint PD):
    per agent, the poses on which the answer earns more under the shaped reward (γ 0.98,
    8 s; and no discount, 16 s) and under (15) (γ 0.98, 8 s), and the poses it leaves
    unsettled by 8 s; empty without learned agents."""
    answer, *others = data["records"]
    learned = [r for r in others if not _name(r["controller"]).startswith("pd_")]
    if not learned:
        return {}
    g, one = data["gammas"].index(0.98), data["gammas"].index(1.0)
    return {"shaped": [_more(answer, r, "shaped", "8s", g)[0] for r in learned],
            "whole": [_more(answer, r, "shaped", "16s", one)[0] for r in learned],
            "paper": [_more(answer, r, "paper", "8s", g)[0] for r in learned],
            "unsettled": [data["poses"] - sum(r["success_8s"]) for r in learned],
            "any": [_more(answer, r, "shaped", w, i)[0] for r in learned
                    for w in ("8s", "16s") for i in range(len(data["gammas"]))],
            "agents": len(learned), "poses": data["poses"]}


def reward_note(arm: tuple) -> str:
    """The learners page's cause for ``arm`` (links, rule), continued: the shaped reward
    pays the time-optimal answers less than the learned agents' own trajectories (empty
    without the data or for another arm)."""
    data = _load(RETURNS, SCHEMAS[RETURNS])
    ok = data and (data["links"], data["rule"]) == tuple(arm)
    counts = _learned_counts(data) if ok else {}
    if not counts:
        return ""
    return (f". The shaped reward they learn from pays those answers less than each of "
            f"{counts['agents']} learned agents' own trajectories on all but at most "
            f"{max(counts['shaped'])} of {counts['poses']} demonstration poses beyond that reach (γ 0.98; at most "
            f"{max(counts['any'])} at any discount tried, over 8 or 16 s; [scaling page](scaling.md#does-their-reward-pay-for-the-swing)): it "
            "does not ask for the manoeuvre")
