"""Identification: the arm's dynamic parameters fitted to a logged MuJoCo experiment.

The horizontal arm's model (6)-(8) depends on the physical parameters only through
P1, P2, P3 of (10) and the damping b1, b2 (besides the torque and speed limits, which are
actuator specifications, not identified). It is linear in theta = [P1, P2, P3, b1, b2]:

    tau = Y(q, dq, ddq) theta                                    (:func:`regressor`)

What the data cannot determine (:data:`NOT_IDENTIFIABLE`): l2 and g have no dynamic effect
on the horizontal arm; l1, m1, m2, c1, c2, I1, I2 act only through the three sums of (10).

The experiment that logs the data is :mod:`twolink.sim.excitation`.

The fit (:func:`fit`) never differentiates the noisy angles twice. Writing (6) for the
momentum p = M(q) dq = Phi(q, dq) theta (:func:`momentum_regressor`),

    dp1/dt = tau1 - b1 dq1,
    dp2/dt = tau2 - b2 dq2 - P3 sin(q2) dq1 (dq1 + dq2),

and integrating twice from the start, every term except the last becomes a function of
the angles alone: int_0^t p1 = (P1 + P2) q1 + P2 q2 + P3 int cos(q2) (2 dq1 + dq2) + const
(a line integral, summed over angle increments), int_0^t int_0^s tau is exact for
zero-order-hold torques, and int (q - q(0)) is an integral of angles. The initial angles
and momenta enter as an unknown constant and slope per joint, fitted alongside theta.
The last term needs speeds: a first pass takes them from a Savitzky-Golay derivative of
the angles (0.3 s window); later passes blend its slow part with the fast part of the
speeds the fitted model's momentum gives (0.5 s split), which removes the smoothing bias.
Standard errors come from a parametric bootstrap: the fit repeated on the smoothed
angles plus fresh noise of the level estimated from the data (the rows of the
integrated form are correlated, so the textbook least-squares formula would not hold).
Data that cannot determine theta (e.g. zero torque) are refused with one line.
"""
from __future__ import annotations

import dataclasses
import math

import numpy as np

from twolink.arm.parameter_file import DYNAMIC
from twolink.arm.parameters import TABLE_I, ArmParameters
from twolink.sim.excitation import MIN_DURATION, Log, seed_streams
from twolink.validate import whole

#: The parameters the fit determines, in the order of theta.
IDENTIFIABLE = DYNAMIC
#: What the data of the horizontal arm cannot determine, and why.
NOT_IDENTIFIABLE = {
    "l2": "no dynamic effect on the horizontal arm (only the drawn arm's length)",
    "g": "the joints turn about the vertical axis, so gravity exerts no joint torque",
    "l1, m1, m2, c1, c2, I1, I2": "act only through P1, P2, P3 of (10): seven unknowns "
                                  "for three sums",
    "tau1_max, tau2_max, dtheta1_max, dtheta2_max": "actuator and speed limits, not "
                                                    "identified (taken from Table I)",
}
#: How the realised ArmParameters are chosen (parameter file provenance).
REALISATION = ("l1, l2, m1, c1, g and the limits from Table I; c2 from Table I where "
               "that leaves I1, I2 positive (else the geometric mean of the interval that "
               "does); then m2 = P3 / (l1 c2), I2 = P2 - m2 c2^2, I1 = P1 - m1 c1^2 - m2 l1^2")

#: Most bootstrap replicates a user may ask for.
MAX_BOOTSTRAP = 200
#: Savitzky-Golay window (s) of the first pass's speeds; split (s) of the speed blend.
_SMOOTH_S, _BLEND_S = 0.3, 0.5
#: Passes that re-estimate the speeds from the fitted momentum.
REFINE_PASSES = 2
#: Refusal thresholds: condition number of the normalised design, relative standard error.
MAX_CONDITION = 1e8
MAX_RELATIVE_ERROR = 0.1
#: A link whose smoothed angles span less than this many noise deviations did not move.
_MIN_SPAN_NOISE = 10.0


