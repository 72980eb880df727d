"""The leaderboard presented: the full Markdown (one ranked table per level, k/n with
Wilson intervals), the compact table (a success percentage per cell, the README's and the
command's), the ``ranks k of M`` lines of one controller, the JSON of every row and the
figure (:mod:`twolink.viz.leaderboard`). Every ranking is :mod:`.ranking`'s rule.
"""
from __future__ import annotations

import os
from pathlib import Path

from twolink.artifacts import provenance, staged_set, write_json, write_text
from twolink.studies.leaderboard.ranking import RULE, columns, ranked, ranked_in, standings
from twolink.viz.formatting import format_rate

FILES = {"markdown": "leaderboard.md", "json": "leaderboard.json",
         "figure": "leaderboard.png"}
#: Why a cell of the compact table is blank, by its mark.
BLANKS = {"—": "no compensated run: the controller names no model (`meta[\"model\"]`) for "
               "the compensator to predict with",
          "·": "not measured under this level"}


def _ratio(v) -> str:
    return "never" if v is None else f"{v:.2f}"


def _settle(v) -> str:
    return "never" if v is None else f"{v:.2f} s"


def percent(k: int, n: int) -> str:
    """A success rate in percent for a table cell: ``100 %`` and ``0 %`` only when every
    run or none succeeded, else one decimal (``>99.9 %``, ``<0.1 %`` at the ends)."""
    if k == n:
        return "100 %"
    if k == 0:
        return "0 %"
    text = f"{100 * k / n:.1f}"
    return ">99.9 %" if text == "100.0" else "<0.1 %" if text == "0.0" else f"{text} %"


def families(names) -> dict:
    """``{name: "fuzzy" | "baseline" | "learned" | "user"}`` from the catalogue's tags
    (:mod:`twolink.control.catalogue`); a name the catalogue does not hold (a
    ``module:callable``, a file) is ``user``."""
    from twolink.control.catalogue import catalogue

    try:
        cat = catalogue()
    except ValueError:                    # a broken user catalogue: the shipped entries
        from twolink.control.catalogue import shipped_entries
        cat = {e.name: e for e in shipped_entries()}
    out = {}
    for n in names:
        tags = cat[n].tags if n in cat else ("user",)
        out[n] = next((f for f in ("learned", "baseline", "fuzzy", "user") if f in tags),
                      "user")
    return out


def labelled(report: dict, most: int = 12) -> list:
    """The controllers the figure labels, at most ``most``: every one of a report of no
    more; else the benchmark's (:data:`twolink.control.catalogue.BENCHMARK`), then those
    outside the catalogue (a user's)."""
    from twolink.control.catalogue import BENCHMARK

    names = list(dict.fromkeys(r["controller"] for r in report["rows"]))
    if len(names) <= most:
        return names
    fam = families(names)
    first = [n for n in BENCHMARK if n in names]
    return list(dict.fromkeys([*first, *(n for n in names if fam[n] == "user")]))[:most]


