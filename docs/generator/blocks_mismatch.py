"""The mismatch guide's findings block (docs/guides/mismatch.md), from
``renders/mismatch/report.json`` (:func:`mismatch_findings`), and the number formats it
shares with the other blocks.
"""
from __future__ import annotations

import re

from .common import _load, _never, REPRODUCE, SCHEMAS, _sci, _t, _wilson


#: The mismatch report the mismatch guide's findings read (the results page reads it too).
MISMATCH = "renders/mismatch/report.json"

_WORDS = ("no", "one", "two", "three", "four", "five", "six", "seven", "eight", "nine", "ten",
          "eleven", "twelve")


def _word(n: int) -> str:
    return _WORDS[n] if 0 <= n < len(_WORDS) else str(n)


def _g3(x: float) -> str:
    """``x`` to three significant figures, 1.49e5 rather than 1.49e+05."""
    return re.sub(r"e([+-])0*(\d)", lambda m: "e" + m.group(1).lstrip("+") + m.group(2),
                  f"{x:.3g}")


def _pct_kn(k: int, n: int) -> str:
    """``k/n (p %, [lo, hi] %)``."""
    return f"{k}/{n} ({100 * k / n:.0f} %, {_wilson(k, n)})"


def _pct1(k: int, n: int) -> str:
    return f"{100 * k / n:.1f} %"


def _wilson1(k: int, n: int) -> str:
    from twolink.sim.metrics import wilson_interval
    lo, hi = wilson_interval(k, n)
    return f"[{100 * lo:.1f}, {100 * hi:.1f}]"


def _sweep_time(rb: dict, seconds: float) -> str:
    """The sweep's share of a mismatch run: its time, or that its cells were reused from
    the sweep file of an earlier run (``reused_cells``)."""
    what = f"the sweep ({rb['cells']} cells, {rb['joint_draws']} plants per joint size)"
    reused = rb.get("reused_cells", 0)
    if reused == rb["cells"]:
        return (f"{what} took {seconds:.0f} s: every cell came from the sweep file of an "
                f"earlier run (`twolink mismatch` resumes from `sweep.jsonl`)")
    if reused:
        return f"{what} {seconds:.0f} s ({reused} of its cells reused from the sweep file)"
    return f"{what} {seconds:.0f} s"


