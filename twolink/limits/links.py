"""Whether an N-link arm can reach the goal band by a deadline at all: the physical
ceiling of the N-link success rates (``twolink scaling``, ``docs/results/scaling.md``).

For a pose x0 and a deadline of K samples the reach problem asks for admissible torques
(|tau_i| <= tau_max_i, speeds within the links' limits) that bring the N-link arm of
:func:`twolink.arm.dynamics.links_acceleration` (the N-link form of (6)-(9)) from x0 to
rest inside the goal band (|theta_i| <= 5 deg around 0 or 2 pi k_i, every joint) at
sample K. At rest with zero torque the horizontal arm stays there, so a pose reachable by
the deadline 1 s before the end of a horizon can succeed under the success rule of
``twolink.sim.metrics``; one that is not cannot, by any controller.

The problem is solved by direct multiple shooting with IPOPT (CasADi), as the two-link
limits of :mod:`twolink.limits.nlp`, with two differences that keep six
links affordable: each torque is held for ``hold`` samples (a restriction of the
admissible sequences: a pose found reachable stays reachable), integrated with RK4 of
``substeps`` steps over the held period (by default the package's own step size, Ts /
:data:`SUBSTEPS`), and IPOPT uses a limited-memory Hessian. An answer
counts only once its trajectory is one of the package's model to within
:data:`DEFECT_TOL`: from every state of the answer, ``hold`` samples of the package's own
RK4 step (:func:`twolink.arm.integrate.sample_step`, :data:`SUBSTEPS` steps per Ts)
under its torque land on the answer's next state to within that (the largest such gap is
``defect``), and the speeds stay within the links' limits at every sample, those inside
a held period included (:func:`peak_speed`; the NLP bounds them at the periods' ends).

The check is on the defect, not on an open-loop replay of the torques: over 7 s an
open-loop six-link arm amplifies any difference of model or integration (a coarser RK4
step of 0.025 s left defects of 0.2 and replays tens of band widths away), as it does
for any controller, which answers it by feedback.

What a failure means: IPOPT is a local solver, so ``reachable=False`` says that no
sequence was found from the initial guesses tried (the nearest band, then the band a full
turn away for the joints beyond 90 degrees), not that none exists. The count of reachable
poses is therefore a lower bound on the ceiling of the success rate.
"""
from __future__ import annotations

import dataclasses
import math
import time
from typing import Optional

import numpy as np

from twolink.arm.dynamics import links_acceleration, links_weights
from twolink.arm.integrate import SUBSTEPS, rk4
from twolink.arm.parameters import GOAL_ANGLE, TS, LinksParameters, as_links
from twolink.limits.symbolic import require_casadi, rk4_expression
from twolink.validate import whole

#: Torques are held this many samples of Ts in the reach problem (default).
HOLD = 2
#: RK4 steps over one held period in the reach problem (default): the package's step
#: size, Ts / SUBSTEPS.
NLP_SUBSTEPS = HOLD * SUBSTEPS
#: Largest gap (rad, rad/s) between an answer's next state and the package's step from
#: its state: a thousandth of the band's half-width.
DEFECT_TOL = 1e-4
#: The most samples a deadline may have (15 s): the NLP grows with it.
MAX_DEADLINE = 300
#: IPOPT's settings for the reach problem.
IPOPT_OPTIONS = {"ipopt.print_level": 0, "ipopt.sb": "yes", "print_time": False,
                 "ipopt.max_iter": 300, "ipopt.tol": 1e-8,
                 "ipopt.hessian_approximation": "limited-memory"}


