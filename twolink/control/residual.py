"""Residual learning over a fixed base controller (Johannink et al. 2019, Silver et al.
2018): the agent's action a in [-1, 1]^N adds to the torque of a base controller,

    tau_i = clip(base_i(x) + tau_max_i a_i, -tau_max_i, tau_max_i),

so with a = 0 the agent is its base. :data:`BASES` names the bases: ``'none'`` (the agent
alone, tau = tau_max a) and ``'pd'``, the per-joint saturated PD of
:mod:`twolink.control.links_pd` with the (sat_deg, zeta) of its ``TUNED`` table (N = 3 to
6 links): joint i's base sees only its own angle and speed, so a residual agent over it
stays decentralized-compatible.

An agent records its base in its ``twolink.json`` (:mod:`twolink.control.agent_meta`; a
multi-agent save in its header, :mod:`twolink.control.marl_agent`):
``"base": "pd"`` with ``"base_gains": {"sat_deg": ..., "zeta": ...}``, the gains it was
trained over, so a later retuning of ``TUNED`` never changes a saved agent.
:func:`agent_base` reads them back (no ``base``: ``'none'``); an unknown base or
unreadable gains is one :class:`~twolink.sim.controller.ControllerError` line.
"""
from __future__ import annotations

import json
import math

import numpy as np

from twolink.sim.controller import ControllerError

#: The base controllers a residual agent may act over.
BASES = ("none", "pd")


def check_base(base, links: int) -> str:
    """``base`` if it is one of :data:`BASES` and has gains for ``links`` links; else
    one ValueError line."""
    if base not in BASES:
        raise ValueError(f"base must be one of {', '.join(BASES)}, got {base!r}")
    if base == "pd" and links < 3:
        raise ValueError(f"base pd is the tuned per-joint PD of 3 to 6 links "
                         f"(twolink.control.links_pd.TUNED); this arm has {links} links")
    return base


def base_gains(base: str, params) -> dict | None:
    """The gains recorded for ``base`` on the arm ``params`` (None for ``'none'``): the
    ``TUNED`` (sat_deg, zeta) of its links and rule."""
    if base == "none":
        return None
    from twolink.control.links_pd import TUNED
    from twolink.arm.parameters import as_links

    c = as_links(params)
    got = TUNED.get((c.links, c.rule))
    if got is None:
        raise ValueError(f"no tuned PD gains for {c.links} {c.rule} links; tuned: "
                         f"{sorted(TUNED)}")
    return {"sat_deg": got["sat_deg"], "zeta": got["zeta"]}


def base_controller(base: str, params, gains: dict | None = None):
    """The base controller (states (..., 2N) -> torques (..., N)) of ``base`` on the arm
    ``params``: None for ``'none'``, the :func:`twolink.control.links_pd.make_links_pd` of
    ``gains`` (default :func:`base_gains`) for ``'pd'``."""
    check_base(base, params.links)
    if base == "none":
        return None
    from twolink.control.links_pd import make_links_pd

    gains = gains or base_gains(base, params)
    return make_links_pd(params, gains["sat_deg"], gains["zeta"], name="base_pd")


def residual_torques(base, x, action, tau_max) -> np.ndarray:
    """Torques (..., N): ``clip(base(x) + tau_max a, -tau_max, tau_max)`` with the action
    a clipped to [-1, 1] (``base`` None: ``tau_max a``)."""
    tau = np.asarray(tau_max, dtype=float)
    u = np.clip(np.asarray(action, dtype=float), -1.0, 1.0) * tau
    if base is None:
        return u
    return np.clip(base(x) + u, -tau, tau)


def agent_base(path, extra: bytes | None, params):
    """(base name, base controller or None) of a saved agent from its ``twolink.json``
    bytes ``extra`` (none, or no ``base`` field: ``'none'``); one ControllerError line
    for a base this version does not know or gains that are not two positive numbers."""
    meta = json.loads(extra) if extra is not None else {}
    return base_of(path, meta if isinstance(meta, dict) else {}, params)


def base_of(path, meta: dict, params, where: str = "twolink.json"):
    """(base name, base controller or None) of the record ``meta`` of a saved agent (its
    ``twolink.json``, or a multi-agent save's header: ``where``), checked as
    :func:`agent_base` says."""
    base = meta.get("base", "none")
    if base not in BASES:
        shown = " ".join(str(base).split())[:30]
        raise ControllerError(f"{path}: its {where} names the base controller "
                              f"{shown!r}, which this version does not know (it knows "
                              f"{', '.join(BASES)})")
    if base == "none":
        return base, None
    gains = meta.get("base_gains")
    ok = isinstance(gains, dict) and set(gains) == {"sat_deg", "zeta"} and all(
        isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)
        and v > 0 for v in gains.values())
    if not ok or params.links < 3:
        raise ControllerError(f"{path}: its {where} gives base pd without gains "
                              f"{{sat_deg, zeta}} (two positive numbers) for its "
                              f"{params.links} links")
    return base, base_controller(base, params, gains)
