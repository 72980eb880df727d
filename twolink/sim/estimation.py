"""Run-time compensation: a state observer for noisy readings, a d-step delay predictor.

Timing (per batch row, sample k counted from the row's restart): the reading y_k is the
state x_{k-o} (observation delay o; before o samples have passed, the initial state),
possibly noisy; the command u_k issued now reaches the plant d samples later (actuation
delay d; the actuators hold zero torque until the first command arrives, as
:class:`twolink.sim.perturbations.ActuationDelay` does), so the plant runs
x_{j+1} = f(x_j, u_{j-d}).

:class:`StateEstimator` turns readings into the state the next command will act on:

* the **observer** is a predictor-corrector on the synthesis model f (the RK4 sample
  step of (6) or (11), :func:`twolink.arm.integrate.sample_step`, run compiled:
  :func:`twolink.arm.integrate.sample_step_compiled`, its operations in its order): the
  prior x^-_m = f(x_{m-1}, u_{m-1-d}) is corrected by a constant gain, x_m = x^-_m + L (y - x^-_m),
  angles of the innovation and of the estimate wrapped. L is the steady-state Kalman gain
  of each joint's sampled double integrator (angle, speed) with white acceleration
  disturbances (:data:`PROCESS_STD`) and the reading's noise (default: the medium
  challenge's 1 deg and 0.02 rad/s). A reading equal bit for bit to its row's previous
  reading is a repeated one (dropped or stuck): the observer predicts through it;
* the **predictor** rolls f from the estimate of x_{k-o} over the o + d commands
  u_{k-o-d}, ..., u_{k-1} already in the pipeline and returns x^_{k+d}.

:class:`Compensator` wraps a policy: u_k = h(x^_{k+d}). With the observer off the
estimate is the reading itself, so with no delay and no observer the wrapper returns
exactly the policy's torques; :func:`compensated` then returns the policy itself.
Everything is vectorised over the batch rows; rows restart independently.
"""
from __future__ import annotations

import math

import numpy as np
import scipy.linalg

from twolink.arm.integrate import sample_step_compiled, wrap_angle
from twolink.arm.parameters import TABLE_I, TS, ArmParameters
from twolink.sim.challenges import LEVELS
from twolink.validate import is_whole

#: Synthesis models a compensator can predict with: ``identified`` is the full model (6)
#: with the parameters identified on the plant (carried in the policy's meta).
PREDICTION_MODELS = {"simplified": "simplified", "full": "full", "identified": "full"}
#: Longest actuation plus observation delay (samples) a compensator accepts: 10 s.
MAX_DELAY = 200
#: Noise the observer's gain is designed for when none is given: the medium challenge's
#: 1 deg angle noise and 0.02 rad/s speed noise.
DESIGN_ANGLE_NOISE_DEG = LEVELS["medium"].angle_noise_deg
DESIGN_SPEED_NOISE = LEVELS["medium"].speed_noise
#: Std (rad/s per sample period) of the acceleration disturbance each joint's speed takes
#: in the observer's design model: how far the synthesis model is trusted over one Ts.
#: Small values smooth the speed readings (gain on the speed innovation 0.39 at 0.01,
#: 0.62 at 0.02, 0.96 at 0.1); large ones follow a mismatched plant faster. Chosen on the development
#: seed 1000 (``docs/studies/compensation_study.py --tune --seed 1000``), never on the seed of
#: the reported figures: the value with the best combined-condition success (+-20 % joint
#: parameters on 32 plants, one-sample delay, 1 deg / 0.02 rad/s noise) in the worse of
#: centralized_full and centralized_robust. Candidates 0.01, 0.02, 0.03, 0.05, 0.1, 0.3,
#: 1 gave centralized_full 97.1, 99.0, 97.0, 91.8, 81.8, 76.6, 75.5 % (robust: 99.9 % at
#: 0.01, 100 % from 0.02 on); the decentralized policies move by at most 1.2 points
#: between 0.01 and 0.03 (the speed chatter of larger values costs decentralized_full
#: more: 78.2 % at 0.1).
PROCESS_STD = 0.02
#: The smallest reading noise (std) a gain is designed for; zero noise would make the
#: Kalman design singular (the gain is then 1 to within 1e-6 anyway).
_MIN_STD = 1e-6