def acceleration_expression(ca, p: LinksParameters, x, tau):
    """:func:`twolink.arm.dynamics.links_acceleration` (no joint locked) in CasADi
    symbols: M(theta) ddtheta = tau - C(theta, dtheta) dtheta - diag(b) dtheta with
    M = L^T G L and the bias of the same weights W (:func:`twolink.arm.dynamics.links_weights`)."""
    n = p.links
    w = links_weights(p)
    phi = [None]                                   # absolute angles of links 2..N
    for k in range(1, n):
        phi.append(x[k] if k == 1 else phi[-1] + x[k])

    def cos_diff(a, b):
        return ca.cos(phi[b]) if a == 0 else ca.cos(phi[a] - phi[b])

    def sin_diff(a, b):
        return -ca.sin(phi[b]) if a == 0 else ca.sin(phi[a] - phi[b])

    g = [[None] * n for _ in range(n)]
    for a in range(n):
        g[a][a] = w[a, a] + p.inertias[a]
        for b in range(a + 1, n):
            g[a][b] = g[b][a] = w[a, b] * cos_diff(a, b)
    for a in range(n - 2, -1, -1):                 # M = L^T G L: suffix sums
        for b in range(n):
            g[a][b] = g[a][b] + g[a + 1][b]
    for b in range(n - 2, -1, -1):
        for a in range(n):
            g[a][b] = g[a][b] + g[a][b + 1]
    omega, omega2 = None, []
    for k in range(n):
        omega = x[n + k] if omega is None else omega + x[n + k]
        omega2.append(omega * omega)
    h = [0.0] * n
    for a in range(n):
        for b in range(a + 1, n):
            s = w[a, b] * sin_diff(a, b)
            h[a] = h[a] + s * omega2[b]
            h[b] = h[b] - s * omega2[a]
    for a in range(n - 2, -1, -1):
        h[a] = h[a] + h[a + 1]
    rhs = ca.vertcat(*[tau[k] - h[k] - p.dampings[k] * x[n + k] for k in range(n)])
    mass = ca.vertcat(*[ca.horzcat(*row) for row in g])
    return ca.solve(mass, rhs)


def step_function(p: LinksParameters, *, ts: float = TS, substeps: int = SUBSTEPS):
    """The CasADi Function ``step(x[2N], u[N]) -> x_next[2N]``: RK4 of ``substeps`` steps
    over ``ts`` with the torque held, before the wrap (:func:`sample_step` to round-off)."""
    ca = require_casadi()
    n = p.links
    x, u = ca.SX.sym("x", 2 * n), ca.SX.sym("u", n)
    y = rk4_expression(lambda s: ca.vertcat(s[n:], acceleration_expression(ca, p, s, u)),
                       x, ts, substeps)
    return ca.Function("links_step", [x, u], [y], ["x", "u"], ["x_next"])


@dataclasses.dataclass(frozen=True)
class Reach:
    """The answer for one pose: ``reachable`` once a sequence replayed in the band at
    rest; ``targets`` the band's centres (2 pi k per joint) of that answer (or of the
    last one tried), ``torques`` (K, N) its sequence per sample (None if none), ``status``
    IPOPT's last return status, ``slack`` the last min s (<= 0: the NLP reached the
    band), ``defect`` the largest gap between the answer and the package's step (inf
    without an answer), ``seconds`` the solve time."""

    reachable: bool
    targets: tuple
    torques: Optional[np.ndarray]
    status: str
    slack: float
    defect: float
    seconds: float

    def as_dict(self) -> dict:
        return {"reachable": self.reachable, "targets": list(self.targets),
                "status": self.status, "slack": self.slack,
                "defect": self.defect, "seconds": round(self.seconds, 2)}


def check_deadline(deadline: int, hold: int) -> None:
    """A one-line ValueError unless ``deadline`` (samples) is a whole multiple of ``hold``
    between ``hold`` and :data:`MAX_DEADLINE`."""
    whole(hold, "hold", 1, 20)
    whole(deadline, "deadline", hold, MAX_DEADLINE)
    if deadline % hold:
        raise ValueError(f"deadline {deadline} must be a whole multiple of hold {hold}")


def _solve(ca, step, p, x0, targets, intervals):
    n = p.links
    opti = ca.Opti()
    x = opti.variable(2 * n, intervals + 1)
    u = opti.variable(n, intervals)
    s = opti.variable()
    opti.subject_to(x[:, 0] == x0)
    opti.subject_to(step.map(intervals)(x[:, :intervals], u) == x[:, 1:])
    for k in range(n):
        opti.subject_to(opti.bounded(-p.torque_limits[k], u[k, :], p.torque_limits[k]))
        opti.subject_to(opti.bounded(-p.speed_limits[k], x[n + k, 1:], p.speed_limits[k]))
        opti.subject_to(opti.bounded(-GOAL_ANGLE * (1 + s), x[k, intervals] - targets[k],
                                     GOAL_ANGLE * (1 + s)))
        opti.subject_to(x[n + k, intervals] == 0)
    opti.subject_to(s >= -1)
    opti.minimize(s)
    for j in range(intervals + 1):                 # angles straight to the band, at rest
        opti.set_initial(x[:n, j], x0[:n] + (targets - x0[:n]) * j / intervals)
    opti.set_initial(s, 1.0)
    opti.solver("ipopt", IPOPT_OPTIONS)
    try:
        sol = opti.solve()
        return (opti.stats()["return_status"], float(sol.value(s)),
                np.atleast_2d(sol.value(x)).reshape(2 * n, -1), np.atleast_2d(sol.value(u)).reshape(n, -1))
    except RuntimeError:
        return opti.stats()["return_status"], float(opti.debug.value(s)), None, None


