"""The generated blocks of README.md and the guides that read the shipped policies, the
leaderboard, the SB3 agent's run record and the N-link runs:

* :func:`policies_table`: the shipped-policy table (README.md, the synthesis guide);
* :func:`tables_table`: the stored Q-tables under ``policies/`` and the policies reading
  each (the synthesis guide);
* :func:`leaderboard_headline`: the leaderboard headline of README.md;
* :func:`compensation_table`: the compensation guide's table;
* :func:`baselines_table`: the classical baselines of the controllers guide;
* :func:`sb3_agent_summary`: the committed SB3 agent (``renders/deep_rl/ppo_agent_seed0.json``)
  of the stable-baselines3 guide;
* :func:`centralized_3link_block` and :func:`link_mismatch_table`: the three-link
  synthesis (the scaling run) and the N-link mismatch
  (``renders/mismatch-3link{,-copied}/report.json``) of the N-links guide.
"""
from __future__ import annotations

from pathlib import Path

from .common import (_cell, _duration, _load, _machine, _overlap, SCHEMAS, _sci, _seconds,
                     _table)


def policies_table(link_prefix: str = "", tuned: bool = True) -> str:
    """The shipped-policy table; without ``tuned`` the designs chosen on tuning seeds are
    named after it instead (with a link to the synthesis guide's full table)."""
    from twolink.policy.registry import SHIPPED

    rows = []
    for p in SHIPPED.values():
        if p.tuned and not tuned:
            continue
        how = [f"{p.kind} {'(16)' if p.kind == 'centralized' else '(18)'}",
               f"on {'(11)' if p.model == 'simplified' else '(6)'}"]
        if p.context:
            how.append(f"{p.context} context")
        if p.robust:
            how.append(f"{p.robust} case of {p.draws} models within ±{100 * p.spread:g} %, "
                       f"seed {p.seed}")
        if p.sweeps != "synchronous":
            how.append(f"{p.sweeps} sweeps")
        if p.levels != 3:
            how.append(f"{p.levels} torque levels")
        if p.bins != "paper":
            how.append(f"{p.bins} bins")
        if p.agent2_link1 != "free":
            how.append(f"agent 2 reads link 1 {p.agent2_link1}")
        if p.speed_dead_zone:
            how.append(f"speed dead zone {p.speed_dead_zone:g} rad/s")
        if p.argmax_beyond_deg is not None:
            how.append(f"argmax of Q beyond {p.argmax_beyond_deg:g}°")
        if p.near_gain < 1:
            how.append(f"near-goal gain {p.near_gain:g} from {p.near_deg:g}°")
        if p.tuned:
            how.append("chosen on tuning seeds")
        rows.append((f"`{p.name}`", p.links, "yes" if p.paper else "", ", ".join(how),
                     _cell(p.description)))
    table = _table(("policy", "links", "paper's", "synthesis", "what it is"), rows)
    if tuned:
        return table
    names = [f"`{n}`" for n, p in SHIPPED.items() if p.tuned]
    return (table + f"\n\nand {len(names)} designs chosen on tuning seeds (more torque levels, "
            "other bins, read-outs; each in the [synthesis guide]"
            f"({link_prefix}docs/guides/synthesis.md)'s table): " + ", ".join(names) + ".")


def tables_table() -> str:
    """The committed files under ``policies/``, one per stored Q-table (named by its
    synthesis settings, :func:`twolink.policy.registry.table_stem`), with the shipped
    policies that read it (the first one's read-out is the file's own)."""
    from twolink.policy.registry import SHIPPED

    readers: dict = {}
    for p in SHIPPED.values():
        readers.setdefault(p.table, []).append(f"`{p.name}`")
    return _table(("file", "policies reading it"),
                  [(f"`policies/{t}.npz`", ", ".join(names))
                   for t, names in readers.items()])


def leaderboard_headline() -> str:
    """The README's leaderboard: the catalogue's benchmark rows of the committed
    leaderboard in the compact table (:func:`twolink.studies.leaderboard.report.compact`:
    a success percentage per level and mode, the best of each column in bold, one line
    per level naming the best, a reason under the table for each blank cell)."""
    report = _load("renders/leaderboard/leaderboard.json",
                   SCHEMAS["renders/leaderboard/leaderboard.json"])
    if report is None:
        return "(no leaderboard data: run `make results STEPS=\"leaderboard docs\"`)"
    from twolink.control.catalogue import BENCHMARK
    from twolink.studies.leaderboard.report import compact

    present = {r["controller"] for r in report["rows"]}
    names = [n for n in BENCHMARK if n in present]
    import textwrap

    caption = (f"The benchmark rows (`twolink controllers --tag benchmark`), success on MuJoCo "
            f"from the {report['states']} evaluation states, {report['plants']} plants per "
            f"perturbed level, seed {report['seed']}; in bold the first of each column by "
            "the [ranking rule](docs/guides/leaderboard.md#how-rows-are-ranked); k/n, "
            "intervals and all "
            f"{len(present)} controllers: [full table](docs/results/leaderboard.md).")
    return (textwrap.fill(caption, 92, break_long_words=False, break_on_hyphens=False)
            + "\n\n" + compact(report, names).replace("T*", "T\\*"))


