"""The arm a saved deep-RL agent was trained on: the optional ``twolink.json`` member of
its Stable-Baselines3 ``.zip`` (:mod:`twolink.control.sb3_agent`), written by
``twolink train`` (:mod:`twolink.training`).

``{"schema": "twolink.agent", "version": 1, "links": N, "rule": "tapered"|"copied"}``:
N must equal the size of the saved action space; the rule picks the arm of
:func:`twolink.arm.parameters.links_parameters` whose tau_max scales the actions (two links: Table
I, rule ``None``). A two-link save without the member is Table I's arm.
"""
from __future__ import annotations

import json

from twolink.arm.parameters import LINK_RULES
from twolink.sim.controller import ControllerError

#: The member's name inside the save.
AGENT_MEMBER = "twolink.json"
#: Its schema and version.
AGENT_SCHEMA, AGENT_VERSION = "twolink.agent", 1


def agent_record(links: int, rule: str | None, **extra) -> dict:
    """The member's content for an agent of ``links`` links and link ``rule`` (None for
    two links), with ``extra`` fields (algorithm, steps, ...) beside them."""
    return {"schema": AGENT_SCHEMA, "version": AGENT_VERSION, "links": int(links),
            "rule": None if links == 2 else rule, **extra}


def _short(value, limit: int = 30) -> str:
    text = " ".join(str(value).split())
    return text if len(text) <= limit else text[:limit - 3] + "..."


def agent_arm(path, links: int, extra: bytes | None) -> tuple:
    """(links, rule) of the agent saved at ``path`` whose action space has ``links``
    components (checked already), checked against the member's bytes ``extra`` when the
    save holds one; one-line ControllerError for a member that is not the agent schema,
    disagrees with the action space, or is missing for N > 2 (the rule is needed)."""
    if extra is None:
        if links == 2:
            return 2, None
        raise ControllerError(f"{path}: a {links}-link agent must name its arm's link rule in "
                              f"a {AGENT_MEMBER} member (twolink train writes one)")
    try:
        meta = json.loads(extra)
    except (ValueError, UnicodeDecodeError, RecursionError):
        meta = None
    if not (isinstance(meta, dict) and meta.get("schema") == AGENT_SCHEMA
            and meta.get("version") == AGENT_VERSION):
        raise ControllerError(f"{path}: its {AGENT_MEMBER} is not a {AGENT_SCHEMA} version "
                              f"{AGENT_VERSION} record")
    if isinstance(meta.get("links"), bool) or meta.get("links") != links:
        raise ControllerError(f"{path}: its {AGENT_MEMBER} says {_short(meta.get('links'))} "
                              f"links, its action space {links}")
    rule = meta.get("rule")
    if rule not in LINK_RULES and not (links == 2 and rule is None):
        raise ControllerError(f"{path}: its {AGENT_MEMBER} names the link rule {_short(rule)}; "
                              f"choose one of {', '.join(LINK_RULES)}")
    return links, (None if links == 2 else rule)


def agent_observation(path, extra: bytes | None, size, links: int) -> tuple:
    """(history length K, observation) of a saved agent of ``links`` links whose saved
    observation space has ``size`` numbers: the history K (and its recorded layout) of
    its ``twolink.json`` (K = 1 without one), and the observation per sample (2N numbers:
    ``'state'``, 3N: ``'cos_sin'``) that, stacked K times with K - 1 actions of N
    (:mod:`twolink.control.history`), makes ``size``. One ControllerError line for a
    history length out of range or a size or recorded layout that disagrees."""
    from twolink.control.history import MAX_HISTORY, history_layout, history_size

    meta = json.loads(extra) if extra is not None else {}
    k = meta.get("history", 1) if isinstance(meta, dict) else 1
    if isinstance(k, bool) or not isinstance(k, int) or not 1 <= k <= MAX_HISTORY:
        raise ControllerError(f"{path}: its {AGENT_MEMBER} says history {_short(k)}; a "
                              f"history is a whole number of samples from 1 to {MAX_HISTORY}")
    by_size = {history_size(k, 2 * links, links): ("state", 2 * links),
               history_size(k, 3 * links, links): ("cos_sin", 3 * links)}
    if size not in by_size:
        raise ControllerError(
            f"{path}: the agent observes shape {_short(size, 40)}; a {links}-link agent "
            f"with a history of {k} observes {history_size(k, 2 * links, links)} (state) or "
            f"{history_size(k, 3 * links, links)} (cos/sin) numbers")
    observation, d = by_size[size]
    layout = meta.get("observation_layout")
    if layout is not None and layout != history_layout(k, d, links):
        raise ControllerError(f"{path}: its {AGENT_MEMBER} records the observation layout "
                              f"{_short(layout, 60)}, not that of its history {k} and "
                              f"observation space ({size} numbers)")
    return k, observation
