"""What the classical baselines share: checked parameters, the state layout, the
base class with ``name``, ``as_dict`` and ``from_dict``, and the model they declare.

A baseline is a callable on states (..., 4) = [theta1, theta2, dtheta1, dtheta2] that
returns torques (..., 2), vectorised over the leading axes. The angles it is handed are
wrapped to [-pi, pi) first (a noisy reading may leave that range). Its ``meta`` names the
full model (6) with the parameters it was designed on, which is what
:func:`twolink.sim.evaluation.evaluate` needs to compensate it for delays and noise
(:mod:`twolink.sim.estimation` predicts with that model).
"""
from __future__ import annotations

import math

import numpy as np

from twolink.arm.integrate import wrap_angle
from twolink.arm.parameters import TABLE_I, ArmParameters
from twolink.validate import is_real

#: The model every baseline declares in its ``meta`` (a name of twolink.arm.dynamics.MODELS).
DESIGN_MODEL = "full"


def check_vector(name: str, value, *, size: int = 2, minimum: float = 0.0,
                 strict: bool = True) -> np.ndarray:
    """``value`` (a number or ``size`` numbers) as a float array of shape (size,), each
    finite and above ``minimum`` (or at least it, when not ``strict``); a one-line
    ValueError otherwise."""
    try:
        arr = np.broadcast_to(np.asarray(value, dtype=float), (size,)).copy()
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a number or {size} numbers, got {value!r}") from None
    bad = ~np.isfinite(arr) | ((arr <= minimum) if strict else (arr < minimum))
    if bad.any():
        rel = ">" if strict else ">="
        raise ValueError(f"{name} must be finite and {rel} {minimum:g}, got "
                         f"{[float(v) for v in arr]}")
    return arr


def check_number(name: str, value, *, minimum: float = 0.0, maximum: float = math.inf,
                 strict: bool = False) -> float:
    """``value`` as a float in [minimum, maximum) (or (minimum, ...) when ``strict``)."""
    if not is_real(value):
        raise ValueError(f"{name} must be a number, got {value!r}")
    v = float(value)
    low_ok = v > minimum if strict else v >= minimum
    if not math.isfinite(v) or not low_ok or not v < maximum:
        raise ValueError(f"{name} must be finite and in {'(' if strict else '['}{minimum:g}, "
                         f"{maximum:g}), got {value!r}")
    return v


def check_params(params) -> ArmParameters:
    if isinstance(params, dict):
        params = ArmParameters.from_dict(params)
    if not isinstance(params, ArmParameters):
        raise ValueError(f"params must be ArmParameters (or their dict), got "
                         f"{type(params).__name__}")
    return params


def split_state(x) -> tuple[np.ndarray, np.ndarray]:
    """Wrapped angles (..., 2) and speeds (..., 2) of states ``x`` (..., 4)."""
    x = np.asarray(x, dtype=float)
    if x.ndim < 1 or x.shape[-1] != 4:
        raise ValueError(f"states must have shape (..., 4) [theta1, theta2, dtheta1, "
                         f"dtheta2], got {x.shape}")
    return wrap_angle(x[..., :2]), x[..., 2:]


def joint_inertia(params: ArmParameters = TABLE_I) -> np.ndarray:
    """The inertia each joint sees on its own at theta2 = 0 with the other joint free
    (no torque on it): 1 / (M0^-1)_ii = det M0 / M0_jj of (7), kg m^2 (about [0.0126,
    0.0021] for Table I; joint 2's is 2.6 times below P2, as joint 1 gives way).
    Converts the per-joint laws' accelerations to torques."""
    m = np.array([[params.P1 + params.P2 + 2.0 * params.P3, params.P2 + params.P3],
                  [params.P2 + params.P3, params.P2]])
    return 1.0 / np.diag(np.linalg.inv(m))


class Baseline:
    """Base of the baseline controllers: ``name``, ``kind``, ``meta``, ``as_dict`` and
    ``from_dict``. A subclass sets ``TYPE`` and ``KIND`` and lists its constructor's
    arguments in ``FIELDS``; :meth:`fields` returns them JSON-ready."""

    TYPE = ""
    KIND = ""
    FIELDS: tuple = ()

    def __init__(self, name: str | None):
        name = self.TYPE if name is None else name
        if not isinstance(name, str) or not name:
            raise ValueError(f"name must be a non-empty string, got {name!r}")
        self.name = name
        self.kind = self.KIND

    @property
    def design_params(self) -> ArmParameters:
        """The arm parameters the controller was designed on (Table I by default)."""
        return TABLE_I

    @property
    def meta(self) -> dict:
        """What the evaluation reads: the label and the synthesis model the compensation
        predicts with (:func:`twolink.sim.estimation.compensated`)."""
        return {"name": self.name, "type": self.TYPE, "model": DESIGN_MODEL,
                "parameters": self.design_params.as_dict()}

    def fields(self) -> dict:
        raise NotImplementedError

    def as_dict(self) -> dict:
        """JSON-ready: ``type``, ``name`` and the constructor's arguments."""
        return {"type": self.TYPE, "name": self.name, **self.fields()}

    @classmethod
    def from_dict(cls, data: dict):
        """The controller :meth:`as_dict` describes; a ValueError for another type or
        unknown keys."""
        if not isinstance(data, dict):
            raise ValueError(f"a {cls.TYPE} controller is described by a dict, got "
                             f"{type(data).__name__}")
        data = dict(data)
        kind = data.pop("type", cls.TYPE)
        if kind != cls.TYPE:
            raise ValueError(f"a {kind!r} controller is not a {cls.TYPE!r} one")
        unknown = sorted(set(data) - set(cls.FIELDS) - {"name"})
        if unknown:
            raise ValueError(f"unknown {cls.TYPE} field(s) {unknown}; known: "
                             f"{sorted(cls.FIELDS)}")
        return cls(**data)

    def __repr__(self) -> str:
        inner = ", ".join(f"{k}={v!r}" for k, v in self.fields().items() if k != "params")
        return f"{type(self).__name__}(name={self.name!r}, {inner})"
