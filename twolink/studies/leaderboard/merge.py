"""Adding controllers to a leaderboard already written, without running the others again.

A leaderboard's rows are independent: each is one controller under one level in one
mode, run from the same states on the same plants with the same noise (the seed's). So
the rows of new or changed controllers, run with the saved report's settings, can replace
or join its rows and give the table a full run would (``twolink leaderboard --merge``).
"""
from __future__ import annotations

import json
import math
from pathlib import Path

#: What rows must share to sit in one table.
SETTINGS = ("states", "plants", "seed", "horizon", "limits")
#: The ranges the command's options allow (``--plants``, ``--seed``).
MAX_PLANTS = 10_000
MAX_SEED = 2**63 - 1


def _is_int(v) -> bool:
    return isinstance(v, int) and not isinstance(v, bool)


def _is_number(v) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)


def _check_settings(report: dict) -> str | None:
    """What is wrong with the settings of a saved report, or None."""
    from twolink.sim.challenges import LEVELS

    missing = [k for k in ("command", "rows", "levels", *SETTINGS) if k not in report]
    if missing:
        return f"no {', '.join(missing)} (not a leaderboard report)"
    if not isinstance(report["rows"], list):
        return "rows is not a list"
    if not _is_int(report["states"]) or report["states"] < 1:
        return f"states must be a positive whole number, got {report['states']!r}"
    if not _is_int(report["plants"]) or not 1 <= report["plants"] <= MAX_PLANTS:
        return f"plants must be a whole number from 1 to {MAX_PLANTS}, got {report['plants']!r}"
    if not _is_int(report["seed"]) or not 0 <= report["seed"] <= MAX_SEED:
        return f"seed must be a whole number from 0 to 2**63 - 1, got {report['seed']!r}"
    if not _is_number(report["horizon"]) or report["horizon"] <= 0:
        return f"horizon must be a positive finite number, got {report['horizon']!r}"
    if not isinstance(report["limits"], str) or not isinstance(report["command"], str):
        return "limits and command must be text"
    levels = report["levels"]
    if not isinstance(levels, list) or not levels or \
            any(not isinstance(v, str) or v not in LEVELS for v in levels) or \
            len(set(levels)) < len(levels):
        return (f"levels must be distinct names among {', '.join(LEVELS)}, got "
                f"{levels!r}")
    return _check_learning(report.get("learning", {}))


def _check_learning(learning) -> str | None:
    """What is wrong with a report's ``learning`` (name -> learning cost), or None."""
    if not isinstance(learning, dict):
        return "learning is not an object"
    for name, cost in learning.items():
        if not isinstance(cost, dict) or not isinstance(cost.get("seeds"), list) or \
                not all(_is_number(cost.get(k)) and cost[k] >= 0
                        for k in ("steps", "cpu_s", "wall_s")):
            return f"learning of {name} lacks seeds, steps, cpu_s or wall_s"
        for s in cost["seeds"]:
            if not isinstance(s, dict) or not all(
                    _is_number(s.get(k)) for k in ("seed", "steps", "cpu_s", "successes", "n")):
                return f"learning of {name} has a seed without seed, steps, cpu_s or score"
    return None


def _check_row(row, report: dict) -> str | None:
    """What is wrong with one saved row, or None."""
    from twolink.studies.leaderboard.measure import MODES

    if not isinstance(row, dict):
        return f"is not an object ({type(row).__name__})"
    missing = [k for k in ROW_KEYS if k not in row]
    if missing:
        return f"no {', '.join(missing)}"
    if not isinstance(row["controller"], str) or not row["controller"]:
        return f"controller {row['controller']!r}: not a name"
    if row["level"] not in report["levels"]:
        return f"level {row['level']!r}: not among the report's levels"
    if row["mode"] not in MODES:
        return f"mode {row['mode']!r}: not one of {', '.join(MODES)}"
    n, k = row["n"], row["successes"]
    if not _is_int(n) or n < 1:
        return f"n {n!r}: not a positive whole number"
    if not _is_int(k) or not 0 <= k <= n:
        return f"successes {k!r}: not a whole number from 0 to n ({n})"
    if not _is_number(row["rate"]) or abs(row["rate"] - k / n) > 1e-9:
        return f"rate {row['rate']!r}: not successes / n ({k}/{n})"
    w = row["wilson_95"]
    if not isinstance(w, list) or len(w) != 2 or not all(_is_number(v) and 0 <= v <= 1
                                                         for v in w):
        return f"wilson_95 {w!r}: not two numbers from 0 to 1"
    if row["worst_plant"] is not None and (not _is_int(row["worst_plant"])
                                           or row["worst_plant"] < 0):
        return f"worst_plant {row['worst_plant']!r}: not a plant index or null"
    wk = row["worst_plant_successes"]
    if wk is not None and (not _is_int(wk) or not 0 <= wk <= n):
        return f"worst_plant_successes {wk!r}: not a whole number from 0 to n ({n}) or null"
    for key in ("median_settle", "settle_ratio_median", "settle_ratio_worst"):
        v = row[key]
        if v is not None and (not _is_number(v) or v < 0):
            return f"{key} {v!r}: not a non-negative finite number or null"
    for key in ("mean_abs_torque", "seconds"):
        v = row[key]
        if not _is_number(v) or v < 0:
            return f"{key} {v!r}: not a non-negative finite number"
    if "grid" in row:
        g = row["grid"]
        if not isinstance(g, dict) or not all(_is_int(g.get(k)) and g[k] >= 0 for k in (
                "successes", "n", "worst_plant_successes", "states")) \
                or not isinstance(g.get("worst_plant"), str) or g["successes"] > g["n"]:
            return "grid: not a worst case over the level's grid (successes, n, states, " \
                   "worst_plant, worst_plant_successes)"
    return None


