"""The tuning table in Markdown: one row per variant, a column per condition (k/n
[95 % interval] and the median settle time) and the settle / T* column.
"""
from __future__ import annotations

from twolink.sim.metrics import wilson_interval

COLUMNS = ("none", "medium", "medium compensated", "hard", "hard compensated")


def ratio_text(cell) -> str:
    """The settle / T* cell: median and worst over the tuning grid, or '-' (a row measured
    before the column existed)."""
    if cell is None:
        return "-"
    med = "never" if cell["median"] is None else f"{cell['median']:.2f}"
    worst = "never" if cell["worst"] is None else f"{cell['worst']:.2f}"
    return f"{med}, {worst} ({cell['successes']}/{cell['n']})"


def markdown(rows: list) -> str:
    """The Markdown table of ``rows`` (as :func:`.measure.measure` returns them)."""
    def fmt(c):
        lo, hi = wilson_interval(c["successes"], c["n"])
        settle = "never" if c["median_settle"] is None else f"{c['median_settle']:.2f} s"
        return f"{c['successes']}/{c['n']} [{100 * lo:.0f}, {100 * hi:.0f}] {settle}"
    lines = ["| variant | " + " | ".join(COLUMNS) + " | settle / T* |",
             "|---" * (len(COLUMNS) + 2) + "|"]
    lines += [f"| {r['variant']} | " + " | ".join(fmt(r[c]) for c in COLUMNS)
              + f" | {ratio_text(r.get('ratio'))} |" for r in rows]
    return "\n".join(lines)
