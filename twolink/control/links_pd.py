"""Saturated per-joint PD for an arm of N links: joint i sees only its own angle and speed,

    tau_i = clip(-kp_i theta_i - kd_i dtheta_i, -tau_max_i, tau_max_i),

theta_i wrapped to [-pi, pi). The gains come from two numbers shared by every joint, as
the two-link ``pd`` baseline is parametrised (:func:`twolink.control.baselines.tuning.pd_from`):
``sat_deg``, the angle at which the P term alone saturates (kp_i = tau_max_i /
radians(sat_deg)), and ``zeta``, the damping ratio on the inertia joint i sees on its
own with every other joint free (kd_i = 2 zeta sqrt(kp_i J_i), J_i = 1 / (M0^-1)_ii of
:func:`twolink.arm.dynamics.links_mass_matrix` at theta = 0).

:func:`tune` picks (sat_deg, zeta) for one arm on a grid, from random poses at rest drawn
from :data:`TUNING_SEED` + N on the MuJoCo plant: the most successes, then the lowest
median and mean settle time. :data:`TUNED` holds the picks (re-created by
``python -m twolink.control.links_pd``); the scaling study evaluates them on
its own seeds, which the tuning never reads.
"""
from __future__ import annotations

import argparse
import json
import math
import sys

import numpy as np

from twolink._imports import renamed
from twolink.arm.dynamics import links_mass_matrix
from twolink.arm.integrate import wrap_angle
from twolink.arm.parameters import (
    LINK_RULES,
    MAX_LINKS,
    LinksParameters,
    as_links,
    links_parameters,
)
from twolink.validate import real

#: Seed of the tuning poses: random_poses(N, TUNING_POSES, TUNING_SEED + N). Apart from
#: the scaling study's evaluation seed (20061122 + N) and the development seeds of the
#: decentralized agents' constructions (500-599).
TUNING_SEED = 7100
TUNING_POSES = 64
#: The grid of :func:`tune`.
SAT_DEG = (10, 20, 40, 57, 80)
ZETA = (0.5, 0.7, 1.0, 1.4, 2.0)
#: The tuned (sat_deg, zeta) per (links, rule), from ``python -m
#: twolink.control.links_pd`` (successes of the 64 tuning poses and the median
#: settle time in seconds beside each; inf: half or more never settle).
TUNED = {
    (3, "tapered"): {"sat_deg": 20, "zeta": 1.0, "successes": 64, "median_settle": 3.15},
    (4, "tapered"): {"sat_deg": 40, "zeta": 1.4, "successes": 64, "median_settle": 4.4},
    (5, "tapered"): {"sat_deg": 40, "zeta": 1.4, "successes": 39, "median_settle": 6.075},
    (6, "tapered"): {"sat_deg": 40, "zeta": 1.4, "successes": 9, "median_settle": math.inf},
    (3, "copied"): {"sat_deg": 57, "zeta": 1.4, "successes": 64, "median_settle": 4.8},
    (4, "copied"): {"sat_deg": 57, "zeta": 1.4, "successes": 13, "median_settle": math.inf},
    (5, "copied"): {"sat_deg": 80, "zeta": 1.4, "successes": 6, "median_settle": math.inf},
    (6, "copied"): {"sat_deg": 80, "zeta": 1.4, "successes": 10, "median_settle": math.inf},
}


def joint_inertias(p) -> np.ndarray:
    """The inertia each joint of ``p`` sees on its own at theta = 0 with the others free:
    1 / (M0^-1)_ii (kg m^2)."""
    c = as_links(p)
    m0 = links_mass_matrix(c, np.zeros(c.links))
    return 1.0 / np.diag(np.linalg.inv(m0))


class LinksPD:
    """Per-joint saturated PD for an N-link arm (module docstring). ``kp`` (> 0), ``kd``
    (>= 0) and ``tau_max`` (> 0): one value per joint."""

    kind = "decentralized"

    def __init__(self, kp, kd, tau_max, *, name: str = "pd"):
        self.kp, self.kd, self.tau_max = (np.asarray(v, dtype=float).ravel()
                                          for v in (kp, kd, tau_max))
        n = len(self.tau_max)
        for what, v, strict in (("kp", self.kp, True), ("kd", self.kd, False),
                                ("tau_max", self.tau_max, True)):
            if len(v) != n or not np.all(np.isfinite(v)) or \
                    np.any(v <= 0 if strict else v < 0):
                raise ValueError(f"{what} must be {n} finite numbers "
                                 f"{'>' if strict else '>='} 0, got {v.tolist()}")
        self.links = n
        self.name = name

    @property
    def meta(self) -> dict:
        return {"name": self.name, "type": "chain_pd", "links": self.links}

    def __call__(self, x) -> np.ndarray:
        x = np.asarray(x, dtype=float)
        n = self.links
        if x.ndim < 1 or x.shape[-1] != 2 * n:
            raise ValueError(f"states must have shape (..., {2 * n}) for {n} links, "
                             f"got {x.shape}")
        theta, speed = wrap_angle(x[..., :n]), x[..., n:]
        return np.clip(-self.kp * theta - self.kd * speed, -self.tau_max, self.tau_max)

    def as_dict(self) -> dict:
        return {"type": "chain_pd", "name": self.name, "kp": self.kp.tolist(),
                "kd": self.kd.tolist(), "tau_max": self.tau_max.tolist()}


