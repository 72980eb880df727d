"""How much of the torque limit a two-link controller uses on the nominal arm.

``python docs/studies/torque_reach.py NAME=CONTROLLER [NAME=CONTROLLER ...] -o FILE.json``
runs each controller (a catalogue name or an agent file) from the 65 states of the
evaluation set for 5 s on MuJoCo's nominal arm and reports, per joint, the largest
|tau| / tau_max over every sample, and the fraction of samples at full torque
(|tau| >= 0.999 tau_max) in the first second, where the time-optimal limit T* of a far
state is bang-bang. It is the measurement behind ``twolink train --action-gain``
(:mod:`twolink.control.action_gain`): SAC's squashed actions stay off the limit without
a gain. The training guide quotes its output, ``renders/challenge_agents/torque_reach.json``.
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

import numpy as np  # noqa: E402

from twolink.arm.parameters import TABLE_I, TS  # noqa: E402
from twolink.artifacts import write_json  # noqa: E402
from twolink.control.controllers import resolve_controller  # noqa: E402
from twolink.sim.controller import ControllerError  # noqa: E402
from twolink.sim.metrics import evaluation_set  # noqa: E402
from twolink.sim.plants import make_plant  # noqa: E402
from twolink.sim.rollout import rollout  # noqa: E402

#: |tau| at or above this fraction of tau_max counts as full torque.
FULL = 0.999
#: The window of the full-torque fraction, seconds from the start.
EARLY_S = 1.0


def measure(spec: str) -> dict:
    """The torque use of the controller ``spec`` (see the module docstring)."""
    c = resolve_controller(spec)
    links = (getattr(c, "meta", None) or {}).get("links", 2)
    if links != 2:
        raise ValueError(f"{spec} is a {links}-link controller; this study runs two links")
    with make_plant("mujoco", TABLE_I) as plant:
        traj = rollout(c, plant, evaluation_set())
    frac = np.abs(traj.u) / TABLE_I.tau_max                   # (65, K, 2)
    early = frac[:, :int(round(EARLY_S / TS))]
    return {"largest_fraction": [float(v) for v in frac.max(axis=(0, 1))],
            "full_torque_share_first_s": [float(v) for v in (early >= FULL).mean(axis=(0, 1))],
            "samples": int(frac.shape[0] * frac.shape[1])}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("controllers", nargs="+", metavar="NAME=CONTROLLER")
    ap.add_argument("-o", "--out", type=Path, required=True, metavar="FILE.json")
    args = ap.parse_args(argv)
    pairs = []
    for item in args.controllers:
        name, sep, spec = item.partition("=")
        if not sep or not name or not spec:
            print(f"torque_reach: {item!r} is not NAME=CONTROLLER", file=sys.stderr)
            return 2
        pairs.append((name, spec))
    rows = {}
    for name, spec in pairs:
        try:
            rows[name] = measure(spec)
        except (ControllerError, ValueError, OSError) as exc:
            print(f"torque_reach: {name}: {exc}", file=sys.stderr)
            return 2
        r = rows[name]
        print(f"{name}: largest |tau|/tau_max " + ", ".join(
            f"{v:.3f}" for v in r["largest_fraction"]) + f"; full torque in the first "
            f"{EARLY_S:g} s " + ", ".join(f"{v:.1%}" for v in r["full_torque_share_first_s"]),
            flush=True)
    write_json(args.out, {"states": 65, "plant": "mujoco (nominal)", "full_at": FULL,
                          "early_s": EARLY_S, "rows": rows})
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
