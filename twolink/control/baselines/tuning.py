"""Tuning of the shipped baselines, and the command that re-creates ``gains.json``:

    python -m twolink.control.baselines.tuning            # tune, print the document
    python -m twolink.control.baselines.tuning --write    # tune, write gains.json

Every baseline is tuned by a coordinate grid search (:mod:`twolink.control.baselines.search`)
on the full model (6), never on the evaluation set nor on the seeds figures are reported
with: the nominal ones (``pd``, ``lqr``, ``bang_bang``) on :data:`TUNING_POSES` random
poses at rest (``random_poses(2, 64, seed=POSE_SEED)``) of the Table I arm; the ones for
imperfect plants and readings (``pd_deadzone``, ``lqr_delay``) on :data:`CHALLENGE_PLANTS`
plants of the ``medium`` challenge drawn from :data:`PLANT_SEED` (its delay, noise and
plants, noise drawn from the same seed, no compensation) from the first
:data:`CHALLENGE_POSES` of those poses. The score is the success count, then the median
settle time, then the mean settle time (failures at the horizon). The chosen gains are
then run once on MuJoCo on the same tuning states and plants (``mujoco_check``).
About two minutes on two cores.
"""
from __future__ import annotations

import argparse
import dataclasses
import sys
import time
from collections.abc import Callable

import numpy as np

from twolink.arm.parameters import TABLE_I
from twolink.artifacts import VERSION, write_json
from twolink.control.baselines.bang_bang import ProximateTimeOptimal
from twolink.control.baselines.common import joint_inertia
from twolink.control.baselines.lqr import SaturatedLQR
from twolink.control.baselines.pd import SaturatedPD
from twolink.control.baselines.registry import GAINS_FORMAT, check_gains, gains_path
from twolink.control.baselines.search import coordinate_search, run_candidates, score
from twolink.sim.challenges import LEVELS
from twolink.sim.evaluation import evaluate
from twolink.sim.metrics import random_poses
from twolink.sim.plants import make_plant
from twolink.sim.rollout import rollout

#: Seed of the tuning poses (random_poses(2, TUNING_POSES, seed=POSE_SEED)).
POSE_SEED = 8101
#: Seed of the medium challenge's tuning plants, noise and faults (evaluate's seed).
PLANT_SEED = 8102
TUNING_POSES = 64
CHALLENGE_PLANTS = 16
CHALLENGE_POSES = 32
#: Seeds the reported figures must not use.
TUNING_SEEDS = (POSE_SEED, PLANT_SEED)

_J = joint_inertia(TABLE_I)
_TAU = TABLE_I.tau_max

#: The grids, per coordinate (geometric ladders).
SATURATION_DEG = [3, 5, 7, 10, 14, 20, 28, 40, 57, 80]
ZETA = [0.3, 0.4, 0.5, 0.7, 1.0, 1.4, 2.0, 2.8]
DEAD_ZONE_DEG = [0, 0.5, 1, 1.5, 2, 2.5, 3, 4]
ANGLE_SCALE_DEG = [1, 2, 3, 5, 7, 10, 14, 20, 30, 45]
SPEED_SCALE = [0.1, 0.2, 0.3, 0.5, 0.7, 1, 1.5, 2, 3, 5]
ALPHA = [0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.9, 1.0, 1.2, 1.5, 2.0, 3.0]
OMEGA = [2, 3, 4, 6, 8, 11, 16, 22]


def pd_from(pt: dict, name: str) -> SaturatedPD:
    """kp_i = tau_max_i / sat_i (the angle where the P term alone saturates) and
    kd_i = 2 zeta_i sqrt(kp_i J_i) (J of :func:`twolink.control.baselines.common.joint_inertia`)."""
    sat = np.radians([pt["sat1_deg"], pt["sat2_deg"]])
    kp = _TAU / sat
    kd = 2.0 * np.array([pt["zeta1"], pt["zeta2"]]) * np.sqrt(kp * _J)
    return SaturatedPD(kp, kd, dead_zone_deg=pt.get("dead_zone_deg", 0.0), name=name)


