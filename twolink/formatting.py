"""How numbers are written in tables and reports (presentation only)."""
from __future__ import annotations

from twolink.metrics import wilson_interval


def format_rate(successes: int, n: int) -> str:
    """``k/n = p % [lo, hi]``: a success rate with its count and 95 % Wilson interval."""
    lo, hi = wilson_interval(successes, n)
    return f"{successes}/{n} = {100 * successes / n:.1f} % [{100 * lo:.0f}, {100 * hi:.0f}]"