def observer_gain(angle_std: float, speed_std: float,
                  process_std: float = PROCESS_STD, ts: float = TS) -> np.ndarray:
    """Steady-state Kalman gain L (2, 2) of one joint, state [theta, dtheta], both read.

    Design model: theta' = theta + ts dtheta + ts/2 w, dtheta' = dtheta + w, w ~ N(0,
    process_std^2); readings [theta, dtheta] + N(0, diag(angle_std^2, speed_std^2)).
    The corrected estimate is x^- + L (y - x^-).
    """
    for name, v in (("angle_std", angle_std), ("speed_std", speed_std),
                    ("process_std", process_std), ("ts", ts)):
        if not (isinstance(v, (int, float, np.number)) and math.isfinite(v) and v >= 0):
            raise ValueError(f"{name} must be a finite non-negative number, got {v!r}")
    F = np.array([[1.0, ts], [0.0, 1.0]])
    G = np.array([[0.5 * ts], [1.0]])
    Q = G @ G.T * max(process_std, _MIN_STD) ** 2
    R = np.diag([max(angle_std, _MIN_STD) ** 2, max(speed_std, _MIN_STD) ** 2])
    P = scipy.linalg.solve_discrete_are(F.T, np.eye(2), Q, R)     # prior covariance
    return P @ np.linalg.inv(P + R)


def _check_samples(value, what: str) -> int:
    if not is_whole(value):
        raise ValueError(f"{what} must be a whole number of samples, got {value!r}")
    if value < 0:
        raise ValueError(f"{what} must be a non-negative whole number of samples, got {value}")
    if value > MAX_DELAY:
        raise ValueError(f"{what} of {value} samples is beyond the {MAX_DELAY} a compensator "
                         f"accepts")
    return int(value)


def _synthesis_model(policy, model, params) -> tuple[str, ArmParameters]:
    """The prediction model's name in dynamics.MODELS and its parameters (from the
    policy's meta where not given)."""
    meta = getattr(policy, "meta", {}) or {}
    name = meta.get("model") if model is None else model
    if name is None:
        who = getattr(policy, "name", None) or type(policy).__name__
        raise ValueError(f"controller {who} names no model for the compensator to predict "
                         f"with: give it meta = {{'model': ...}} (one of "
                         f"{', '.join(PREDICTION_MODELS)}), or run it without compensation")
    if name not in PREDICTION_MODELS:
        raise ValueError(f"unknown prediction model {name!r}; choose one of "
                         f"{', '.join(PREDICTION_MODELS)}")
    if params is None:
        params = ArmParameters.from_dict(meta["parameters"]) if "parameters" in meta else TABLE_I
    if not isinstance(params, ArmParameters):
        raise ValueError(f"params must be an ArmParameters, got {type(params).__name__}")
    return PREDICTION_MODELS[name], params