def markdown(report: dict) -> str:
    """The report as Markdown: what was run, the ranking rule, then one ranked table per
    level (the plain rows, then the compensated ones, each ranked from 1)."""
    names = list(dict.fromkeys(r["controller"] for r in report["rows"]))
    have_model = {r["controller"] for r in report["rows"] if r["mode"] == "compensated"}
    plain_only = [n for n in names if n not in have_model]
    lines = ["# Leaderboard", "",
             f"`{report['command']}`: {report['states']} initial states, "
             f"{report['plants']} plants per perturbing level, seed {report['seed']}, "
             f"on MuJoCo. Success: settled in the goal band 1 s before the end of "
             f"{report['horizon']:g} s (k/n with the 95 % Wilson interval). settle / T*: "
             f"each run's settle time over the time-optimal limit of its initial state "
             f"({report['limits']}), a failure counting as never settled. "
             "*plain*: the controller reads the challenge's readings as they are; "
             "*compensated*: through the delay predictor and observer "
             "(twolink.sim.estimation), for controllers that name their model. Level none "
             "runs one nominal plant (no worst plant) and has nothing to compensate.", "",
             RULE, ""]
    if plain_only:
        lines += ["No compensated rows (they name no model to predict with): "
                  + ", ".join(plain_only) + ".", ""]
    grid = any("grid" in r for r in report["rows"])
    if grid:
        lines += ["*grid*: the same controller on the level's grid of plants (its parameter "
                  "box's centre and 24 corners, twolink.sim.plant_grid): successes over the "
                  "grid and its worst plant; - where the row was not run on the grid (a row "
                  "measured or merged without --worst-case).", ""]
    for level in report["levels"]:
        lines += [f"## {level}", "",
                  "| # | controller | mode | success | worst plant | median settle | "
                  "settle / T* (median, worst) | mean abs torque [N m] |"
                  + (" grid (worst plant) |" if grid else ""),
                  "|---|---|---|---|---|---|---|---|" + ("---|" if grid else "")]
        for mode in ("plain", "compensated"):
            for k, r in enumerate(ranked_in(report, level, mode), 1):
                worst = ("-" if r["worst_plant"] is None
                         else f"{r['worst_plant_successes']}/{r['n'] // report['plants']}")
                lines.append(f"| {k} | {r['controller']} | {r['mode']} | "
                             f"{format_rate(r['successes'], r['n'])} | {worst} | "
                             f"{_settle(r['median_settle'])} | "
                             f"{_ratio(r['settle_ratio_median'])}, "
                             f"{_ratio(r['settle_ratio_worst'])} | "
                             f"{r['mean_abs_torque']:.3f} |" + (_grid_cell(r) if grid else ""))
        lines.append("")
    return "\n".join(lines + learning_lines(report))


def learning_lines(report: dict) -> list:
    """The section on what the learned rows cost to learn (the report's ``learning``:
    every seed trained, the chosen one marked), or nothing."""
    learning = report.get("learning") or {}
    if not learning:
        return []
    lines = ["## Cost of learning", "",
             "Every seed trained for a row is paid for: environment steps, CPU and wall "
             "time summed over the seeds; each seed's score is its final evaluation on the "
             "training plants (never the leaderboard's), the row's agent the best of them.",
             "", "| controller | seeds (final score on training plants) | env steps | "
             "CPU | wall | CPU per env step |", "|---|---|---|---|---|---|"]
    for name, c in sorted(learning.items()):
        seeds = ", ".join(f"{s['seed']} ({s['successes']}/{s['n']}"
                          f"{', chosen' if s['seed'] == c.get('chosen_seed') else ''})"
                          for s in c["seeds"])
        per_step = 1e6 * c["cpu_s"] / c["steps"] if c["steps"] else float("nan")
        lines.append(f"| {name} | {seeds} | {c['steps'] / 1e6:.2f} M | "
                     f"{c['cpu_s'] / 60:.1f} min | {c['wall_s'] / 60:.1f} min | "
                     f"{per_step:.0f} µs |")
    return lines + [""]


def _grid_cell(row: dict) -> str:
    g = row.get("grid")
    if g is None:
        return " - |"
    return (f" {format_rate(g['successes'], g['n'])} "
            f"({g['worst_plant_successes']}/{g['states']}) |")


def _column_name(level: str, mode: str) -> str:
    return level + (" + comp." if mode == "compensated" else "")


