"""Adding controllers to a leaderboard already written, without running the others again.

A leaderboard's rows are independent: each is one controller under one level in one
mode, run from the same states on the same plants with the same noise (the seed's). So
the rows of new or changed controllers, run with the saved report's settings, can replace
or join its rows and give the table a full run would (``twolink leaderboard --merge``).
"""
from __future__ import annotations

import json
from pathlib import Path

#: What rows must share to sit in one table.
SETTINGS = ("states", "plants", "seed", "horizon", "limits")


def saved_report(path: Path) -> dict:
    """The leaderboard JSON at ``path``, or a ValueError naming what is wrong with it."""
    try:
        report = json.loads(Path(path).read_text())
    except FileNotFoundError:
        raise ValueError(f"--merge: {path} does not exist; run the leaderboard once "
                         f"without --merge") from None
    except (OSError, ValueError) as exc:
        raise ValueError(f"--merge: {path} is not a leaderboard JSON ({exc})") from None
    if not isinstance(report, dict) or not isinstance(report.get("rows"), list) or \
            any(k not in report for k in SETTINGS + ("levels",)):
        raise ValueError(f"--merge: {path} is not a leaderboard JSON (no rows or settings)")
    return report


def merged(saved: dict, new: dict) -> dict:
    """``saved`` with the rows of ``new``'s controllers replaced by ``new``'s rows (new
    controllers after the saved ones), or a ValueError when the settings differ."""
    differ = [k for k in SETTINGS if saved[k] != new[k]]
    if differ:
        raise ValueError("--merge: the saved leaderboard was run with other settings ("
                         + ", ".join(f"{k} {saved[k]!r} here {new[k]!r}" for k in differ)
                         + ")")
    if set(new["levels"]) - set(saved["levels"]):
        raise ValueError(f"--merge: levels {sorted(set(new['levels']) - set(saved['levels']))} "
                         f"are not in the saved leaderboard ({', '.join(saved['levels'])})")
    replaced = {r["controller"] for r in new["rows"]}
    rows = [r for r in saved["rows"] if r["controller"] not in replaced] + new["rows"]
    return {**saved, "rows": rows, "provenance": new.get("provenance", saved.get("provenance"))}