def lqr_from(pt: dict, name: str, delay: int = 0) -> SaturatedLQR:
    """Bryson-style weights: q = 1 / scale^2 (angle scales in degrees, speed scales in
    rad/s), r = 1 / tau_max^2."""
    a = np.radians([pt["angle1_deg"], pt["angle2_deg"]])
    s = np.array([pt["speed1"], pt["speed2"]])
    return SaturatedLQR(np.concatenate([1.0 / a ** 2, 1.0 / s ** 2]), 1.0 / _TAU ** 2,
                        delay=delay, name=name)


def ptos_from(pt: dict, name: str) -> ProximateTimeOptimal:
    return ProximateTimeOptimal([pt["alpha1"], pt["alpha2"]], [pt["omega1"], pt["omega2"]],
                                name=name)


@dataclasses.dataclass(frozen=True)
class Spec:
    """How one baseline is tuned: its coordinates' start and grids, how a point becomes
    a controller, and the challenge it is tuned under."""

    name: str
    build: Callable[[dict, str], object]
    start: dict
    grid: dict
    challenge: str = "none"
    parametrisation: str = ""


_PD_GRID = {"sat1_deg": SATURATION_DEG, "sat2_deg": SATURATION_DEG, "zeta1": ZETA,
            "zeta2": ZETA}
_LQR_GRID = {"angle1_deg": ANGLE_SCALE_DEG, "angle2_deg": ANGLE_SCALE_DEG,
             "speed1": SPEED_SCALE, "speed2": SPEED_SCALE}
_PD_TEXT = "kp_i = tau_max_i / radians(sat_i_deg), kd_i = 2 zeta_i sqrt(kp_i J_i), " \
           "J of twolink.control.baselines.common.joint_inertia (Table I)"
_LQR_TEXT = "q = [1/radians(angle1_deg)^2, 1/radians(angle2_deg)^2, 1/speed1^2, " \
            "1/speed2^2], r = 1/tau_max^2"

#: The tuning of every shipped baseline, in the order it runs.
SPECS = {s.name: s for s in (
    Spec("pd", pd_from, {"sat1_deg": 20, "sat2_deg": 20, "zeta1": 0.7, "zeta2": 0.7},
         _PD_GRID, parametrisation=_PD_TEXT),
    Spec("pd_deadzone", pd_from, {"dead_zone_deg": 3, "sat1_deg": 28, "sat2_deg": 28,
                                  "zeta1": 0.7, "zeta2": 0.5},
         {"dead_zone_deg": DEAD_ZONE_DEG, **_PD_GRID}, challenge="medium",
         parametrisation=_PD_TEXT + "; angle error 0 inside +-dead_zone_deg, shrunk by it "
         "outside"),
    Spec("lqr", lqr_from, {"angle1_deg": 10, "angle2_deg": 10, "speed1": 1, "speed2": 1},
         _LQR_GRID, parametrisation=_LQR_TEXT),
    Spec("lqr_delay", lambda pt, name: lqr_from(pt, name, LEVELS["medium"].action_delay),
         {"angle1_deg": 20, "angle2_deg": 20, "speed1": 1, "speed2": 1}, _LQR_GRID,
         challenge="medium",
         parametrisation=_LQR_TEXT + "; state augmented with the last "
         f"{LEVELS['medium'].action_delay} torque(s)"),
    Spec("bang_bang", ptos_from, {"alpha1": 0.8, "alpha2": 0.8, "omega1": 6, "omega2": 6},
         {"alpha1": ALPHA, "alpha2": ALPHA, "omega1": OMEGA, "omega2": OMEGA},
         parametrisation="alpha and omega per joint, J and tau_max of Table I"),
)}


def tuning_states(spec: Spec) -> np.ndarray:
    poses = random_poses(2, TUNING_POSES, seed=POSE_SEED)
    return poses if spec.challenge == "none" else poses[:CHALLENGE_POSES]


def tuning_plants(spec: Spec) -> list:
    ch = LEVELS[spec.challenge]
    return ch.plants(CHALLENGE_PLANTS, PLANT_SEED) if ch.perturbs_plant() else [TABLE_I]


def mujoco_check(spec: Spec, ctrl) -> dict:
    """The chosen controller on MuJoCo, on the tuning states (and plants, seed)."""
    x0 = tuning_states(spec)
    if spec.challenge == "none":
        with make_plant("mujoco", TABLE_I) as plant:
            from twolink.sim.metrics import settle_time, success
            traj = rollout(ctrl, plant, x0)
        return score(success(traj), settle_time(traj))
    ev = evaluate(ctrl, challenge=spec.challenge, compensate=False, count=CHALLENGE_PLANTS,
                  seed=PLANT_SEED, x0=x0)
    return score(np.asarray(ev.success), np.asarray(ev.settle))


