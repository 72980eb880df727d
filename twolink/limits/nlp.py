"""Direct multiple shooting of the goal-band problem, solved by IPOPT through CasADi.

Decision vector w = [x_0, u_0, x_1, u_1, ..., x_{K-1}, u_{K-1}, x_K, s] over K samples:
x_0 is fixed to the initial state by its bounds, the torques lie in +-tau_max and the
speeds of x_1..x_K in +-2 pi rad/s (Table I) by theirs, and the defects
f(x_k, u_k) - x_{k+1} vanish, f the CasADi step of :mod:`.symbolic` (the package's RK4).
The goal band around the targets t (0 + 2 pi k per angle: the winding) is written with a
slack s,

    |theta_i,k - t_i| / 5 deg <= 1 + s,    |dtheta_i,k| / 0.1 rad/s <= 1 + s,

for the samples k of a window [first, K] (the rows of the other samples get infinite
bounds, so one solver serves every window), and optionally the speeds of x_K are zero
(the arm at rest in the band: zero torque then keeps it there for ever). The objective
is s: the band is reachable in the window iff min s <= 0.
"""
from __future__ import annotations

import contextlib
import dataclasses
import io
import sys

import numpy as np

from twolink.arm.parameters import GOAL_ANGLE, GOAL_SPEED, TABLE_I, ArmParameters
from twolink.limits.symbolic import check_model, require_casadi, step_function

#: IPOPT's settings (tight: a feasible answer must replay on the numpy model).
IPOPT_OPTIONS = {
    "ipopt.print_level": 0,
    "ipopt.sb": "yes",
    "ipopt.tol": 1e-9,
    "ipopt.constr_viol_tol": 1e-10,
    "ipopt.acceptable_tol": 1e-7,
    "ipopt.acceptable_constr_viol_tol": 1e-9,
    "ipopt.max_iter": 200,
    "ipopt.mu_strategy": "adaptive",
    "print_time": False,
}
#: IPOPT's and CasADi's printing when asked for (``verbose``): the iterations and timings.
VERBOSE_OPTIONS = {"ipopt.print_level": 5, "ipopt.sb": "no", "print_time": True}
#: IPOPT's answers that count as converged.
CONVERGED = ("Solve_Succeeded", "Solved_To_Acceptable_Level")
#: Largest defect |f(x_k, u_k) - x_{k+1}| of an answer that counts as a trajectory.
DEFECT_TOL = 1e-8
#: Rows of the band constraint per sample: +- angle and +- speed of each link.
BAND_ROWS = 8


#: One CasADi step per (model, parameters), shared by the solvers of every K (its
#: derivative functions are then generated once).
_STEPS: dict = {}


def shared_step(model: str, params: ArmParameters):
    """The :func:`~.symbolic.step_function` of ``model``, made once per process."""
    key = (model, params)
    if key not in _STEPS:
        _STEPS[key] = step_function(model, params)
    return _STEPS[key]


@dataclasses.dataclass(frozen=True)
class Solution:
    """One IPOPT answer: slack ``s``, states (K+1, 4) unwrapped, torques (K, 2)."""

    s: float
    states: np.ndarray
    torques: np.ndarray
    status: str
    iterations: int
    defect: float

    @property
    def converged(self) -> bool:
        return self.status in CONVERGED and self.defect <= DEFECT_TOL

    def feasible(self, margin: float = 0.0) -> bool:
        """Converged, with the band reached at slack ``s <= -margin``."""
        return self.converged and self.s <= -margin