def make_links_pd(p: LinksParameters, sat_deg: float, zeta: float, *, name: str = "pd") -> LinksPD:
    """The PD of ``p`` with gains from ``sat_deg`` (> 0) and ``zeta`` (> 0)."""
    for what, v in (("sat_deg", sat_deg), ("zeta", zeta)):
        real(v, what, 0.0, open_low=True, numpy=False,
             message="{what} must be a positive number, got {value!r}")
    c = as_links(p)
    kp = c.tau_max / math.radians(sat_deg)
    kd = 2.0 * zeta * np.sqrt(kp * joint_inertias(c))
    return LinksPD(kp, kd, c.tau_max, name=name)


def tuned(p: LinksParameters, *, name: str = "pd") -> LinksPD:
    """The PD of ``p`` with the (sat_deg, zeta) of :data:`TUNED` for its links and rule;
    a ValueError for an arm that was not tuned."""
    c = as_links(p)
    got = TUNED.get((c.links, c.rule))
    if got is None:
        raise ValueError(f"no tuned PD gains for {c.links} {c.rule} links; tuned: "
                         f"{sorted(TUNED)}")
    return make_links_pd(c, got["sat_deg"], got["zeta"], name=name)


def _score(ok: np.ndarray, settle: np.ndarray, end: float) -> tuple:
    capped = np.where(ok, settle, end)
    return (int(ok.sum()), -float(np.median(capped)), -float(capped.mean()))


def tune(links: int, rule: str, *, poses: int = TUNING_POSES, seed: int = TUNING_SEED,
         log=None) -> dict:
    """The best (sat_deg, zeta) of the grid on MuJoCo from ``poses`` random poses at rest
    (seed ``seed`` + ``links``), with its successes and median settle time. Every
    candidate runs in one batch (rows candidate-major)."""
    from twolink.arm.parameters import horizon
    from twolink.sim.metrics import random_poses, settle_time, success
    from twolink.sim.plants import make_plant
    from twolink.sim.rollout import rollout

    p = links_parameters(links, rule)
    x0 = random_poses(links, poses, seed + links)
    grid = [(s, z) for s in SAT_DEG for z in ZETA]
    ctrls = [make_links_pd(p, s, z) for s, z in grid]
    kp = np.repeat([c.kp for c in ctrls], poses, axis=0)
    kd = np.repeat([c.kd for c in ctrls], poses, axis=0)
    stack = LinksPD(np.ones(links), np.zeros(links), p.tau_max, name="stack")

    def act(x):
        theta, speed = wrap_angle(x[..., :links]), x[..., links:]
        return np.clip(-kp * theta - kd * speed, -stack.tau_max, stack.tau_max)

    act.links = links
    end = horizon(links)
    with make_plant("mujoco", p) as plant:
        traj = rollout(act, plant, np.tile(x0, (len(grid), 1)), duration=end)
    ok = np.asarray(success(traj)).reshape(len(grid), poses)
    settle = np.asarray(settle_time(traj)).reshape(len(grid), poses)
    scores = [_score(ok[k], settle[k], end) for k in range(len(grid))]
    best = max(range(len(grid)), key=lambda k: scores[k])
    capped = np.where(ok[best], settle[best], np.inf)
    out = {"sat_deg": grid[best][0], "zeta": grid[best][1], "successes": scores[best][0],
           "n": poses, "median_settle": float(np.median(capped)), "seed": seed + links}
    if log:
        log(f"{links} {rule}: {out}")
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m twolink.control.links_pd",
                                 description="Tune the N-link per-joint PD on the tuning "
                                 "poses and print the TUNED table.")
    ap.add_argument("--links", type=int, nargs="+", default=list(range(3, MAX_LINKS + 1)))
    ap.add_argument("--rules", nargs="+", default=list(LINK_RULES), choices=LINK_RULES)
    args = ap.parse_args(argv)
    log = (lambda msg: print(msg, file=sys.stderr, flush=True))
    table = {f"{n} {r}": tune(n, r, log=log) for r in args.rules for n in args.links}
    print(json.dumps(table, indent=1))
    return 0


#: The names of 0.1 that said *chain*, kept until the next release (with a
#: DeprecationWarning; twolink._imports.renamed).
__getattr__ = renamed(__name__, {
    "ChainPD": "LinksPD", "chain_pd": "make_links_pd"
})


if __name__ == "__main__":
    sys.exit(main())