def tune(spec: Spec, *, log=print) -> dict:
    """Tune one baseline: its gains document entry (controller and provenance)."""
    t0 = time.perf_counter()
    start = dict(spec.start)
    x0, plants = tuning_states(spec), tuning_plants(spec)
    ch = LEVELS[spec.challenge]
    count = [0]

    def evaluate_points(points):
        ctrls = [spec.build(pt, spec.name) for pt in points]
        ok, settle = run_candidates(ctrls, x0, plants, ch, seed=PLANT_SEED)
        count[0] += len(points)
        return [score(ok[i], settle[i]) for i in range(len(points))]

    point, best, history = coordinate_search(evaluate_points, start, spec.grid)
    ctrl = spec.build(point, spec.name)
    check = mujoco_check(spec, ctrl)
    seconds = time.perf_counter() - t0
    log(f"{spec.name}: {best['successes']}/{best['n']} on the tuning set, median settle "
        f"{best['median_settle']} s (MuJoCo check {check['successes']}/{check['n']}, "
        f"{check['median_settle']} s); {count[0]} candidates, {seconds:.0f} s")
    states = f"twolink.sim.metrics.random_poses(2, {TUNING_POSES}, seed={POSE_SEED})"
    if spec.challenge != "none":
        states += f"[:{CHALLENGE_POSES}]"
    return {"controller": ctrl.as_dict(),
            "tuning": {
                "method": "coordinate grid search (twolink.control.baselines.search)",
                "optimised": "success count, then median settle time, then mean settle "
                             "time (failures at the horizon)",
                "parametrisation": spec.parametrisation, "point": point,
                "grid": spec.grid, "start": start, "candidates": count[0],
                "plant": "full model (6), numpy RK4 (twolink.control.baselines.search."
                         "RowPlant)",
                "challenge": spec.challenge, "compensated": False, "states": states,
                "pose_seed": POSE_SEED,
                "plants": (f"LEVELS['{spec.challenge}'].plants({CHALLENGE_PLANTS}, "
                           f"seed={PLANT_SEED})" if spec.challenge != "none" else "Table I"),
                "noise_seed": PLANT_SEED if spec.challenge != "none" else None,
                "score": best, "mujoco_check": check, "path": history,
                "seconds": round(seconds, 1)}}


def tune_all(names=None, *, log=print) -> dict:
    """The gains document of every baseline (or of ``names``)."""
    want = list(SPECS) if not names else list(dict.fromkeys(names))
    unknown = sorted(set(want) - set(SPECS))
    if unknown:
        raise ValueError(f"unknown baseline(s) {unknown}; choose from {', '.join(SPECS)}")
    done = {name: tune(SPECS[name], log=log) for name in want}
    return check_gains({
        "format": GAINS_FORMAT, "twolink_version": VERSION,
        "created_by": "python -m twolink.control.baselines.tuning --write",
        "tuning_seeds": {"poses": POSE_SEED, "plants_and_noise": PLANT_SEED},
        "note": "tuned off the evaluation set (twolink.sim.metrics.evaluation_set) and "
                "off the seeds of reported figures; the gains are the 'controller' entries",
        "controllers": {n: done[n] for n in want}})


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m twolink.control.baselines.tuning",
                                 description="Tune the classical baselines (off the "
                                 "evaluation set) and print or write gains.json.")
    ap.add_argument("--write", action="store_true",
                    help=f"write the package's {gains_path().name} (else print the document)")
    ap.add_argument("--out", help="write the document to this path instead")
    ap.add_argument("--only", nargs="+", choices=list(SPECS), help="tune only these")
    args = ap.parse_args(argv)
    if args.write and args.only:
        ap.error("--write re-creates the whole file; leave out --only (or use --out)")
    log = (lambda msg: print(msg, file=sys.stderr, flush=True))
    doc = tune_all(args.only, log=log)
    if args.write or args.out:
        path = write_json(args.out or str(gains_path()), doc)
        log(f"wrote {path}")
    else:
        import json
        print(json.dumps(doc, indent=2, sort_keys=True))
    return 0


if __name__ == "__main__":
    sys.exit(main())
