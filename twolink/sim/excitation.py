"""The identification experiment: a MuJoCo arm driven by an excitation, its angles logged.

A plant whose parameters the fit never sees (:func:`hidden_plant`) is driven from rest at
random angles by seeded bang-bang torques (the policies' own levels 0 and +-tau_max, held
for random stretches of 0.25 to 2 s; a link is not driven faster once its measured speed
exceeds 35 % of its limit, and pushed back beyond 60 %, so that the plant never clips a
speed, which (6) does not model), and its angles are read at every MuJoCo timestep
(Ts / 10) with Gaussian noise (:func:`run_experiment`). Speeds are not measured. The
torques commanded are taken as applied (the plant's torque limits are Table I's). The
:class:`Log` is all that :func:`twolink.sim.identify.fit` sees.
"""
from __future__ import annotations

import dataclasses
import math

import mujoco
import numpy as np

from twolink.arm import mjcf
from twolink.arm.integrate import wrap_angle
from twolink.arm.parameters import TABLE_I, TS, ArmParameters
from twolink.sim.perturbations import PHYSICAL, random_perturbation
from twolink.sim.plants import (
    SimulationError,
    finish_data,
    mujoco_warnings,
    set_data,
    substeps_per_sample,
)
from twolink.validate import whole

#: Excitation signals by name.
EXCITATIONS = {
    "bang-bang": "torques 0 or +-tau_max per link, each held 0.25-2 s at random; a link "
                 "is not driven faster beyond 35 % of its speed limit and is pushed back "
                 "beyond 60 %",
    "zero": "no torque: the arm stays at rest and nothing can be identified (shows the "
            "refusal)",
}
#: Hold of a bang-bang level, in sample periods Ts (0.25 s to 2 s).
_HOLD = (5, 40)
#: A link whose measured speed exceeds this fraction of its limit is pushed back.
_SPEED_GUARD = 0.6
#: A link whose measured speed exceeds this fraction of its limit is not driven faster
#: (its torque is zeroed while it points along the speed): with the one-period lag of the
#: measured speed, the guard alone let link 2 (up to 80 rad/s^2 near theta2 = 0) reach
#: its limit, where the plant clips the speed and (6) no longer holds.
_COAST = 0.35

#: Bounds on what a user may ask for.
MIN_DURATION, MAX_DURATION = 1.0, 60.0
MAX_NOISE_DEG = 10.0
#: The hidden plant of an experiment lies within +-MAX_HIDDEN_SPREAD of Table I: the
#: identification is checked over that range, narrower than a challenge's.
MAX_HIDDEN_SPREAD = 0.5


@dataclasses.dataclass(frozen=True)
class Log:
    """What an experiment records, and all the fit sees: angle readings (N + 1, 2) every
    ``dt`` seconds (wrapped to [-pi, pi), noisy), and the torques (n, 2) commanded over
    each sample period ``ts`` (zero-order hold), with ``ts = m dt`` and N = n m."""

    dt: float
    ts: float
    angles: np.ndarray
    torques: np.ndarray
    angle_noise_deg: float = 0.0
    seed: int | None = None
    excitation: str = ""

    def __post_init__(self):
        angles = np.asarray(self.angles, dtype=float)
        torques = np.asarray(self.torques, dtype=float)
        if not (math.isfinite(self.dt) and math.isfinite(self.ts)) or self.dt <= 0 \
                or self.ts < self.dt:
            raise ValueError(f"log: need 0 < dt <= ts, got dt = {self.dt}, ts = {self.ts}")
        m = round(self.ts / self.dt)
        if abs(m * self.dt - self.ts) > 1e-9 * self.ts:
            raise ValueError(f"log: ts = {self.ts} is not a whole number of dt = {self.dt}")
        if torques.ndim != 2 or torques.shape[1] != 2 or len(torques) < 1:
            raise ValueError(f"log: torques must have shape (n, 2), got {torques.shape}")
        if angles.shape != (len(torques) * m + 1, 2):
            raise ValueError(f"log: {len(torques)} torque periods of {m} readings need angles "
                             f"of shape ({len(torques) * m + 1}, 2), got {angles.shape}")
        if not (np.all(np.isfinite(angles)) and np.all(np.isfinite(torques))):
            raise ValueError("log: angles and torques must be finite (no NaN)")
        object.__setattr__(self, "angles", angles)
        object.__setattr__(self, "torques", torques)

    @property
    def duration(self) -> float:
        return len(self.torques) * self.ts

    @property
    def readings_per_period(self) -> int:
        return round(self.ts / self.dt)


def seed_streams(seed: int) -> list[np.random.Generator]:
    """Independent generators of an identification seed: plant, start, torques, noise,
    bootstrap."""
    return [np.random.default_rng(s) for s in np.random.SeedSequence(seed).spawn(5)]