#: The keys of a saved row (:meth:`twolink.studies.leaderboard.measure.Entry.as_dict`).
ROW_KEYS = ("controller", "level", "mode", "successes", "n", "rate", "wilson_95",
            "worst_plant", "worst_plant_successes", "median_settle", "settle_ratio_median",
            "settle_ratio_worst", "mean_abs_torque", "seconds")


def saved_report(path: Path) -> dict:
    """The leaderboard JSON at ``path``, checked as strictly as the command's options
    (settings in the ranges --plants and --seed allow, every row of the schema
    :data:`ROW_KEYS` with finite numbers, no two rows of one controller, level and
    mode), or a one-line ValueError ``leaderboard report PATH: ...`` naming the first
    problem (rows counted from 1)."""
    what = f"leaderboard report {path}"
    try:
        text = Path(path).read_text()
    except FileNotFoundError:
        raise ValueError(f"--merge: {path} does not exist; run the leaderboard once "
                         f"without --merge") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise ValueError(f"{what}: cannot be read ({exc})") from None
    try:
        report = json.loads(text, parse_constant=_no_constant)
    except ValueError as exc:
        raise ValueError(f"{what}: not valid JSON ({exc})") from None
    if not isinstance(report, dict):
        raise ValueError(f"{what}: not a leaderboard report (a JSON "
                         f"{type(report).__name__}, not an object)")
    problem = _check_settings(report)
    if problem:
        raise ValueError(f"{what}: {problem}")
    seen = set()
    for i, row in enumerate(report["rows"], 1):
        problem = _check_row(row, report)
        if problem:
            raise ValueError(f"{what}: row {i} has {problem}")
        key = (row["controller"], row["level"], row["mode"])
        if key in seen:
            raise ValueError(f"{what}: row {i} has {key[0]} {key[1]} {key[2]} a second time")
        seen.add(key)
    return report


def _no_constant(name):
    raise ValueError(f"{name} is not a number JSON allows")


def check_joinable(saved: dict, settings: dict, levels) -> None:
    """A one-line ValueError, before any measurement, when rows run with ``settings``
    (the keys of :data:`SETTINGS`) under ``levels`` cannot join the saved report."""
    differ = [k for k in SETTINGS if saved[k] != settings[k]]
    if differ:
        raise ValueError("--merge: the saved leaderboard was run with other settings ("
                         + ", ".join(f"{k} {saved[k]!r} here {settings[k]!r}" for k in differ)
                         + ")")
    if set(levels) - set(saved["levels"]):
        raise ValueError(f"--merge: levels {sorted(set(levels) - set(saved['levels']))} "
                         f"are not in the saved leaderboard ({', '.join(saved['levels'])})")


def merged(saved: dict, new: dict) -> dict:
    """``saved`` with the rows of ``new``'s controllers replaced by ``new``'s rows (new
    controllers after the saved ones), or a ValueError when the settings differ."""
    check_joinable(saved, new, new["levels"])
    replaced = {r["controller"] for r in new["rows"]}
    rows = [r for r in saved["rows"] if r["controller"] not in replaced] + new["rows"]
    learning = {name: cost for name, cost in saved.get("learning", {}).items()
                if name not in replaced}
    learning.update(new.get("learning", {}))
    out = {**saved, "rows": rows, "provenance": new.get("provenance", saved.get("provenance"))}
    out.pop("learning", None)
    return {**out, **({"learning": learning} if learning else {})}