class ShootingProblem:
    """The NLP over ``samples`` = K sample periods of ``model`` (one IPOPT instance,
    reused for every initial state, target and window)."""

    def __init__(self, model: str, samples: int, params: ArmParameters = TABLE_I,
                 options: dict | None = None, verbose: bool = False):
        ca = require_casadi()
        self.verbose = bool(verbose)
        self.model = check_model(model)
        self.params = params
        self.samples = k = int(samples)
        self.step = shared_step(model, params)
        w = ca.MX.sym("w", 6 * k + 5)
        targets = ca.MX.sym("t", 2)
        xu = ca.reshape(w[:6 * k], 6, k)
        xs = ca.horzcat(xu[:4, :], w[6 * k:6 * k + 4])          # x_0 .. x_K
        s = w[-1]
        defects = ca.vec(self.step.map(k)(xs[:, :-1], xu[4:, :]) - xs[:, 1:])
        rows = []
        for j in range(1, k + 1):
            for i in range(2):
                a = (xs[i, j] - targets[i]) / GOAL_ANGLE
                rows += [a - s, -a - s]
            for i in range(2):
                v = xs[2 + i, j] / GOAL_SPEED
                rows += [v - s, -v - s]
        g = ca.vertcat(defects, *rows, xs[2:, -1])
        opts = dict(IPOPT_OPTIONS)
        opts.update(VERBOSE_OPTIONS if verbose else {})
        opts.update(options or {})
        self.solver = ca.nlpsol(f"limit_{model}_{k}", "ipopt",
                                {"x": w, "p": targets, "f": s, "g": g}, opts)
        self._defects = ca.Function("defects", [w], [defects])
        bound = np.r_[np.inf, np.inf, params.speed_max]
        self.ubx = np.r_[np.tile(np.r_[bound, params.tau_max], k), bound, np.inf]
        self.lbx = -self.ubx
        self.lbx[-1] = -1.0
        self.n_defects = 4 * k

    def bounds(self, first: int, rest: bool) -> tuple:
        """lbg, ubg with the band rows of samples ``first``..K on, and x_K's speeds zero
        if ``rest``."""
        k = self.samples
        if not 1 <= first <= k:
            raise ValueError(f"the band window must start in 1..{k}, got {first}")
        band_ub = np.full(BAND_ROWS * k, np.inf)
        band_ub[BAND_ROWS * (first - 1):] = 1.0
        rest_b = np.zeros(2) if rest else np.full(2, np.inf)
        lbg = np.r_[np.zeros(self.n_defects), np.full(BAND_ROWS * k, -np.inf), -rest_b]
        ubg = np.r_[np.zeros(self.n_defects), band_ub, rest_b]
        return lbg, ubg

    def pack(self, states: np.ndarray, torques: np.ndarray, s: float = 1.0) -> np.ndarray:
        """The decision vector of states (K+1, 4) and torques (K, 2)."""
        k = self.samples
        return np.r_[np.c_[states[:k], torques].ravel(), states[k], s]

    def solve(self, x0, targets, guess_states, guess_torques, *, first: int | None = None,
              rest: bool = False) -> Solution:
        """min s from x0 (4,) with the band around ``targets`` (2,) at samples
        ``first``..K (default K: reach at K), from the initial guess given."""
        k = self.samples
        lbg, ubg = self.bounds(k if first is None else first, rest)
        lbx, ubx = self.lbx.copy(), self.ubx.copy()
        lbx[:4] = ubx[:4] = x0
        guess_torques = np.clip(guess_torques, -self.params.tau_max, self.params.tau_max)
        w0 = np.clip(self.pack(np.asarray(guess_states, float), guess_torques), lbx, ubx)
        with _solver_output(self.verbose):
            out = self.solver(x0=w0, p=np.asarray(targets, float), lbx=lbx, ubx=ubx,
                              lbg=lbg, ubg=ubg)
        stats = self.solver.stats()
        w = np.asarray(out["x"]).ravel()
        xu = w[:6 * k].reshape(k, 6)
        states = np.r_[xu[:, :4], w[6 * k:6 * k + 4][None]]
        defect = float(np.abs(np.asarray(self._defects(w))).max(initial=0.0))
        return Solution(s=float(w[-1]), states=states, torques=xu[:, 4:].copy(),
                        status=str(stats.get("return_status", "")),
                        iterations=int(stats.get("iter_count", 0)), defect=defect)


@contextlib.contextmanager
def _solver_output(verbose: bool):
    """Around one IPOPT solve: CasADi's printing (it writes through ``sys.stdout`` and
    ``sys.stderr``) is swallowed unless ``verbose``, and a Ctrl-C or SIGTERM that arrived
    during the solve is raised when it returns. CasADi turns the signal's exception into
    a warning and an early return (or, when IPOPT's own code takes it, into a return
    status), so without this the search would go on: a signal is seen in that warning or
    in the signals :func:`twolink.artifacts.sigterm_raises` recorded during the solve."""
    out, err = io.StringIO(), io.StringIO()
    with _signals_raised(err), contextlib.ExitStack() as stack:
        if not verbose:
            stack.enter_context(contextlib.redirect_stdout(out))
            stack.enter_context(contextlib.redirect_stderr(err))
        else:
            stack.enter_context(contextlib.redirect_stderr(_Tee(sys.stderr, err)))
        yield


@contextlib.contextmanager
def _signals_raised(err: io.StringIO | None = None):
    """Raise, when the block ends, a Ctrl-C (KeyboardInterrupt) or SIGTERM
    (:class:`~twolink.artifacts.Terminated`) that :func:`twolink.artifacts.sigterm_raises`
    recorded during it, or whose exception CasADi printed as a warning into ``err``: any
    CasADi call (building a problem, a solve, evaluating its defects) may swallow one."""
    from twolink.artifacts import Terminated, signal_count, signal_received

    before = signal_count()
    yield
    if (err is not None and "KeyboardInterrupt" in err.getvalue()) or \
            signal_count() > before:
        if signal_received() == "SIGTERM":
            raise Terminated("terminated by SIGTERM")
        raise KeyboardInterrupt


class _Tee(io.TextIOBase):
    """A text stream writing to two others."""

    def __init__(self, *streams):
        self.streams = streams

    def write(self, text):
        for stream in self.streams:
            stream.write(text)
        return len(text)

    def flush(self):
        for stream in self.streams:
            stream.flush()


class ProblemCache:
    """One :class:`ShootingProblem` per (model, K), built on first use; ``verbose``
    lets IPOPT and CasADi print (silent by default)."""

    def __init__(self, params: ArmParameters = TABLE_I, options: dict | None = None,
                 verbose: bool = False):
        self.params = params
        self.options = options
        self.verbose = bool(verbose)
        self.problems: dict = {}
        self.solves = 0

    def get(self, model: str, samples: int) -> ShootingProblem:
        key = (model, int(samples))
        if key not in self.problems:
            self.problems[key] = ShootingProblem(model, samples, self.params, self.options,
                                                 self.verbose)
        return self.problems[key]

    def solve(self, model: str, samples: int, x0, targets, states, torques, **kw) -> Solution:
        """One solve of the (model, K) problem (built first if new); a Ctrl-C or SIGTERM
        that any CasADi call of it swallowed is raised when it returns."""
        self.solves += 1
        with _signals_raised():
            return self.get(model, samples).solve(x0, targets, states, torques, **kw)
