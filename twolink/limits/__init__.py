"""The physical limit T*(x): the fewest samples in which any admissible torque sequence
brings the arm from x into the goal band to stay.

Admissible: zero-order-hold torques with |tau_i| <= tau_max_i in every sample period
Ts, speeds within +-2 pi rad/s at the end of every sample (Table I; the plants saturate
them there), on the full model (6)-(8) or the simplified model (11), each sampled with the
package's own RK4 (:data:`twolink.arm.integrate.SUBSTEPS` substeps per Ts) written in
CasADi symbols (:mod:`.symbolic`). The goal band is |theta_i| <= 5 deg, |dtheta_i| <= 0.1
rad/s for both links, reached around 0 or around 2 pi k_i (the angles wrap).

Direct multiple shooting solved by IPOPT (:mod:`.nlp`), searched over N, windings and
initial guesses (:mod:`.search`), gives for each state

* ``lower``: the smallest N at which the reach problem (band at sample N) was found
  feasible; N - 1 failed from every initial guess and winding tried;
* ``upper``: the smallest N for which a sequence reaching the band at N and holding it
  (band over N..N+hold, then at rest, zero torque after) replays on the numpy model in
  the band at every later sample of the horizon.

``lower == upper`` pins T*(x) down (up to IPOPT being a local solver).

    >>> from twolink.limits import limit
    >>> r = limit([-1, -3, 0, 0], "full")            # doctest: +SKIP
    >>> r.samples, r.seconds, r.lower, r.upper       # doctest: +SKIP

:func:`limit` solves one state, :func:`limit_table` many (in worker processes),
:func:`shipped_limits` reads the table of the 65 evaluation states shipped in
``data/limits.json`` (no CasADi needed). CasADi comes with ``pip install
'twolink[limits]'``. For arms of N links, :mod:`.links` asks the question at a deadline:
whether a pose can be brought to rest in the band by then at all (the ceiling of the
N-link success rates).
"""
from __future__ import annotations

import datetime
import multiprocessing
import os
import signal
import time
from concurrent.futures import ProcessPoolExecutor

import numpy as np

from twolink.arm.integrate import SUBSTEPS
from twolink.arm.parameters import GOAL_ANGLE, GOAL_SPEED, TABLE_I, TS, ArmParameters
from twolink.limits.symbolic import (
    INSTALL_HINT,
    MODELS,
    CasadiMissing,
    casadi_version,
    check_model,
    require_casadi,
    step_function,
)
from twolink.limits.search import estimate, replay, search, wrap_state
from twolink.limits.table import (
    FORMAT,
    Limit,
    LimitTable,
    OpenLoop,
    format_table,
    replay_on,
    tables_from_json,
    tables_to_json,
)
from twolink.validate import whole

__all__ = ["INSTALL_HINT", "MODELS", "CasadiMissing", "FORMAT", "Limit", "LimitTable",
           "OpenLoop", "limit", "limit_table", "shipped_limits", "shipped_tables",
           "check_states", "format_table", "replay_on", "step_function", "casadi_version",
           "tables_from_json", "tables_to_json", "provenance", "MAX_SAMPLES",
           "DEFAULT_MAX_SAMPLES", "DEFAULT_STARTS", "MAX_STARTS", "DEFAULT_HOLD", "MAX_HOLD",
           "WINDINGS"]

#: Most samples the search may try (the 5 s evaluation horizon).
MAX_SAMPLES = 100
#: Samples the search tries by default (3 s).
DEFAULT_MAX_SAMPLES = 60
#: Initial guesses per winding at N - 1 (warm, smooth, bang-bang, then random ones).
DEFAULT_STARTS = 3
MAX_STARTS = 10
#: Samples the upper bound holds the band before it must be at rest (0.2 s).
DEFAULT_HOLD = 4
MAX_HOLD = 40
#: Largest |angle| (rad) accepted; angles are wrapped, so more is a typo.
MAX_ANGLE = 1e3


def check_states(states, params: ArmParameters = TABLE_I) -> np.ndarray:
    """``states`` as a float array of shape (n, 4) (one state (4,) gives n = 1): finite,
    |angles| <= 1e3 rad, |speeds| <= the speed limits; else a one-line ValueError."""
    try:
        x = np.array(states, dtype=float)
    except (TypeError, ValueError):
        raise ValueError(f"states must be numbers [theta1, theta2, dtheta1, dtheta2], "
                         f"got {states!r}") from None
    if x.ndim == 1:
        x = x[None]
    if x.ndim != 2 or x.shape[1] != 4 or x.shape[0] == 0:
        raise ValueError(f"states must have shape (4,) or (n, 4) [theta1, theta2, dtheta1, "
                         f"dtheta2], got {np.shape(states)}")
    if not np.all(np.isfinite(x)):
        raise ValueError("states contain NaN or infinite values")
    if np.abs(x[:, :2]).max() > MAX_ANGLE:
        raise ValueError(f"states have an angle of magnitude {np.abs(x[:, :2]).max():.4g} "
                         f"rad, beyond {MAX_ANGLE:g} rad")
    over = np.abs(x[:, 2:]) > params.speed_max * (1 + 1e-12)
    if over.any():
        raise ValueError(f"states have a speed of magnitude {np.abs(x[:, 2:])[over].max():.4g}"
                         f" rad/s, beyond the speed limit {params.speed_max.max():.4g} rad/s")
    return x


