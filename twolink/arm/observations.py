"""What a learner observes of a state: the ``'state'`` itself or its ``'cos_sin'``
features (:func:`features`), the observations of the Gymnasium and Stable-Baselines3
environments (:mod:`twolink.envs.gym_arms`) and of the controllers that run agents
trained on them (:mod:`twolink.control.sb3_agent`)."""
from __future__ import annotations

import numpy as np

#: The observations :func:`features` makes.
OBSERVATIONS = ("state", "cos_sin")


def features(x: np.ndarray, observation: str = "state") -> np.ndarray:
    """The observation of (measured) states x (..., 2N): ``'state'`` as given (a copy), or
    ``'cos_sin'`` = [cos theta1, sin theta1, .., cos thetaN, sin thetaN, dtheta1 ..
    dthetaN] (for two links [cos theta1, sin theta1, cos theta2, sin theta2, dtheta1,
    dtheta2])."""
    x = np.asarray(x)
    if observation == "state":
        return x.copy()
    n = x.shape[-1] // 2
    trig = [f(x[..., k]) for k in range(n) for f in (np.cos, np.sin)]
    return np.stack(trig + [x[..., n + k] for k in range(n)], -1)
