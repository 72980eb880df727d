"""The bound loss of a Gaussian policy's mean: keeping an IPPO/MAPPO agent's mean action
within the action bounds (``twolink train --bound-loss C``).

skrl's Gaussian policies are not squashed: a sampled action is clipped to [-1, 1] by the
env, but the mean may drift beyond it. Once an agent's mean lies beyond a bound by several
of its standard deviations in the states it visits, every sample clips to the same
torque, every return is the same whatever it draws, and the policy gradient carries
nothing that brings the mean back. The bound loss of
rl_games' PPO (``bounds_loss_coef``, used across the Isaac Gym tasks) penalizes the mean's
excess over the bound:

    L_b = C * mean( max(|mu| - b, 0)^2 ),   b = :data:`BOUND`,

added to each update's loss. skrl 2.1.1's ``update`` gives no hook for another loss term,
so :func:`bounded` adds the gradient of L_b on the way back instead: it is the identity
forward, and its backward adds dL_b/dmu to the gradient arriving from the PPO loss. Each
minibatch's loss evaluates the policy's mean once, so the update's gradient is exactly
that of (PPO loss + L_b). Actions sampled while acting (no gradient) are untouched.
"""
from __future__ import annotations

#: The bound b beyond which the mean is penalized (the normalized action's limit).
BOUND = 1.0
#: The range of the coefficient C (0: no bound loss).
BOUND_LOSS_RANGE = (0.0, 100.0)


def check_bound_loss(value) -> float:
    """``value`` as a float if it lies in :data:`BOUND_LOSS_RANGE`; else one line."""
    from twolink.validate import in_range

    return in_range(value, "bound_loss", BOUND_LOSS_RANGE,
                    f"the weight of the penalty on a policy mean beyond +-{BOUND:g}")


def penalty(mu, coef: float):
    """L_b of the means ``mu`` (a torch tensor): C * mean(max(|mu| - b, 0)^2)."""
    torch = _torch()
    return coef * (torch.relu(mu.abs() - BOUND) ** 2).mean()


def bounded(mu, coef: float):
    """``mu`` unchanged, whose gradient gains dL_b/dmu = 2 C max(|mu| - b, 0) sign(mu) /
    mu.numel() on the way back (see the module docstring); ``mu`` itself when ``coef`` is
    0 or no gradient is being recorded."""
    torch = _torch()
    if coef <= 0 or not torch.is_grad_enabled() or not mu.requires_grad:
        return mu
    return _function()(mu, float(coef))


def _torch():
    import torch

    return torch


_FUNCTION = None


def _function():
    """The ``torch.autograd.Function`` of :func:`bounded`, made once (torch is optional)."""
    global _FUNCTION
    if _FUNCTION is None:
        torch = _torch()

        class Bounded(torch.autograd.Function):
            @staticmethod
            def forward(ctx, mu, coef):
                ctx.save_for_backward(mu)
                ctx.coef = coef
                return mu.view_as(mu)

            @staticmethod
            def backward(ctx, grad):
                (mu,) = ctx.saved_tensors
                excess = torch.relu(mu.abs() - BOUND) * mu.sign()
                return grad + 2.0 * ctx.coef * excess / mu.numel(), None

        _FUNCTION = Bounded.apply
    return _FUNCTION


__all__ = ["BOUND", "BOUND_LOSS_RANGE", "bounded", "check_bound_loss", "penalty"]
