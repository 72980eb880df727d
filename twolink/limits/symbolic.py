"""The package's sample step x_{k+1} = f(x_k, u_k) written in CasADi symbols.

Line for line the numpy code of :mod:`twolink.arm.dynamics` (models (6)-(8) and (11)) and
:func:`twolink.arm.integrate.rk4` (fixed-step RK4, :data:`~twolink.arm.integrate.SUBSTEPS`
substeps over Ts, the torque held), so that the CasADi step equals
:func:`twolink.arm.integrate.sample_step` to round-off (tests/control/test_time_optimal.py
holds it to 1e-12). The end-of-sample wrap and the torque clip are left out: the NLP keeps
the torques inside +-tau_max and the speeds inside +-2 pi rad/s by bounds, where the clip
and the speed saturation do nothing, and it tracks the angles unwrapped (the goal band is
reached around 0 + 2 pi k).

CasADi is optional (``pip install 'twolink[limits]'``); :func:`require_casadi` imports it
or raises :class:`CasadiMissing`, one line naming that command.
"""
from __future__ import annotations

from twolink.arm.integrate import SUBSTEPS
from twolink.arm.parameters import TABLE_I, TS, ArmParameters

#: The models the limits are computed for: (6)-(8) and (11), by the names of
#: ``twolink.arm.dynamics.MODELS``.
MODELS = ("full", "simplified")
#: What installs CasADi.
INSTALL_HINT = "pip install 'twolink[limits]'"


class CasadiMissing(ImportError, RuntimeError):
    """CasADi is not installed (an ImportError, and a RuntimeError so that the command
    line prints it as its one-line error)."""


def require_casadi():
    """The ``casadi`` module, or :class:`CasadiMissing` naming :data:`INSTALL_HINT`."""
    try:
        import casadi
    except ImportError:
        raise CasadiMissing(f"the time-optimal limits need CasADi, which is not installed: "
                            f"{INSTALL_HINT}") from None
    return casadi


def casadi_version() -> str | None:
    """The installed CasADi's version, or None."""
    try:
        return require_casadi().__version__
    except CasadiMissing:
        return None


def check_model(model) -> str:
    """``model`` if it is one of :data:`MODELS`, else a one-line ValueError."""
    if model not in MODELS:
        raise ValueError(f"unknown model {model!r}; choose one of {', '.join(MODELS)}")
    return model


def full_acceleration(ca, p: ArmParameters, x, tau):
    """:func:`twolink.arm.dynamics.full_acceleration` (horizontal arm) in symbols."""
    h = p.P3 * ca.sin(x[1])
    d1, d2 = x[2], x[3]
    rhs0 = tau[0] - (-h * (2.0 * d1 * d2 + d2 * d2))
    rhs1 = tau[1] - h * d1 * d1
    rhs0 = rhs0 - p.b1 * x[2]
    rhs1 = rhs1 - p.b2 * x[3]
    c = ca.cos(x[1])
    m11 = p.P1 + p.P2 + 2.0 * p.P3 * c
    m12 = p.P2 + p.P3 * c
    m22 = p.P2
    det = m11 * m22 - m12 * m12
    return ca.vertcat((m22 * rhs0 - m12 * rhs1) / det, (m11 * rhs1 - m12 * rhs0) / det)


def simplified_acceleration(ca, p: ArmParameters, x, tau):
    """:func:`twolink.arm.dynamics.simplified_acceleration` (model (11)) in symbols."""
    c = ca.cos(x[1])
    a1 = (p.P2 * (tau[0] - p.b1 * x[2]) - (p.P2 + p.P3 * c) * tau[1]) / (
        p.P2 * (p.P1 + p.P2 + 2.0 * p.P3 * c))
    a2 = tau[1] / p.P2 - p.b2 * x[3]
    return ca.vertcat(a1, a2)


ACCELERATIONS = {"full": full_acceleration, "simplified": simplified_acceleration}


def step_expression(ca, model: str, p: ArmParameters, x, u, *, ts: float = TS,
                    substeps: int = SUBSTEPS):
    """The state after one sample period from ``x`` under the held torque ``u``
    (symbols or numbers), before the wrap: :func:`twolink.arm.integrate.rk4`."""
    accel = ACCELERATIONS[check_model(model)]
    return rk4_expression(lambda s: ca.vertcat(s[2:], accel(ca, p, s, u)), x, ts, substeps)


def rk4_expression(f, x, duration: float, substeps: int):
    """``substeps`` RK4 steps of dx/dt = f(x) over ``duration``, operation for operation
    :func:`twolink.arm.integrate.rk4`, in whatever ``x`` is (CasADi symbols or numbers)."""
    h = duration / substeps
    for _ in range(substeps):
        k1 = f(x)
        k2 = f(x + 0.5 * h * k1)
        k3 = f(x + 0.5 * h * k2)
        k4 = f(x + h * k3)
        x = x + (h / 6.0) * (k1 + 2.0 * k2 + 2.0 * k3 + k4)
    return x


def step_function(model: str = "full", params: ArmParameters = TABLE_I, *,
                  ts: float = TS, substeps: int = SUBSTEPS):
    """The CasADi Function ``step(x[4], u[2]) -> x_next[4]`` of ``model`` (SX, so its
    derivatives are exact and cheap to evaluate)."""
    ca = require_casadi()
    x = ca.SX.sym("x", 4)
    u = ca.SX.sym("u", 2)
    return ca.Function(f"step_{check_model(model)}", [x, u],
                       [step_expression(ca, model, params, x, u, ts=ts, substeps=substeps)],
                       ["x", "u"], ["x_next"])