def _check_count(name: str, value, top: int) -> int:
    return whole(value, name, 1, top)


#: The winding sets :func:`limit` takes: every winding of :func:`.search.windings`, or
#: the band around 0 of the wrapped angles only.
WINDINGS = ("all", "nearest")


def _settings(max_samples, starts, hold, windings="all") -> dict:
    if windings not in WINDINGS:
        raise ValueError(f"windings must be one of {', '.join(WINDINGS)}, got {windings!r}")
    return {"max_samples": _check_count("max_samples", max_samples, MAX_SAMPLES),
            "starts": _check_count("starts", starts, MAX_STARTS),
            "hold": _check_count("hold", hold, MAX_HOLD), "nearest": windings == "nearest"}


#: Per process: one ProblemCache per parameter set (worker processes keep theirs).
_CACHES: dict = {}


def _solve(job) -> Limit:
    """One state's search in this process (the workers' entry point)."""
    from twolink.limits.nlp import ProblemCache

    x0, model, params, settings, *rest = job
    verbose = bool(rest and rest[0])
    cache = _CACHES.get((params, verbose))
    if cache is None:
        cache = _CACHES[(params, verbose)] = ProblemCache(params, verbose=verbose)
    r = search(np.asarray(x0, float), model, cache, **settings)
    torques = np.zeros((0, 2)) if r.hold is None else r.hold.torques
    x = wrap_state(x0)
    return Limit(x0=tuple(float(v) for v in x), model=model, lower=r.lower, upper=r.upper,
                 winding=tuple(int(v) for v in r.winding), torques=torques,
                 reach_slack=None if r.reach is None else r.reach.s,
                 hold_slack=None if r.hold is None else r.hold.s,
                 solves=r.solves, time_s=r.seconds)


