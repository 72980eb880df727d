"""Classical baselines shipped as controllers: saturated decentralized PD (with an
optional dead zone), saturated discrete LQR (with a delay-aware variant) and a per-joint
proximate time-optimal law, each tuned by :mod:`twolink.control.baselines.tuning` off the
evaluation set, the tuned gains shipped in ``gains.json``.

    from twolink.control.baselines import baseline
    lqr = baseline("lqr")            # callable: states (n, 4) -> torques (n, 2)
"""
from twolink.control.baselines.bang_bang import ProximateTimeOptimal
from twolink.control.baselines.lqr import SaturatedLQR
from twolink.control.baselines.pd import SaturatedPD
from twolink.control.baselines.registry import (
    BASELINES,
    baseline,
    from_description,
    load_gains,
)

__all__ = ["BASELINES", "ProximateTimeOptimal", "SaturatedLQR", "SaturatedPD", "baseline",
           "from_description", "load_gains"]