class StateEstimator:
    """Observer and d-step predictor, batched over rows (see the module docstring).

    Per sample call :meth:`update` with the readings (B, 4) (or one (4,)), then
    :meth:`record` with the commands issued for them. ``model`` is a name of
    :data:`twolink.arm.dynamics.MODELS` (or ``identified``), ``params`` its parameters.
    """

    def __init__(self, *, model: str, params: ArmParameters = TABLE_I, delay: int = 0,
                 observation_delay: int = 0, observer: bool = True,
                 angle_noise_deg: float = DESIGN_ANGLE_NOISE_DEG,
                 speed_noise: float = DESIGN_SPEED_NOISE, process_std: float = PROCESS_STD):
        self.delay = _check_samples(delay, "delay")
        self.observation_delay = _check_samples(observation_delay, "observation delay")
        if self.delay + self.observation_delay > MAX_DELAY:
            raise ValueError(f"delay plus observation delay must be at most {MAX_DELAY} "
                             f"samples, got {self.delay + self.observation_delay}")
        if not isinstance(observer, (bool, np.bool_)):
            raise ValueError(f"observer must be True or False, got {observer!r}")
        self.observer = bool(observer)
        self.model, self.params = _synthesis_model(None, model, params)
        if not (isinstance(angle_noise_deg, (int, float, np.number))
                and math.isfinite(angle_noise_deg)):
            raise ValueError(f"angle_noise_deg must be a finite number, got {angle_noise_deg!r}")
        self.gain = observer_gain(math.radians(angle_noise_deg), speed_noise, process_std)
        self._rows = None           # batch size, set by the first reading
        self._single = False

    # ------------------------------------------------------------------ state
    def _allocate(self, rows: int) -> None:
        self._rows = rows
        n = self.delay + self.observation_delay + 1
        self._u = np.zeros((n, rows, 2))          # issued commands, oldest first
        self._k = np.zeros(rows, dtype=np.int64)  # samples since the row's restart
        self._fresh = np.ones(rows, dtype=bool)   # no reading yet
        self._x = np.zeros((rows, 4))             # estimate of the measured state
        self._y = np.full((rows, 4), np.nan)      # the previous reading
        self._pending = np.zeros(rows, dtype=bool)  # a reading awaits its command
        self.prediction = np.full((rows, 4), np.nan)  # the last x^_{k+d} of every row

    def _index(self, rows) -> np.ndarray:
        if rows is None:
            return np.arange(self._rows)
        try:
            idx = np.arange(self._rows)[rows]
        except (IndexError, TypeError, ValueError):
            raise ValueError(f"rows must index a batch of {self._rows} rows (indices or a "
                             f"bool mask), got {rows!r}") from None
        return np.atleast_1d(idx)

    def restart(self, rows=None) -> None:
        """Rows ``rows`` (indices or a bool mask; all when None) begin a new episode: their
        readings, estimates and commands are forgotten."""
        if self._rows is None:
            return
        idx = self._index(rows)
        self._u[:, idx] = 0.0
        self._k[idx] = 0
        self._fresh[idx] = True
        self._x[idx] = 0.0
        self._y[idx] = np.nan
        self._pending[idx] = False

    def _check(self, y, rows) -> tuple[np.ndarray, np.ndarray]:
        y = np.asarray(y)
        if y.dtype.kind not in "iuf":
            raise ValueError(f"readings must hold real numbers, got dtype {y.dtype}")
        if y.ndim not in (1, 2) or y.shape[-1] != 4:
            raise ValueError(f"readings must have shape (4,) or (B, 4), got {y.shape}")
        if not np.all(np.isfinite(y)):
            raise ValueError("readings contain NaN or infinite values")
        flat = y.astype(float).reshape(-1, 4)
        if self._rows is None:
            if rows is not None:
                raise ValueError("the first readings must be of every row (no rows=)")
            self._allocate(len(flat))
            self._single = y.ndim == 1
        idx = self._index(rows)
        if len(flat) != len(idx) or (rows is None and (y.ndim == 1) != self._single):
            raise ValueError(f"readings of shape {y.shape} for {len(idx)} of a batch of "
                             f"{self._rows} rows; make a new compensator for another batch")
        return flat, idx

    def _step(self, x: np.ndarray, u: np.ndarray) -> np.ndarray:
        """One sample period of the synthesis model from x (B, 4) under u (B, 2): the
        compiled RK4 (one pass per row, no numpy call per substep)."""
        return sample_step_compiled(self.model, self.params, x, u)

    # ----------------------------------------------------------------- update
    def update(self, y, rows=None) -> np.ndarray:
        """The predicted state x^_{k+d} (same shape as y) the command issued now acts on.

        ``rows`` (indices or a bool mask): y holds the readings of these rows only.
        """
        flat, idx = self._check(y, rows)
        if self._pending[idx].any():
            raise ValueError("update() twice without record(): pass the commands issued for "
                             "the previous readings first")
        o, d = self.observation_delay, self.delay
        k, u = self._k[idx], self._u[:, idx]
        if self.observer:
            x = self._x[idx]
            new_time = k > o                  # the reading is of a later time than the last
            if new_time.any():                # x^-_m = f(x_{m-1}, u_{m-1-d})
                x[new_time] = self._step(x[new_time], u[0][new_time])
            innovation = flat - x
            innovation[:, :2] = wrap_angle(innovation[:, :2])
            innovation[np.all(flat == self._y[idx], axis=-1)] = 0.0    # a repeated reading
            (la, lb), (lc, ld) = self.gain    # joint j: angle j, speed 2 + j
            ea, es = innovation[:, :2], innovation[:, 2:]
            x[:, :2] += la * ea + lb * es     # elementwise: a row's value never depends
            x[:, 2:] += lc * ea + ld * es     # on the rows beside it
            x[:, :2] = wrap_angle(x[:, :2])
            x = np.where(self._fresh[idx][:, None], flat, x)
        else:
            x = flat.copy()
        self._x[idx] = x
        self._y[idx] = flat
        self._fresh[idx] = False
        # Roll from x_{k-o} over u_{k-o-d}, ..., u_{k-1} (rows in their first o samples
        # read x_0 and roll over the first k + d steps only).
        z = x
        skip = np.maximum(o - k, 0)
        for s in range(o + d):
            active = s >= skip
            if active.all():
                z = self._step(z, u[1 + s])
            elif active.any():
                z = z.copy()
                z[active] = self._step(z[active], u[1 + s][active])
        self.prediction[idx] = z
        self._pending[idx] = True
        return z[0].copy() if self._single and rows is None else z.copy()

    def record(self, u, rows=None) -> None:
        """The commands (B, 2) (or one (2,)) issued for the last readings (of ``rows``)."""
        if self._rows is None:
            raise ValueError("record() before update(): pass a reading first")
        idx = self._index(rows)
        if not self._pending[idx].all():
            raise ValueError("record() before update(): pass the readings first")
        u = np.asarray(u)
        want = (2,) if self._single and rows is None else (len(idx), 2)
        if u.dtype.kind not in "iuf" or u.shape != want:
            raise ValueError(f"commands must be real numbers of shape {want}, got dtype "
                             f"{u.dtype} and shape {u.shape}")
        if not np.all(np.isfinite(u)):
            raise ValueError("commands contain NaN or infinite values")
        self._u[:, idx] = np.concatenate([self._u[1:, idx], u.reshape(1, -1, 2)])
        self._k[idx] += 1
        self._pending[idx] = False

    @property
    def estimate(self) -> np.ndarray:
        """The observer's estimate of the measured state x_{k-o} (rows, 4)."""
        if self._rows is None:
            raise ValueError("no reading yet")
        return self._x.copy()