def check_experiment(*, duration: float, angle_noise_deg: float, seed: int,
                     excitation: str, spread: float = 0.0) -> None:
    """A ValueError (one line) for options outside what an experiment accepts."""
    if not (isinstance(duration, (int, float)) and MIN_DURATION <= duration <= MAX_DURATION):
        raise ValueError(f"duration must lie in [{MIN_DURATION:g}, {MAX_DURATION:g}] s, "
                         f"got {duration!r}")
    if not (isinstance(angle_noise_deg, (int, float)) and 0 <= angle_noise_deg <= MAX_NOISE_DEG):
        raise ValueError(f"angle noise must lie in [0, {MAX_NOISE_DEG:g}] deg, got "
                         f"{angle_noise_deg!r}")
    if not (isinstance(spread, (int, float)) and 0 <= spread <= MAX_HIDDEN_SPREAD):
        raise ValueError(f"spread must lie in [0, {MAX_HIDDEN_SPREAD:g}], got {spread!r}")
    whole(seed, "seed", 0)
    if excitation not in EXCITATIONS:
        raise ValueError(f"unknown excitation {excitation!r}; choose one of "
                         f"{', '.join(EXCITATIONS)}")


def hidden_plant(seed: int, spread: float, base: ArmParameters = TABLE_I) -> ArmParameters:
    """The plant an identification of ``seed`` runs on: every parameter of
    :data:`~twolink.sim.perturbations.PHYSICAL` changed jointly, uniform in +-``spread``."""
    return random_perturbation(seed_streams(seed)[0], spread, base, names=PHYSICAL)


def run_experiment(params: ArmParameters, *, duration: float = 10.0,
                   angle_noise_deg: float = 1.0, seed: int = 0,
                   excitation: str = "bang-bang") -> Log:
    """Drive the MuJoCo arm ``params`` with the excitation and log its noisy angles."""
    check_experiment(duration=duration, angle_noise_deg=angle_noise_deg, seed=seed,
                     excitation=excitation)
    _, start, pick, noise_rng, _ = seed_streams(seed)
    model = mjcf.build_model(params)
    data = mujoco.MjData(model)
    m = substeps_per_sample(model)
    n = max(1, round(duration / TS))
    x0 = np.r_[start.uniform(-math.pi, math.pi, 2), 0.0, 0.0]
    set_data(data, x0)
    sigma = math.radians(angle_noise_deg)
    noise = sigma * noise_rng.standard_normal((n * m + 1, 2))
    angles = np.empty((n * m + 1, 2))
    angles[0] = x0[:2]
    torques = np.zeros((n, 2))
    level, left = np.zeros(2), np.zeros(2, dtype=int)
    guard = _SPEED_GUARD * TABLE_I.speed_max
    tau_max = TABLE_I.tau_max
    with mujoco_warnings() as messages:
        for k in range(n):
            if excitation == "bang-bang":
                for i in range(2):
                    if left[i] == 0:
                        level[i] = pick.choice((-1.0, 0.0, 1.0))
                        left[i] = pick.integers(_HOLD[0], _HOLD[1] + 1)
                    left[i] -= 1
                u = level.copy()
                if k:       # measured speed over the last period, from the noisy readings
                    seen = wrap_angle(angles[k * m] + noise[k * m])
                    before = wrap_angle(angles[(k - 1) * m] + noise[(k - 1) * m])
                    speed = wrap_angle(seen - before) / TS
                    fast = np.abs(speed) > guard
                    u[fast] = -np.sign(speed[fast])
                    coast = (np.abs(speed) > _COAST * TABLE_I.speed_max) & (u * speed > 0)
                    u[coast] = 0.0
                torques[k] = u * tau_max
            data.ctrl[:] = torques[k]
            for j in range(1, m):
                mujoco.mj_step(model, data)
                angles[k * m + j] = data.qpos
            mujoco.mj_step(model, data)
            angles[(k + 1) * m] = finish_data(params, data)[:2]
            if messages or not np.all(np.isfinite(data.qpos)):
                why = f": {messages[0].strip()}" if messages else ""
                raise SimulationError(f"the identification experiment went unstable at "
                                      f"t = {k * TS:.2f} s{why}")
    return Log(dt=TS / m, ts=TS, angles=wrap_angle(angles + noise), torques=torques,
               angle_noise_deg=float(angle_noise_deg), seed=int(seed), excitation=excitation)


def experiment(seed: int = 0, *, spread: float = 0.2, duration: float = 10.0,
               angle_noise_deg: float = 1.0, excitation: str = "bang-bang") -> Log:
    """The experiment of ``twolink identify``: a hidden plant drawn from ``seed``
    (:func:`hidden_plant`), driven and logged. Only the log comes back."""
    check_experiment(duration=duration, angle_noise_deg=angle_noise_deg, seed=seed,
                     excitation=excitation, spread=spread)
    return run_experiment(hidden_plant(seed, spread), duration=duration,
                          angle_noise_deg=angle_noise_deg, seed=seed, excitation=excitation)