def ranking_rule() -> str:
    """The leaderboard's ranking rule (:data:`twolink.studies.leaderboard.ranking.RULE`)."""
    from twolink.studies.leaderboard.ranking import RULE

    return RULE.replace("T*", "T\\*")


#: The leaderboard's data file (the guides' blocks read it as the leaderboard pages do).
LEADERBOARD = "renders/leaderboard/leaderboard.json"


def _leaderboard() -> dict | None:
    return _load(LEADERBOARD, SCHEMAS[LEADERBOARD])


def _no_leaderboard() -> str:
    return "(no leaderboard data: run `twolink leaderboard`, then `python docs/generate.py`)"


def _board_rows(report: dict) -> dict:
    return {(r["controller"], r["level"], r["mode"]): r for r in report["rows"]}


def _board_caption(report: dict) -> str:
    return (f"MuJoCo, the {report['states']} evaluation states, {report['plants']} plants per "
            f"perturbed level, seed {report['seed']} (`{report['command']}`; 95 % Wilson "
            f"intervals; the [leaderboard](../results/leaderboard.md) has every row)")


#: The fuzzy policies the compensation guide compares with and without compensation.
COMPENSATED_POLICIES = ("centralized_full", "decentralized_full", "centralized_robust",
                        "decentralized_robust")


def compensation_table() -> str:
    """Each of :data:`COMPENSATED_POLICIES` under every perturbing level of the leaderboard,
    plain -> compensated (k/n with the interval; "intervals overlap" where they do)."""
    from twolink.viz.formatting import format_rate

    report = _leaderboard()
    if report is None:
        return _no_leaderboard()
    rows = _board_rows(report)
    levels = [lv for lv in report["levels"]
              if any((p, lv, "compensated") in rows for p in COMPENSATED_POLICIES)]

    def cell(p, lv):
        a, b = rows.get((p, lv, "plain")), rows.get((p, lv, "compensated"))
        if a is None or b is None:
            return ""
        same = _overlap((a["successes"], a["n"]), (b["successes"], b["n"]))
        return (f"{format_rate(a['successes'], a['n'])} → "
                f"{format_rate(b['successes'], b['n'])}" + (" (intervals overlap)" if same else ""))

    body = [(f"`{p}`", *[cell(p, lv) for lv in levels]) for p in COMPENSATED_POLICIES
            if any((p, lv, "plain") in rows for lv in levels)]
    return (_board_caption(report) + "; plain → compensated:\n\n"
            + _table(("policy", *levels), body))


#: The classical baselines of the controllers guide (twolink.control.baselines).
BASELINES = ("pd", "pd_deadzone", "lqr", "lqr_delay", "bang_bang")


def baselines_table() -> str:
    """The classical baselines nominal (success, median settle) and under ``medium`` and
    ``hard``, plain and compensated, from the committed leaderboard."""
    from twolink.viz.formatting import format_rate

    report = _leaderboard()
    if report is None:
        return _no_leaderboard()
    rows = _board_rows(report)
    cols = [(lv, m) for lv in ("medium", "hard") for m in ("plain", "compensated")
            if any((b, lv, m) in rows for b in BASELINES)]

    def rate(r):
        return "" if r is None else format_rate(r["successes"], r["n"])

    def nominal(b):
        r = rows.get((b, "none", "plain"))
        return "" if r is None else f"{rate(r)}, median {_seconds(r['median_settle'])}"

    body = [(f"`{b}`", nominal(b), *[rate(rows.get((b, lv, m))) for lv, m in cols])
            for b in BASELINES if any(k[0] == b for k in rows)]
    return (_board_caption(report) + ":\n\n"
            + _table(("baseline", "nominal", *[f"{lv}, {m}" for lv, m in cols]), body))


#: The committed SB3 agent the stable-baselines3 guide describes, and its run record.
SB3_AGENT = "renders/deep_rl/ppo_agent_seed0.json"