class Compensator:
    """A batched policy wrapper: observer (noisy measurements) + d-step predictor (delays).

    ``policy(x)`` is evaluated on x^_{k+d}, the synthesis model's prediction of the state
    when the command issued now reaches the plant (``delay`` samples of actuation delay,
    ``observation_delay`` samples of reading delay), from the observer's estimate when
    ``observer`` (else from the reading itself). ``model``/``params`` default to the
    policy's synthesis model and parameters (its meta). Keyword ``angle_noise_deg``,
    ``speed_noise`` and ``process_std`` design the observer's gain (:func:`observer_gain`).
    State lives in the wrapper: make one per rollout, or :meth:`restart` rows.
    """

    def __init__(self, policy, *, delay: int = 0, observation_delay: int = 0,
                 observer: bool = True, params: ArmParameters | None = None,
                 model: str | None = None, **design):
        if not callable(policy):
            raise ValueError(f"policy must be callable, got {type(policy).__name__}")
        name, p = _synthesis_model(policy, model, params)
        self.policy = policy
        self.kind = getattr(policy, "kind", "")
        self.meta = getattr(policy, "meta", {})
        self.estimator = StateEstimator(model=name, params=p, delay=delay,
                                        observation_delay=observation_delay,
                                        observer=observer, **design)

    def __call__(self, y) -> np.ndarray:
        """Torque command(s) (..., 2) issued now for the measured state(s) (4,) or (B, 4)."""
        u = np.asarray(self.policy(self.estimator.update(y)), dtype=float)
        self.estimator.record(u)
        return u

    def restart(self, rows=None) -> None:
        """Rows ``rows`` begin a new episode (their state forgotten; all when None)."""
        self.estimator.restart(rows)


def compensated(policy, *, delay: int = 0, observation_delay: int = 0, noise: bool = False,
                **kw):
    """``policy`` compensated for ``delay`` actuation and ``observation_delay`` reading
    samples, with the observer on when ``noise`` (noisy, dropped or stuck readings); the
    policy itself when there is nothing to compensate. ``kw`` go to :class:`Compensator`."""
    delay = _check_samples(delay, "delay")
    observation_delay = _check_samples(observation_delay, "observation delay")
    if not isinstance(noise, (bool, np.bool_)):
        raise ValueError(f"noise must be True or False, got {noise!r}")
    if delay == 0 and observation_delay == 0 and not noise:
        return policy
    return Compensator(policy, delay=delay, observation_delay=observation_delay,
                       observer=bool(noise), **kw)