def _ignore_interrupt() -> None:
    """A worker process's start: Ctrl-C (sent to the whole process group) is left to
    the parent, which terminates the workers; SIGTERM ends a worker at once (not the
    parent's handler, whose exception CasADi would swallow mid-solve)."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)


def _in_workers(jobs: list, workers: int) -> list:
    """:func:`_solve` of every job in ``workers`` processes, in order. On any exception
    in this process (Ctrl-C, SIGTERM raised as an exception, an error) the workers are
    terminated at once instead of finishing their searches, and it propagates."""
    method = "fork" if "fork" in multiprocessing.get_all_start_methods() else "spawn"
    pool = ProcessPoolExecutor(max_workers=workers, initializer=_ignore_interrupt,
                               mp_context=multiprocessing.get_context(method))
    try:
        solved = list(pool.map(_solve, jobs, chunksize=1))
    except BaseException:
        processes = list((getattr(pool, "_processes", None) or {}).values())
        pool.shutdown(wait=False, cancel_futures=True)
        for process in processes:
            process.terminate()
        for process in processes:
            process.join(timeout=0.5)
            if process.is_alive():
                process.kill()
                process.join(timeout=0.5)
        raise
    pool.shutdown(wait=True)
    return solved


def _mirrors(x: np.ndarray) -> list:
    """For each row of wrapped states ``x``, the first earlier row equal to its mirror
    image -x (wrapped), else None."""
    image = wrap_state(-x)
    out = []
    for i in range(len(x)):
        hit = np.flatnonzero(np.all(np.abs(x[:i] - image[i]) <= 1e-12, axis=1))
        out.append(int(hit[0]) if hit.size and out[hit[0]] is None else None)
    return out


def _mirrored(row: Limit, j: int, x0, model: str, params, settings) -> Limit:
    """``row`` (the answer of state j) for the mirror state x0, checked by replay."""
    import dataclasses

    torques = -np.asarray(row.torques, float)
    if row.upper is not None and not replay(model, params, x0, torques, row.upper)[1]:
        return _solve((x0, model, params, settings))
    return dataclasses.replace(row, x0=tuple(float(v) for v in x0), torques=torques,
                               winding=tuple(-k for k in row.winding), solves=0,
                               time_s=0.0, mirror_of=j)


def _with_mujoco(rows: list, params) -> list:
    import dataclasses

    idx, settle = replay_on("mujoco", rows, params=params)
    out = list(rows)
    for i, t in zip(idx, settle):
        out[i] = dataclasses.replace(out[i], mujoco_settle=float(t))
    return out


def limit(x0, model: str = "full", *, max_samples: int = DEFAULT_MAX_SAMPLES,
          starts: int = DEFAULT_STARTS, hold: int = DEFAULT_HOLD,
          params: ArmParameters = TABLE_I, mujoco: bool = False,
          windings: str = "all") -> Limit:
    """The limit T*(x0) of one state x0 (4,) on ``model`` (``full`` or ``simplified``).

    ``max_samples`` caps N (at most :data:`MAX_SAMPLES`), ``starts`` is the number of
    initial guesses per winding at N - 1, ``hold`` the samples the upper bound's band
    holds before the arm is at rest. ``mujoco`` also replays the torques open loop on
    the MuJoCo plant (:attr:`Limit.mujoco_settle`). ``windings="nearest"`` restricts the
    band to the one around 0 of the wrapped angles (no extra turn of either link). Bad
    input: a one-line ValueError; CasADi missing: :class:`CasadiMissing` naming
    ``pip install 'twolink[limits]'``.
    """
    check_model(model)
    x = check_states(x0, params)
    if x.shape[0] != 1 or np.ndim(x0) != 1:
        raise ValueError(f"limit takes one state of shape (4,), got shape {np.shape(x0)}; "
                         f"use limit_table for many")
    settings = _settings(max_samples, starts, hold, windings)
    require_casadi()
    row = _solve((x[0], model, params, settings))
    return _with_mujoco([row], params)[0] if mujoco else row


def limit_table(states, model: str = "full", *, max_samples: int = DEFAULT_MAX_SAMPLES,
                starts: int = DEFAULT_STARTS, hold: int = DEFAULT_HOLD,
                params: ArmParameters = TABLE_I, workers: int | None = None,
                mujoco: bool = True, mirror: bool = True,
                windings: str = "all", verbose: bool = False) -> LimitTable:
    """:func:`limit` of every state of ``states`` (n, 4) on ``model``, in ``workers``
    processes (default: one per CPU, at most n), with the run's provenance (CasADi
    version, model, parameters, Ts, substeps, settings, wall time). ``mujoco`` replays
    every upper bound's torques on the MuJoCo plant. ``mirror``: a state whose mirror
    image -x is an earlier row takes that row's answer mirrored (the models are odd:
    f(-x, -u) = -f(x, u)), its torques replayed on the numpy model to check it; a
    mirror that fails the replay is searched itself. ``verbose`` lets IPOPT print its
    iterations (silent by default). Ctrl-C or SIGTERM stops it within an IPOPT
    iteration: the worker processes ignore Ctrl-C and are terminated at once."""
    check_model(model)
    x = check_states(states, params)
    settings = _settings(max_samples, starts, hold, windings)
    if workers is None:
        workers = min(os.cpu_count() or 1, len(x))
    workers = _check_count("workers", workers, 256)
    require_casadi()
    x = wrap_state(x)
    mirrors = _mirrors(x) if mirror else [None] * len(x)
    own = sorted((i for i, m in enumerate(mirrors) if m is None),     # longest first
                 key=lambda i: -estimate(x[i], params))
    jobs = [(x[i], model, params, settings, verbose) for i in own]
    t0 = time.perf_counter()
    if workers == 1 or len(jobs) == 1:
        solved = [_solve(j) for j in jobs]
    else:
        solved = _in_workers(jobs, min(workers, len(jobs)))
    rows = [None] * len(x)
    for i, r in zip(own, solved):
        rows[i] = r
    for i, j in enumerate(mirrors):
        if j is not None:
            rows[i] = _mirrored(rows[j], j, x[i], model, params, settings)
    wall = time.perf_counter() - t0
    if mujoco:
        rows = _with_mujoco(rows, params)
    prov = provenance(params, settings)
    prov.update(model=model, workers=workers, mirror=bool(mirror), time_s=round(wall, 2),
                cpu_time_s=round(sum(r.time_s for r in rows), 2))
    return LimitTable(model=model, rows=tuple(rows), provenance=prov)


def provenance(params: ArmParameters = TABLE_I, settings: dict | None = None) -> dict:
    """What a limits table was computed with: the package, CasADi, numpy, the machine,
    the parameters, Ts, the RK4 substeps, the goal band and the search's settings."""
    from twolink.artifacts import provenance as machine

    settings = dict(settings or {})
    if "nearest" in settings:
        settings["windings"] = "nearest" if settings.pop("nearest") else "all"
    return {**machine(), "casadi_version": casadi_version(), "solver": "ipopt",
            "parameters": params.as_dict(), "ts": TS, "substeps": SUBSTEPS,
            "goal_band": {"angle_rad": GOAL_ANGLE, "speed_rad_s": GOAL_SPEED},
            **settings,
            "created": datetime.datetime.now(datetime.timezone.utc).isoformat(
                timespec="seconds")}


def shipped_tables() -> dict:
    """{model: LimitTable} of the shipped ``data/limits.json`` (the 65 evaluation
    states of :func:`twolink.sim.metrics.evaluation_set` on both models); a damaged file
    gives a one-line ValueError naming it."""
    from twolink.resources import limits_file

    path = limits_file()
    try:
        text = path.read_text()
    except (OSError, UnicodeDecodeError) as exc:
        raise ValueError(f"{path}: cannot be read ({exc})") from None
    return tables_from_json(text, str(path))


def shipped_limits(model: str = "full") -> LimitTable:
    """The shipped table of ``model`` (``full`` or ``simplified``); no CasADi needed."""
    check_model(model)
    tables = shipped_tables()
    if model not in tables:
        raise ValueError(f"the shipped limits have no model {model!r}")
    return tables[model]
