"""The leaderboard's ranking rule, stated once (:data:`RULE`) and applied by
:func:`ranked` wherever rows are ranked: the report's tables, the command's
``ranks k of M`` lines, the README's table and its best-per-level line, the figure's
labels and the docs pages.

Rows are ranked within one level and one mode (a compensated row competes with the
other compensated rows of its level). Success comes first, but two rates whose 95 %
Wilson intervals overlap are not called different (docs/conventions.md), so rows are
placed in tiers: the row with the highest success rate not yet placed leads a tier,
every unplaced row whose interval overlaps the leader's joins it, and inside a tier the
shorter median settle / T* ranks first (a row that never settles, last), then the
higher success rate, then the name.
"""
from __future__ import annotations

import math

from twolink.sim.metrics import wilson_interval

#: The rule in words: the report, the guide and the command print this text.
RULE = ("Ranking, per level and mode: highest success rate first; rows whose 95 % Wilson "
        "intervals overlap that of the best row not yet placed tie with it, and a tie goes "
        "to the shorter median settle / T* (never settled last), then the higher rate, "
        "then the name.")


def _interval(row: dict) -> tuple[float, float]:
    return wilson_interval(row["successes"], row["n"])


def _settle(row: dict) -> float:
    v = row.get("settle_ratio_median")
    return math.inf if v is None else float(v)


def ranked(rows) -> list:
    """``rows`` (leaderboard row dicts of one level and mode) in the order of
    :data:`RULE`, best first."""
    pending = sorted(rows, key=lambda r: (-r["rate"], _settle(r), r["controller"]))
    out = []
    while pending:
        lead_lo = _interval(pending[0])[0]
        # The leader has the highest rate left, so an interval overlaps its interval
        # exactly when it reaches the leader's lower bound.
        tier = [r for r in pending if _interval(r)[1] >= lead_lo]
        tier.sort(key=lambda r: (_settle(r), -r["rate"], r["controller"]))
        out += tier
        placed = {id(r) for r in tier}
        pending = [r for r in pending if id(r) not in placed]
    return out


def columns(report: dict) -> list:
    """The (level, mode) pairs of ``report`` that hold rows, levels in the report's order,
    plain before compensated."""
    present = {(r["level"], r["mode"]) for r in report["rows"]}
    return [(lv, m) for lv in report["levels"] for m in ("plain", "compensated")
            if (lv, m) in present]


def ranked_in(report: dict, level: str, mode: str) -> list:
    """The rows of ``report`` under ``level`` in ``mode``, ranked (:func:`ranked`)."""
    return ranked([r for r in report["rows"] if r["level"] == level and r["mode"] == mode])


def best(report: dict, level: str, mode: str = "plain") -> dict | None:
    """The first row of ``level`` in ``mode`` under :data:`RULE` (None when there is none)."""
    rows = ranked_in(report, level, mode)
    return rows[0] if rows else None


def standings(report: dict, controller: str) -> list:
    """``[(level, mode, k, M, row)]``: where ``controller`` ranks (k of M, from 1) in every
    column of ``report`` it has a row in."""
    out = []
    for level, mode in columns(report):
        rows = ranked_in(report, level, mode)
        for k, r in enumerate(rows, 1):
            if r["controller"] == controller:
                out.append((level, mode, k, len(rows), r))
    return out
