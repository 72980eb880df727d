"""The Gymnasium ids of the arm, registered without importing the environments.

``import twolink`` calls :func:`install`: when gymnasium is (or later gets) imported,
:func:`register` adds :data:`ENV_ID` and :data:`DISCRETE_ID` with string entry points
into :mod:`twolink.envs.gym`, which loads only at ``gymnasium.make``. Nothing here
imports gymnasium, numpy or mujoco before the user does.
"""
from __future__ import annotations

from twolink._imports import around_import

#: The continuous-torque environment (:class:`twolink.envs.gym.TwoLinkEnv`).
ENV_ID = "twolink/TwoLink-v0"
#: The same environment with the 9 discrete joint actions of (16).
DISCRETE_ID = "twolink/TwoLinkDiscrete-v0"
_ENTRY = "twolink.envs.gym"


def register() -> None:
    """Register :data:`ENV_ID` and :data:`DISCRETE_ID` with Gymnasium (idempotent)."""
    import gymnasium

    for env_id, kwargs in ((ENV_ID, {}), (DISCRETE_ID, {"actions": "discrete"})):
        if env_id not in gymnasium.registry:
            gymnasium.register(env_id, entry_point=f"{_ENTRY}:TwoLinkEnv",
                               vector_entry_point=f"{_ENTRY}:TwoLinkVectorEnv",
                               kwargs=kwargs)


def install() -> None:
    """Register now if gymnasium is imported, else as soon as it is."""
    around_import("gymnasium", lambda module: register())