def mismatch_findings() -> str:
    """What the committed mismatch report shows, the guide's bullets: open loop, the paper's
    policies on MuJoCo, synthesis on (6), the robustness margins, the robust section and
    the throughput, every figure and every judgement computed from ``renders/mismatch/
    report.json`` (and the x0 rollout of ``docs/data/reproduce.json``)."""
    from twolink.arm.parameters import HORIZON, SUCCESS_MARGIN
    from twolink.policy.registry import SHIPPED
    from twolink.sim.challenges import SPEED_PER_DEG
    from twolink.sim.perturbations import PHYSICAL

    report = _load(MISMATCH, SCHEMAS[MISMATCH])
    if report is None:
        return "(no mismatch report: run `twolink mismatch`, then `python docs/generate.py`)"
    repro = _load(REPRODUCE, SCHEMAS[REPRODUCE])
    ol, cl, rb, gc = (report["open_loop"], report["closed_loop"], report["robustness"],
                      report["gap_closure"])
    thr = rb["threshold"]
    out = []

    # 1. open loop
    full = max(v["max"] for v in ol["summary"]["full"].values())
    integ = max(ol["integration_error_full"]["max"])
    simp = ol["summary"]["simplified"]
    line = (f"- **Open loop.** Over all {ol['transitions']} transitions (every bin centre of "
            f"the centralized grid × every action), the full model (6) agrees with MuJoCo to "
            f"{'round-off' if full < integ else 'within'} (max {_sci(full)} rad/s")
    line += (f"; the RK4 integration error itself is {'far ' if integ > 1e3 * full else ''}"
             f"larger, up to {_sci(integ)}), so "
             "MuJoCo *is* (6)." if full < integ else
             f", against an RK4 integration error of {_sci(integ)}).")
    line += (f" The simplified model (11) is off by up to {simp['dtheta2']['max']:#.2g} rad/s "
             f"in dθ̇2 and {simp['dtheta1']['max']:#.2g} rad/s in dθ̇1 in a single 0.05 s "
             f"sample (RMS {simp['dtheta2']['rms']:#.2g} and {simp['dtheta1']['rms']:#.2g} "
             "rad/s).")
    out.append(line)

    # 2. the paper's policies
    def kn(p, plant):
        v = cl[p][plant]
        return v["successes"], v["states"]

    c, d = cl["centralized"], cl["decentralized"]
    line = ("- **Paper policies on MuJoCo** (k of "
            f"{report['evaluation_set']['closed_loop']} states, 95 % Wilson interval). "
            f"Centralized: {_pct_kn(*kn('centralized', 'simplified'))} on the simplified "
            f"plant, {_pct_kn(*kn('centralized', 'mujoco'))} on MuJoCo (from x0: settles in "
            f"{_t(c['simplified']['x0_settle_time'])} vs {_t(c['mujoco']['x0_settle_time'])}"
            "). Decentralized (frozen context): "
            f"{_pct_kn(*kn('decentralized', 'simplified'))} vs "
            f"{_pct_kn(*kn('decentralized', 'mujoco'))}; from x0 ")
    xs, xm = d["simplified"]["x0_settle_time"], d["mujoco"]["x0_settle_time"]
    if _never(xs) and _never(xm):
        line += "it never settles on either plant"
        th1 = None if repro is None else \
            repro["rollouts"]["decentralized"]["simplified"]["final_offsets_deg"][0]
        if th1 is not None and abs(th1) > 5:
            line += (f" (on the simplified one it parks {_sci(abs(th1) - 5)}° outside the "
                     "band, see [what matches, what differs](../findings/reproduction.md))")
    else:
        line += f"it settles in {_t(xs)} on the simplified plant and {_t(xm)} on MuJoCo"
    line += (f". Propagated context: {_pct_kn(*kn('decentralized_propagated', 'simplified'))}"
             f" vs {_pct_kn(*kn('decentralized_propagated', 'mujoco'))}.")
    out.append(line)

    # 3. synthesis on (6)
    cf, df = cl["centralized_full"]["mujoco"], cl["decentralized_full"]["mujoco"]
    k, n = cf["successes"], cf["states"]
    line = ("- **Synthesis on (6) recovers the gap.** `centralized_full` succeeds from "
            + (f"all {n} states" if k == n else f"{k} of {n} states")
            + f" on MuJoCo ({k}/{n}, {_wilson(k, n)}, "
            f"{100 * gc['centralized']['gain_on_mujoco']:+.0f} points; x0 settles in "
            f"{_t(cf['x0_settle_time'])}). `decentralized_full` keeps the information "
            "structure of (18): agent 2 sees only link 2 and assumes link 1 at rest (θ̇1 = 0, "
            "τ1 = 0) in its model; agent 1 uses (6) with link 2 held at rest over a "
            f"transition. It reaches {df['successes']}/{df['states']} on MuJoCo "
            f"({100 * df['success_rate']:.0f} %, {_wilson(df['successes'], df['states'])}, "
            f"{100 * gc['decentralized']['gain_on_mujoco']:+.0f} points against the "
            "frozen-context paper policy)")
    ds, cs = df["settle_time"], cf["settle_time"]
    missed = df["states"] - df["successes"]
    if ds["settled"] == 1.0:
        line += " and settles from every state"
        if ds["median"] > cs["median"]:
            line += (f", but later (median {_t(ds['median'])} vs {_t(cs['median'])} "
                     "centralized")
            if missed:
                line += (f"; the {missed} it misses settle after the "
                         f"{HORIZON - SUCCESS_MARGIN:g} s cut-off")
            line += ")"
    else:
        line += (f"; {100 * ds['settled']:.0f} % of its runs settle (median "
                 f"{_t(ds['median'])} vs {_t(cs['median'])} centralized)")
    a2 = ol["summary"]["agent2_assumption"]["dtheta2"]["max"]
    line += (": that is the measured cost of agent 2's blind spot (its one-step link-2 error "
             f"is up to {a2:#.2g} rad/s when link 1 moves).")
    out.append(line)

    # 4. the margins
    m, counts, worst, sizes = rb["margins"], rb["counts"], rb["joint_worst_plant"], rb["sizes"]
    t = f"{100 * thr:.0f} %"

    def joint(p, s):
        return counts[p]["joint"][str(float(s))]

    def at(p, fam, s):
        return rb["curves"][p][fam].get(str(float(s)))

    line = (f"- **Robustness margins** (largest perturbation with ≥ {t} success on MuJoCo; "
            f"joint perturbations from {rb['joint_draws']} random plants per size, each with "
            "its k/n, Wilson interval, worst plant, mean and worst-case return; a second "
            f"column counts a size only when its Wilson lower bound clears {t}, so "
            "neighbouring sizes count as different only when the data tell them apart).")
    p = "centralized_full"
    if m[p]["every_parameter_alone"] is not None:
        mp = m[p]
        params = {k_: v for k_, v in mp.items() if k_.startswith("parameter:")}
        top = max(abs(s) for s in sizes["parameter"])
        at_top = sum(v == top for v in params.values())
        line += (f" `{p}` survives every Table I parameter alone changed by "
                 f"±{100 * mp['every_parameter_alone']:g} %")
        if mp["every_parameter_alone"] < top and at_top:
            line += f" ({at_top} of the {len(params)} by ±{100 * top:g} %)"
        mj = mp["joint"]
        if mj:
            k, n = joint(p, mj)
            w = worst[p][str(float(mj))]
            line += (f", all {_word(len(PHYSICAL))} physical parameters jointly at random by "
                     f"±{100 * mj:g} % ({k}/{n} = {_pct1(k, n)} {_wilson1(k, n)}; worst plant "
                     f"{w['successes']}/{w['states']}")
            nxt = [s for s in sizes["joint"] if s > mj]
            if nxt:
                k2, n2 = joint(p, nxt[0])
                line += f"; at ±{100 * nxt[0]:g} % {_pct1(k2, n2)}"
            line += ")"
            if mp.get("joint_lower_bound") is not None and mp["joint_lower_bound"] != mj:
                line += (f" (±{100 * mp['joint_lower_bound']:g} % by the Wilson lower "
                         "bound)")
        if mp["noise"]:
            line += (f", state noise of {mp['noise']:g}° (and "
                     f"{mp['noise'] * SPEED_PER_DEG:g} rad/s)")
        if mp["torque_limit"]:
            line += f", torque limits cut by {100 * mp['torque_limit']:g} %"
        if mp["delay"] == 0:
            s1 = min(sizes["delay"])
            line += (f", but **not a {_word(int(s1))}-sample actuation delay "
                     f"({100 * at(p, 'delay', s1):.0f} % success)** without the "
                     "[compensator](compensation.md).")
        else:
            line += f", and a {_word(int(mp['delay']))}-sample actuation delay."
    p = "centralized_robust"
    mp = m[p]
    if mp["every_parameter_alone"] is not None:
        fams = {"parameter": "every_parameter_alone", "joint": "joint", "noise": "noise",
                "delay": "delay", "torque_limit": "torque_limit"}
        kept = {f: mp[key] is not None and mp[key] >= max(abs(s) for s in sizes[f])
                for f, key in fams.items()}
        parts = []
        if kept["parameter"] and kept["joint"]:
            k, n = joint(p, mp["joint"])
            parts.append(f"±{100 * mp['joint']:g} % for each parameter and jointly "
                         f"({_pct1(k, n)} at ±{100 * mp['joint']:g} %)")
        if kept["noise"]:
            parts.append(f"{mp['noise']:g}° of noise")
        if kept["delay"]:
            parts.append(f"a {_word(int(mp['delay']))}-sample delay even without "
                         "compensation")
        if kept["torque_limit"]:
            parts.append(f"torque limits cut by {100 * mp['torque_limit']:g} %")
        if all(kept.values()):
            line += f" `{p}` keeps every tested size: " + ", ".join(parts) + "."
        else:
            short = []
            if not (kept["parameter"] and kept["joint"]):
                short.append(f"±{100 * mp['every_parameter_alone']:g} % for each parameter "
                             f"alone, ±{100 * (mp['joint'] or 0):g} % jointly")
            if not kept["noise"]:
                big = min(s for s in sizes["noise"] if s > (mp["noise"] or 0))
                short.append(f"noise up to {mp['noise'] or 0:g}° "
                             f"({100 * at(p, 'noise', big):.0f} % at {big:g}°, of up to "
                             f"{max(sizes['noise']):g}° tested)")
            if not kept["delay"]:
                short.append(f"a delay of {mp['delay'] or 0:g} samples")
            if not kept["torque_limit"]:
                short.append(f"torque limits cut by {100 * (mp['torque_limit'] or 0):g} %")
            what = {"parameter": "parameter", "joint": "joint", "noise": "noise",
                    "delay": "delay", "torque_limit": "torque limit"}
            line += (f" `{p}` keeps every tested size of "
                     + ", ".join(what[f] for f in fams if kept[f]) + ": " + ", ".join(parts)
                     + "; " + ", ".join(short).replace("noise up to", "noise only up to")
                     + ".")
    nominal = {q: rb["curves"][q]["nominal"] for q in m}
    none = [q for q in m if nominal[q] is None or nominal[q] < thr]
    paper = [q for q in m if q in SHIPPED and SHIPPED[q].paper]
    if none:
        names = (["the paper's policies"] if paper and set(paper) <= set(none) else []) \
            + [f"`{q}`" for q in none if not (paper and set(paper) <= set(none) and q in paper)]
        who = " and ".join(names)
        line += (f" {who[0].upper() + who[1:]} fall below {t} already on the nominal MuJoCo "
                 "plant, so they have no margin")
    for q in m:
        if q in none or m[q]["joint"] != 0.0:
            continue
        s1 = min(sizes["joint"])
        k, n = joint(q, s1)
        k0, n0 = counts[q]["nominal"]
        gap = thr - k / n
        line += (f"; `{q}` ({_pct1(k0, n0)} nominal) keeps {_pct1(k, n)} at ±{100 * s1:g} % "
                 f"jointly, {'just ' if 0 < gap < 0.03 else ''}short of {t}")
    out.append(line + ".")

    # 5. the robust section
    if "robust" in report:
        rs, st = report["robust"], report["stage_seconds"]
        out.append(
            "- **Robust section** (report section 5; see [challenges](challenges.md)): "
            f"every shipped policy under every challenge level, {rs['plants']} plants × "
            f"{rs['states']} states from seed {rs['seed']} (fixed in the plan, never tuned "
            "on), as it is and behind the run-time compensator (the paper's policies only as "
            "they are), one `twolink.sim.evaluation.evaluate` call each, with its targets "
            f"checked. Measured in the committed run, on a "
            f"{report['provenance']['cpu_count']}-core machine shared with other jobs: the "
            f"whole `{report['command']}` took {report['seconds']:.0f} s, of which "
            + _sweep_time(rb, st["sweep"])
            + f" and this section {rs['seconds']:.0f} s wall ({rs['cpu_seconds']:.0f} s CPU).")

    # 6. throughput
    tp = report["throughput"]
    steps = f"{tp['mujoco_steps']:,}".replace(",", " ")
    out.append(
        "- **Throughput.** Sweeps batch many states × many perturbed plants, evaluate the "
        "policy once per sample for the whole batch and advance MuJoCo with `mujoco.rollout` "
        f"on a thread pool: {_g3(tp['closed_loop_steps_per_s'])} closed-loop steps/s against "
        f"{_g3(tp['open_loop_steps_per_s'])} for a single open-loop `mujoco.rollout` call "
        f"over the same {steps} steps with the same torques. That is a ratio "
        f"of {tp['ratio_closed_to_open']:.2f} with {tp['nthread']} threads, measured in the "
        f"run of `{report['command']}` that made the committed report "
        "(`twolink.studies.throughput.measure`, the one definition the benchmarks use too), "
        "on a machine shared with other jobs at the time.")
    return "\n".join(out)