def defect(p: LinksParameters, states: np.ndarray, torques: np.ndarray, hold: int) -> float:
    """The largest gap between ``states`` (K+1, 2N) and ``hold`` samples of the package's
    RK4 step from each of them under ``torques`` (K, N) (no wrap: the answer's angles are
    unwrapped)."""
    return _check_answer(p, states, torques, hold)[0]


def peak_speed(p: LinksParameters, states: np.ndarray, torques: np.ndarray,
               hold: int) -> float:
    """The largest |speed| over the links' speed limits at every sample of the answer,
    the samples inside each held period included (the NLP bounds the speeds only at the
    ends of the periods; <= 1: within the limits)."""
    return _check_answer(p, states, torques, hold)[1]


def _check_answer(p, states, torques, hold) -> tuple:
    states = np.asarray(states, float)
    x, peak = states[:-1], 0.0
    for _ in range(hold):
        x = rk4(links_acceleration, p, x, np.asarray(torques, float), TS, SUBSTEPS)
        peak = max(peak, float((np.abs(x[:, p.links:]) / p.speed_max).max()))
    return float(np.abs(x - states[1:]).max()), peak


def candidate_targets(x0, links: int) -> list:
    """The band centres tried, in order: 0 for every joint (the nearest band of a pose in
    [-pi, pi)), then a full turn the other way round for every joint beyond 90 deg."""
    theta = np.mod(np.asarray(x0[:links], float) + math.pi, 2 * math.pi) - math.pi
    first = 2 * math.pi * np.round((np.asarray(x0[:links], float) - theta) / (2 * math.pi))
    out = [first]
    far = np.abs(theta) > math.pi / 2
    if far.any():
        out.append(first + np.where(far, 2 * math.pi * np.sign(theta), 0.0))
    return out


def reach(p, x0, deadline: int, *, hold: int = HOLD, substeps: int = NLP_SUBSTEPS,
          step=None) -> Reach:
    """Whether the arm ``p`` (an N-link :class:`LinksParameters`) can be brought from
    ``x0`` (2N,) to rest in the goal band by sample ``deadline`` (see the module
    docstring). ``step``: a :func:`step_function` of ``p`` over ``hold`` samples, made
    once and shared by many poses."""
    ca = require_casadi()
    p = as_links(p)
    n = p.links
    x0 = np.asarray(x0, float)
    if x0.shape != (2 * n,) or not np.all(np.isfinite(x0)):
        raise ValueError(f"x0 of a {n}-link arm must be {2 * n} finite numbers, got "
                         f"shape {x0.shape}")
    if np.any(np.abs(x0[n:]) > p.speed_max):
        raise ValueError("x0's speeds must lie within the links' speed limits")
    check_deadline(deadline, hold)
    whole(substeps, "substeps", 1, 50)
    step = step or step_function(p, ts=hold * TS, substeps=substeps)
    t0 = time.perf_counter()
    status, slack, gap, targets = "not solved", math.inf, math.inf, None
    for targets in candidate_targets(x0, n):
        status, slack, states, torques = _solve(ca, step, p, x0, targets, deadline // hold)
        if torques is None or slack > 1e-6:
            continue
        gap, peak = _check_answer(p, states.T, torques.T, hold)
        if gap <= DEFECT_TOL and peak <= 1.0 + DEFECT_TOL:
            return Reach(True, tuple(targets.tolist()), np.repeat(torques.T, hold, axis=0),
                         status, slack, gap, time.perf_counter() - t0)
    return Reach(False, tuple(np.asarray(targets).tolist()), None, status, slack, gap,
                 time.perf_counter() - t0)


def reach_all(p, poses, deadline: int, *, hold: int = HOLD, substeps: int = NLP_SUBSTEPS,
              on_pose=None) -> list:
    """:func:`reach` for every pose (rows of ``poses``), one CasADi step shared;
    ``on_pose(i, answer)`` after each."""
    p = as_links(p)
    check_deadline(deadline, hold)
    step = step_function(p, ts=hold * TS, substeps=substeps)
    out = []
    for i, x0 in enumerate(np.asarray(poses, float)):
        out.append(reach(p, x0, deadline, hold=hold, substeps=substeps, step=step))
        if on_pose is not None:
            on_pose(i, out[-1])
    return out


__all__ = ["HOLD", "NLP_SUBSTEPS", "Reach", "acceleration_expression",
           "candidate_targets", "defect", "peak_speed", "reach", "reach_all", "step_function"]