def sb3_agent_summary() -> str:
    """What the committed PPO agent is (its run record) and how it does on the leaderboard."""
    from twolink.viz.formatting import format_rate

    run = _load(SB3_AGENT, SCHEMAS[SB3_AGENT])
    report = _leaderboard()
    if run is None or report is None:
        return "(no agent data: run `python docs/studies/deep_rl.py`, then `python docs/generate.py`)"
    name = Path(run["saved"]).stem
    rows = _board_rows(report)
    text = (f"The committed agent `{run['saved']}` ({run['algo'].upper()}, seed {run['seed']}, "
            f"{run['steps']:,} environment steps in its {run['minutes_cap']:g}-minute budget, "
            f"curve in `{SB3_AGENT}`)")
    levels = [lv for lv in report["levels"] if (name, lv, "plain") in rows]
    if not levels:
        return text + " has no leaderboard rows yet."
    parts = []
    for lv in levels:
        r = rows[(name, lv, "plain")]
        part = f"{lv}: {format_rate(r['successes'], r['n'])}"
        if r["settle_ratio_median"] is not None:
            part += f" (median settle / T\\* {r['settle_ratio_median']:.2f})"
        parts.append(part)
    return (text + f" on the leaderboard as `{name}`, plain (seed {report['seed']}, "
            f"{report['plants']} plants per perturbed level): " + "; ".join(parts) + ".")


def _gib_of(b: float) -> str:
    return f"{b / 2 ** 30:.2f} GiB"


def centralized_3link_block() -> str:
    """The three-link centralized synthesis of the committed scaling run: T's non-zeros,
    factored against sparse storage, peak memory, sweeps and time."""
    rel = "renders/scaling/scaling.json"
    report = _load(rel, SCHEMAS[rel])
    row = None if report is None else next(
        (r for r in report["rows"] if r["links"] == 3 and r["scheme"] == "centralized"
         and r["status"] == "run" and r["synthesis"]), None)
    if row is None:
        return "(no three-link centralized run: run `twolink scaling`, then `python docs/generate.py`)"
    s, e = row["synthesis"], row["estimate"]
    sparse = s["nnz"] * 12                 # CSR: an 8-byte value and a 4-byte column each
    agent = s["agents"][0]
    return (f"In the committed scaling run (`{report['command']}`, {_machine(report['provenance'])}), "
            f"T's {_sci(s['nnz'])} non-zeros took {_gib_of(e['stored_bytes'])} (estimated) "
            f"instead of {_gib_of(sparse)} as a sparse matrix (8-byte values, 4-byte "
            f"columns). The synthesis peaked at {_gib_of(s['peak_bytes'])} and ran "
            f"{agent['sweeps']} sweeps, {s['cpu_seconds']:.0f} s of CPU "
            f"({_duration(s['wall_seconds'])} wall); "
            f"[scaling results](../results/scaling.md).")


#: The N-link mismatch runs the N-link guide shows: (data file, what built the policy).
LINK_MISMATCH = (("renders/mismatch-3link/report.json", "tapered, shipped"),
                 ("renders/mismatch-3link-copied/report.json",
                  "copied, `twolink synthesize decentralized --links 3 --rule copied -o d3c.npz`"))


def link_mismatch_table() -> str:
    """Each N-link policy of :data:`LINK_MISMATCH` on the numpy full N-link model and on
    MuJoCo: success, median settle, same outcome, largest RMS gap."""
    from twolink.viz.formatting import format_rate

    rows, runs = [], []
    for rel, how in LINK_MISMATCH:
        report = _load(rel, SCHEMAS[rel])
        if report is None:
            continue
        runs.append(report)
        for name, res in report["results"].items():
            full, mj, gap = res["full"], res["mujoco"], report["gap"][name]
            settle = _seconds(full["median_settle"])
            if mj["median_settle"] != full["median_settle"]:
                settle += f" / {_seconds(mj['median_settle'])}"
            rows.append((f"`{name}` ({how})", format_rate(full["successes"], full["n"]),
                         format_rate(mj["successes"], mj["n"]), settle,
                         f"{gap['same_outcome']}/{full['n']}",
                         f"{_sci(gap['angle_rms'])} rad, {_sci(gap['speed_rms'])} rad/s"))
    if not runs:
        return "(no N-link mismatch data: run `twolink mismatch --links 3`, then `python docs/generate.py`)"
    r = runs[0]
    return (f"{r['poses']} random poses at rest (seed {r['seed']}, never tuned on), "
            f"{r['duration']:g} s; " + ", ".join(f"`{x['command']}`" for x in runs) + ":\n\n"
            + _table(("policy", "success on full", "success on MuJoCo", "median settle",
                      "same outcome", "largest RMS gap"), rows))