class IdentificationError(ValueError):
    """Data that cannot determine the parameters."""


# --------------------------------------------------------------------------- the model
def regressor(q, dq, ddq) -> np.ndarray:
    """Y(q, dq, ddq) of (6)-(8) in linear form: tau = Y theta, theta = [P1, P2, P3, b1,
    b2]; shape (..., 2, 5). Row 1: M11 ddq1 + M12 ddq2 - P3 sin q2 (2 dq1 dq2 + dq2^2) +
    b1 dq1; row 2: M12 ddq1 + P2 ddq2 + P3 sin q2 dq1^2 + b2 dq2."""
    q, dq, ddq = (np.asarray(a, dtype=float) for a in (q, dq, ddq))
    c, s = np.cos(q[..., 1]), np.sin(q[..., 1])
    d1, d2, a1, a2 = dq[..., 0], dq[..., 1], ddq[..., 0], ddq[..., 1]
    z = np.zeros(np.broadcast_shapes(c.shape, d1.shape, a1.shape))
    row1 = [a1 + z, a1 + a2, c * (2 * a1 + a2) - s * (2 * d1 * d2 + d2 * d2), d1 + z, z]
    row2 = [z, a1 + a2, c * a1 + s * d1 * d1, z, d2 + z]
    return np.stack([np.stack(row1, -1), np.stack(row2, -1)], -2)


def momentum_regressor(q, dq) -> np.ndarray:
    """Phi(q, dq) with M(q) dq = Phi theta (the momentum of (7)); shape (..., 2, 5)."""
    q, dq = np.asarray(q, dtype=float), np.asarray(dq, dtype=float)
    c = np.cos(q[..., 1])
    d1, d2 = dq[..., 0], dq[..., 1]
    z = np.zeros(np.broadcast_shapes(c.shape, d1.shape))
    row1 = [d1 + z, d1 + d2, c * (2 * d1 + d2), z, z]
    row2 = [z, d1 + d2, c * d1, z, z]
    return np.stack([np.stack(row1, -1), np.stack(row2, -1)], -2)


def theta(p: ArmParameters) -> np.ndarray:
    """theta = [P1, P2, P3, b1, b2] of an arm."""
    return np.array([getattr(p, name) for name in IDENTIFIABLE])


def realise(values, base: ArmParameters = TABLE_I) -> ArmParameters:
    """An :class:`ArmParameters` with the given P1, P2, P3, b1, b2 (a mapping or theta),
    the rest chosen as :data:`REALISATION` says; a ValueError if none exists."""
    if not isinstance(values, dict):
        values = dict(zip(IDENTIFIABLE, np.asarray(values, dtype=float).tolist()))
    P1, P2, P3, b1, b2 = (float(values[name]) for name in IDENTIFIABLE)
    if not all(math.isfinite(v) and v > 0 for v in (P1, P2, P3, b1, b2)):
        raise ValueError(f"P1, P2, P3, b1, b2 must be positive and finite, got "
                         f"{[P1, P2, P3, b1, b2]}")
    l1, m1, c1 = base.l1, base.m1, base.c1
    rest = P1 - m1 * c1 * c1
    # I2 > 0 needs c2 < P2 l1 / P3; I1 > 0 needs c2 > P3 l1 / (P1 - m1 c1^2).
    lo, hi = (P3 * l1 / rest if rest > 0 else math.inf), P2 * l1 / P3
    if not lo < hi:
        raise ValueError(f"no arm with Table I's l1, m1, c1 has P1 = {P1:.6g}, P2 = {P2:.6g}, "
                         f"P3 = {P3:.6g} (needs P3^2 < P2 (P1 - m1 c1^2))")
    c2 = base.c2 if lo < base.c2 < hi else math.sqrt(lo * hi)
    m2 = P3 / (l1 * c2)
    return dataclasses.replace(base, m2=m2, c2=c2, I2=P2 - m2 * c2 * c2,
                               I1=P1 - m1 * c1 * c1 - m2 * l1 * l1, b1=b1, b2=b2)