def compact(report: dict, names=None, *, code: bool = True) -> str:
    """A short Markdown table of ``names``' rows (default: every controller of
    ``report``): a success percentage per level and mode, the median settle / T* at the
    first level, the best cell of each column in bold (:mod:`.ranking`'s rule among these
    rows), a mark with its reason under the table for each blank cell, and one line per
    level naming the best. Rows in their rank under the last level, plain."""
    rows = [r for r in report["rows"] if names is None or r["controller"] in set(names)]
    sub = {**report, "rows": rows}
    fam = families(dict.fromkeys(r["controller"] for r in rows))
    cols = columns(sub)
    by = {(r["controller"], r["level"], r["mode"]): r for r in rows}
    last = report["levels"][-1]
    order = [r["controller"] for r in ranked_in(sub, last, "plain")]
    order += sorted(n for n in fam if n not in order)
    best = {c: (ranked_in(sub, *c) or [None])[0] for c in cols}
    first = report["levels"][0]
    used = set()

    def cell(n, level, mode):
        r = by.get((n, level, mode))
        if r is None:
            mark = "—" if mode == "compensated" and (n, level, "plain") in by else "·"
            used.add(mark)
            return mark
        text = percent(r["successes"], r["n"])
        return f"**{text}**" if r is best[(level, mode)] and r["successes"] else text

    def label(n):
        return f"`{n}`" if code else n

    header = ("controller", "family", *[_column_name(*c) for c in cols],
              f"settle / T* ({first})")
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    for n in order:
        r0 = by.get((n, first, "plain"))
        lines.append("| " + " | ".join([label(n), fam[n], *[cell(n, *c) for c in cols],
                                        "·" if r0 is None else _ratio(
                                            r0["settle_ratio_median"])]) + " |")
    lines.append("")
    for level in report["levels"]:
        parts = []
        for mode in ("plain", "compensated"):
            b = best.get((level, mode))
            if b is not None and not b["successes"]:
                parts.append("none succeeds" if mode == "plain"
                             else "with compensation none succeeds")
            elif b is not None:
                what = (f"{label(b['controller'])} ({percent(b['successes'], b['n'])}, "
                        f"settle / T* {_ratio(b['settle_ratio_median'])})")
                parts.append(what if mode == "plain" else f"with compensation {what}")
        if parts:
            lines.append(f"- best under **{level}**: " + "; ".join(parts))
    notes = [f"{m} {why}" for m, why in BLANKS.items() if m in used]
    if notes:
        lines += ["", "; ".join(notes) + "."]
    return "\n".join(lines)


def standing_lines(report: dict, controller: str) -> list:
    """``NAME ranks k of M under LEVEL (mode): k/n = p % [lo, hi], settle / T* x`` for
    every column ``controller`` has a row in (:func:`.ranking.standings`)."""
    return [f"{controller} ranks {k} of {m} under {level} ({mode}): "
            f"{format_rate(r['successes'], r['n'])}, settle / T* "
            f"{_ratio(r['settle_ratio_median'])}"
            for level, mode, k, m, r in standings(report, controller)]


def figure_of(report: dict):
    """The leaderboard's matplotlib figure (:func:`twolink.viz.leaderboard.leaderboard_figure`):
    families from the catalogue, the :func:`labelled` controllers, each panel titled with
    its level's best labelled controller in the plain mode (:mod:`.ranking`)."""
    from twolink.viz.leaderboard import leaderboard_figure

    names = list(dict.fromkeys(r["controller"] for r in report["rows"]))
    shown = labelled(report)
    titles = {}
    for level in report["levels"]:
        top = ranked([r for r in report["rows"] if r["level"] == level
                      and r["mode"] == "plain" and r["controller"] in shown])
        titles[level] = level if not top else (
            f"{level}: best {top[0]['controller']} "
            f"({percent(top[0]['successes'], top[0]['n'])})")
    return leaderboard_figure(report, families=families(names), labelled=shown,
                              titles=titles)


def figure(report: dict, path: os.PathLike) -> Path:
    """Write the figure of :func:`figure_of` as a PNG at ``path``."""
    from twolink.viz.leaderboard import save_png

    return save_png(figure_of(report), path)


def write(report: dict, out: os.PathLike, *, files=tuple(FILES)) -> dict:
    """Write ``files`` (default the Markdown, the JSON with provenance and the figure)
    into ``out`` (made if missing), all or none (:func:`twolink.artifacts.staged_set`);
    their paths."""
    out = Path(out)
    with staged_set(out) as staging:
        if "json" in files:
            write_json(staging / FILES["json"], {**report, "provenance": provenance()})
        if "markdown" in files:
            write_text(staging / FILES["markdown"], markdown(report) + "\n")
        if "figure" in files:
            figure(report, staging / FILES["figure"])
    return {k: out / v for k, v in FILES.items() if k in files}
