"""How numbers are written in tables and reports (presentation only)."""
from __future__ import annotations

from twolink.sim.metrics import wilson_interval

#: From this many trials on, the interval is written to a tenth of a percent (it is
#: narrower than a percent: 2077/2080 is [99.6, 100.0], not [100, 100]).
FINE_FROM = 1000


def format_rate(successes: int, n: int) -> str:
    """``k/n = p % [lo, hi]``: a success rate with its count and 95 % Wilson interval
    (bounds in whole percent, or to 0.1 % from :data:`FINE_FROM` trials on)."""
    lo, hi = wilson_interval(successes, n)
    d = 1 if n >= FINE_FROM else 0
    return f"{successes}/{n} = {100 * successes / n:.1f} % [{100 * lo:.{d}f}, {100 * hi:.{d}f}]"