# --------------------------------------------------------------------------- the fit
@dataclasses.dataclass(frozen=True)
class Fit:
    """Fitted theta with bootstrap standard errors, and how well the data determine it."""

    values: dict
    std_errors: dict
    condition_number: float
    noise_deg_estimate: float
    residual_rms: float
    samples: int
    duration: float
    bootstrap: int
    passes: int

    def params(self, base: ArmParameters = TABLE_I) -> ArmParameters:
        """The fitted arm (:func:`realise`)."""
        return realise(self.values, base)

    def relative_errors(self, truth: ArmParameters) -> dict:
        """(fit - truth) / truth of every fitted parameter."""
        return {k: self.values[k] / getattr(truth, k) - 1.0 for k in IDENTIFIABLE}

    def as_dict(self) -> dict:
        return {"identified": {k: {"value": self.values[k], "std_error": self.std_errors[k]}
                               for k in IDENTIFIABLE},
                "not_identifiable": dict(NOT_IDENTIFIABLE),
                "condition_number": self.condition_number,
                "noise_deg_estimate": self.noise_deg_estimate,
                "residual_rms": self.residual_rms, "samples": self.samples,
                "duration_s": self.duration, "bootstrap": self.bootstrap,
                "passes": self.passes}


def _odd(n: float) -> int:
    return max(5, int(round(n)) // 2 * 2 + 1)


class _Design:
    """The twice-integrated momentum equations of a log, at every reading: rows A theta'
    = b with theta' = [P1, P2, P3, b1, b2, k10, k11, k20, k21] (k: constant and slope of
    joint 1 and joint 2, from the initial angles and momenta)."""

    def __init__(self, log: Log, q: np.ndarray):
        from scipy.integrate import cumulative_trapezoid   # scipy loads with the first fit

        m, dt = log.readings_per_period, log.dt
        self.dt, self.q = dt, q
        self.t = np.arange(len(q)) * dt
        tau = np.repeat(log.torques, m, axis=0)
        self.U = np.concatenate([np.zeros((1, 2)), np.cumsum(tau * dt, axis=0)])
        self.IU = cumulative_trapezoid(self.U, dx=dt, axis=0, initial=0)
        self.Iq = cumulative_trapezoid(q, dx=dt, axis=0, initial=0)
        step = np.diff(q, axis=0)
        c = np.cos(0.5 * (q[1:, 1] + q[:-1, 1]))
        self.L1 = np.concatenate([[0.0], np.cumsum(c * (2 * step[:, 0] + step[:, 1]))])
        self.L2 = np.concatenate([[0.0], np.cumsum(c * step[:, 0])])
        self.smooth = _odd(_SMOOTH_S / dt)
        self.blend = _odd(_BLEND_S / dt)

    def rows(self, v: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(A, b, F) for speeds v (N + 1, 2) in the velocity-product term."""
        from scipy.integrate import cumulative_trapezoid

        q, t, dt = self.q, self.t, self.dt
        f = np.sin(q[:, 1]) * v[:, 0] * (v[:, 0] + v[:, 1])
        F = cumulative_trapezoid(f, dx=dt, initial=0)
        IF = cumulative_trapezoid(F, dx=dt, initial=0)
        one, z = np.ones_like(t), np.zeros_like(t)
        r1 = np.stack([q[:, 0], q[:, 0] + q[:, 1], self.L1, self.Iq[:, 0], z, one, t, z, z], -1)
        r2 = np.stack([z, q[:, 0] + q[:, 1], self.L2 + IF, z, self.Iq[:, 1], z, z, one, t], -1)
        return np.concatenate([r1, r2]), np.concatenate([self.IU[:, 0], self.IU[:, 1]]), F

    def speeds(self, th: np.ndarray, F: np.ndarray, v_smooth: np.ndarray) -> np.ndarray:
        """Speeds from the fitted momentum's fast part and the smoothed speeds' slow part."""
        P1, P2, P3, b1, b2 = th[:5]
        c = np.cos(self.q[:, 1])
        m11, m12, m22 = P1 + P2 + 2 * P3 * c, P2 + P3 * c, P2
        p_smooth = np.stack([m11 * v_smooth[:, 0] + m12 * v_smooth[:, 1],
                             m12 * v_smooth[:, 0] + m22 * v_smooth[:, 1]], -1)
        p_model = np.stack([self.U[:, 0] - b1 * self.q[:, 0],
                            self.U[:, 1] - b2 * self.q[:, 1] - P3 * F], -1)

        from scipy.ndimage import uniform_filter1d

        def low(x):
            return uniform_filter1d(x, self.blend, axis=0, mode="nearest")

        p = low(p_smooth) + p_model - low(p_model)
        det = m11 * m22 - m12 * m12
        return np.stack([(m22 * p[:, 0] - m12 * p[:, 1]) / det,
                         (m11 * p[:, 1] - m12 * p[:, 0]) / det], -1)


def _lstsq(A: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Least squares through the normal equations of the unit-norm columns (a few
    columns, thousands of rows: far cheaper than an SVD, and as accurate at the condition
    numbers :data:`MAX_CONDITION` admits)."""
    norms = np.linalg.norm(A, axis=0)
    norms[norms == 0] = 1.0
    X = A / norms
    return np.linalg.solve(X.T @ X, X.T @ b) / norms


def _condition(A: np.ndarray) -> float:
    """Condition number of theta's columns after the nuisance constants and slopes are
    projected out, each column scaled to unit norm (inf when a column vanishes)."""
    nuisance = A[:, 5:]
    X = A[:, :5] - nuisance @ np.stack([_lstsq(nuisance, col) for col in A[:, :5].T], -1)
    norms = np.linalg.norm(X, axis=0)
    if np.any(norms <= 1e-12 * max(1.0, np.abs(A[:, :5]).max())):
        return math.inf
    eig = np.linalg.eigvalsh((X / norms).T @ (X / norms))
    return math.inf if eig[0] <= 0 else float(math.sqrt(eig[-1] / eig[0]))


def _check_physical(est: np.ndarray) -> None:
    if not np.all(np.isfinite(est)) or np.any(est <= 0) or est[0] * est[1] <= est[2] ** 2:
        values = ", ".join(f"{k} = {v:.3g}" for k, v in zip(IDENTIFIABLE, est))
        raise IdentificationError(
            f"the data cannot determine {', '.join(IDENTIFIABLE)}: the fit ({values}) is "
            f"not a physical arm (all positive, P1 P2 > P3^2); excite the arm more, log "
            f"longer or with less noise")


def _solve(log: Log, q: np.ndarray, passes: int) -> tuple[np.ndarray, float, float]:
    """theta' of a log with unwrapped angles q; (theta', condition, residual rms)."""
    from scipy.signal import savgol_filter

    design = _Design(log, q)
    v_smooth = savgol_filter(q, design.smooth, 3, deriv=1, delta=log.dt, axis=0)
    v = v_smooth
    cond = None
    for k in range(passes + 1):
        A, b, F = design.rows(v)
        if cond is None:
            cond = _condition(A)
            if not cond <= MAX_CONDITION:
                raise IdentificationError(
                    f"the data cannot determine {', '.join(IDENTIFIABLE)}: the regressor's "
                    f"condition number is {cond:.3g} (over {MAX_CONDITION:.0e}); the arm "
                    f"hardly moved, so excite it (e.g. --excitation bang-bang)")
        th = _lstsq(A, b)
        _check_physical(th[:5])
        if k < passes:
            v = design.speeds(th, F, v_smooth)
    residual = float(np.sqrt(np.mean((b - A @ th) ** 2)))
    return th, cond, residual


def least_squares(Y: np.ndarray, tau: np.ndarray) -> np.ndarray:
    """theta minimising |Y theta - tau| for regressor rows Y (..., 2, 5) and torques
    (..., 2) of (6); an :class:`IdentificationError` when Y cannot determine theta."""
    A = np.asarray(Y, dtype=float).reshape(-1, 5)
    b = np.asarray(tau, dtype=float).reshape(-1)
    if len(A) != len(b):
        raise ValueError(f"{len(A)} regressor rows for {len(b)} torques")
    norms = np.linalg.norm(A, axis=0)
    X = A / np.where(norms > 0, norms, 1.0)
    eig = np.linalg.eigvalsh(X.T @ X)
    if np.any(norms == 0) or eig[0] <= 0 or not math.sqrt(eig[-1] / eig[0]) <= MAX_CONDITION:
        raise IdentificationError(f"the data cannot determine {', '.join(IDENTIFIABLE)}: "
                                  f"the regressor is rank deficient or ill-conditioned")
    return _lstsq(A, b)


def check_bootstrap(bootstrap: int) -> None:
    """A ValueError unless ``bootstrap`` is a whole number in [2, MAX_BOOTSTRAP]."""
    whole(bootstrap, "bootstrap", 2, MAX_BOOTSTRAP,
          message="{what} must be a whole number in [{low}, {high}], got {value!r}")


def fit(log: Log, *, bootstrap: int = 20, passes: int = REFINE_PASSES) -> Fit:
    """Fit theta = [P1, P2, P3, b1, b2] to a log (the module docstring says how), with
    ``bootstrap`` replicates for the standard errors; refuses data that cannot determine
    it (:class:`IdentificationError`, a ValueError)."""
    if not isinstance(log, Log):
        raise ValueError(f"fit needs a Log, got {type(log).__name__}")
    check_bootstrap(bootstrap)
    if log.duration < MIN_DURATION - 1e-9:
        raise ValueError(f"a log of {log.duration:g} s is shorter than {MIN_DURATION:g} s")
    from scipy.signal import savgol_coeffs, savgol_filter

    q = np.unwrap(log.angles, axis=0)
    # Noise level of the readings: what a smoothing leaves, corrected for its hat value.
    window = _odd(_SMOOTH_S / log.dt)
    smooth = savgol_filter(q, window, 3, axis=0)
    h0 = savgol_coeffs(window, 3)[window // 2]
    sigma = float(np.std(q - smooth) / math.sqrt(1.0 - h0))
    span = np.ptp(smooth, axis=0)
    if np.any(span <= _MIN_SPAN_NOISE * sigma) or np.any(span <= 1e-9):
        raise IdentificationError(
            f"the data cannot determine {', '.join(IDENTIFIABLE)}: the arm hardly moved "
            f"(its angles span {np.degrees(span.min()):.3g} deg, noise "
            f"{math.degrees(sigma):.3g} deg); excite it (e.g. --excitation bang-bang)")
    th, cond, residual = _solve(log, q, passes)
    est = th[:5]
    rng = seed_streams(log.seed or 0)[4]
    draws = np.array([_solve(log, smooth + sigma * rng.standard_normal(q.shape), passes)[0][:5]
                      for _ in range(int(bootstrap))])
    se = draws.std(axis=0, ddof=1)
    values = dict(zip(IDENTIFIABLE, est.tolist()))
    rel = se / np.abs(est)
    if np.any(rel > MAX_RELATIVE_ERROR):
        worst = int(np.argmax(rel))
        raise IdentificationError(
            f"the data cannot determine {IDENTIFIABLE[worst]}: its standard error is "
            f"{100 * rel[worst]:.0f} % of its value (over {100 * MAX_RELATIVE_ERROR:.0f} %); "
            f"excite the arm more, log longer or with less noise")
    return Fit(values=values, std_errors=dict(zip(IDENTIFIABLE, se.tolist())),
               condition_number=cond, noise_deg_estimate=math.degrees(sigma),
               residual_rms=residual, samples=len(q), duration=log.duration,
               bootstrap=int(bootstrap), passes=int(passes))
