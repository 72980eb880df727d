"""How well `twolink identify` does: parameter errors over many hidden plants, and what
the identified model is worth to a policy.

1. For ``--plants`` hidden plants (seeds ``--first-seed`` onwards; every physical
   parameter changed jointly within +-``--spread``), ``--duration`` s of data with
   ``--angle-noise-deg`` noise: the relative error of P1, P2, P3, b1, b2 (max, median,
   95th percentile of |error|), how often all five lie within 2 %, and how often the
   error lies within 2 bootstrap standard errors (are the standard errors honest?).
2. For the first ``--policy-plants`` of them: the centralized full-model policy
   synthesised on the identified parameters, on the hidden true parameters and on
   Table I, each run on a MuJoCo plant with the true parameters from the 65 states of
   the evaluation set; success counts with 95 % Wilson intervals and the difference
   identified - true in points.

The evaluation seeds (default 10000 on) were not used to choose the method or its
settings (those were chosen on other seeds). Prints tables; ``--json PATH`` also merges
the run into PATH (schema ``twolink.identification_study``, version 1: one entry of
``runs`` per set of options, a rerun with the same options replaces its entry), from
which ``python docs/generate.py`` writes docs/results/identification.md.

Run: .venv/bin/python docs/studies/identification_study.py [--plants 48] [--policy-plants 8]
     [--first-seed 10000] [--json renders/identification/identification.json]
"""
from __future__ import annotations

import argparse
import sys
import time

import numpy as np
from tqdm import tqdm

from twolink.arm.parameters import TABLE_I
from twolink.artifacts import check_outputs, provenance, read_runs, write_json
from twolink.synthesis.synthesize import synthesize
from twolink.sim import excitation, identify
from twolink.sim.metrics import evaluation_set, success, wilson_interval
from twolink.sim.plants import make_plant
from twolink.sim.rollout import rollout
from twolink.viz.formatting import format_rate

MAX_PLANTS = 1000
MAX_POLICY_PLANTS = 64
TARGET = 0.02
#: What the --json file calls itself; docs/generate.py refuses any other.
SCHEMA, VERSION = "twolink.identification_study", 1


def measure_identification(seeds, *, spread, duration, noise, bootstrap, progress=True):
    """Per plant: the truth, the fit and the relative errors (a list of dicts)."""
    rows = []
    for seed in tqdm(seeds, desc="identify", disable=not progress, file=sys.stderr):
        start = time.perf_counter()
        log = excitation.experiment(seed, spread=spread, duration=duration,
                                    angle_noise_deg=noise)
        fit = identify.fit(log, bootstrap=bootstrap)
        truth = excitation.hidden_plant(seed, spread)
        rows.append({"seed": seed, "seconds": time.perf_counter() - start,
                     "truth": {k: getattr(truth, k) for k in identify.IDENTIFIABLE},
                     "fit": fit.values, "std_error": fit.std_errors,
                     "relative_error": fit.relative_errors(truth),
                     "params": fit.params(), "truth_params": truth})
    return rows


def summarise_identification(rows) -> dict:
    err = np.array([[r["relative_error"][k] for k in identify.IDENTIFIABLE] for r in rows])
    z = np.array([[abs(r["fit"][k] - r["truth"][k]) / r["std_error"][k]
                   for k in identify.IDENTIFIABLE] for r in rows])
    within = int(np.sum(np.abs(err).max(axis=1) < TARGET))
    lo, hi = wilson_interval(within, len(rows))
    return {
        "plants": len(rows),
        "per_parameter": {k: {"max_abs_percent": 100 * float(np.abs(err[:, i]).max()),
                              "median_abs_percent": 100 * float(np.median(np.abs(err[:, i]))),
                              "p95_abs_percent": 100 * float(np.percentile(np.abs(err[:, i]), 95)),
                              "within_2_std_errors": int(np.sum(z[:, i] <= 2.0))}
                          for i, k in enumerate(identify.IDENTIFIABLE)},
        "all_within_2_percent": within, "all_within_2_percent_wilson": [lo, hi],
        "median_seconds": float(np.median([r["seconds"] for r in rows])),
    }


def measure_policies(rows, *, progress=True) -> list:
    """Success of the centralized full-model policy synthesised on the identified, the
    true and Table I's parameters, on MuJoCo plants with the true parameters."""
    x0 = evaluation_set()
    nominal = synthesize("centralized", TABLE_I, model="full")
    out = []
    for r in tqdm(rows, desc="policies", disable=not progress, file=sys.stderr):
        truth = r["truth_params"]
        policies = {"identified": synthesize("centralized", r["params"], model="full"),
                    "true": synthesize("centralized", truth, model="full"),
                    "table_i": nominal}
        counts = {}
        with make_plant("mujoco", truth) as plant:
            for label, policy in policies.items():
                counts[label] = int(success(rollout(policy, plant, x0)).sum())
        out.append({"seed": r["seed"], "states": len(x0), "successes": counts})
    return out


def summarise_policies(runs) -> dict:
    n = sum(r["states"] for r in runs)
    totals = {k: sum(r["successes"][k] for r in runs) for k in runs[0]["successes"]}
    return {"runs": n, "plants": len(runs),
            "successes": totals,
            "wilson": {k: list(wilson_interval(v, n)) for k, v in totals.items()},
            "identified_minus_true_points": 100 * (totals["identified"] - totals["true"]) / n,
            "worst_plant_points": min(100 * (r["successes"]["identified"] -
                                             r["successes"]["true"]) / r["states"]
                                      for r in runs)}


def _print(ident, policy_summary, policy_runs, args) -> None:
    print(f"Identification: {ident['plants']} hidden plants (seeds {args.first_seed}.."
          f"{args.first_seed + args.plants - 1}, +-{100 * args.spread:g} %), "
          f"{args.duration:g} s of data, {args.angle_noise_deg:g} deg angle noise")
    print(f"{'param':<6} {'max |err| %':>12} {'median %':>9} {'p95 %':>7} {'|err| <= 2 SE':>14}")
    for k, s in ident["per_parameter"].items():
        print(f"{k:<6} {s['max_abs_percent']:>12.2f} {s['median_abs_percent']:>9.2f} "
              f"{s['p95_abs_percent']:>7.2f} {s['within_2_std_errors']:>8}/{ident['plants']}")
    print(f"all five within 2 %: {format_rate(ident['all_within_2_percent'], ident['plants'])}; "
          f"median time per identification {ident['median_seconds']:.2f} s")
    if policy_summary:
        n = policy_summary["runs"]
        print(f"\nCentralized full-model policy on MuJoCo plants with the true parameters "
              f"({policy_summary['plants']} plants x 65 states):")
        for k, v in policy_summary["successes"].items():
            print(f"  synthesised on {k:<10} {format_rate(v, n)}")
        print(f"  identified - true: {policy_summary['identified_minus_true_points']:+.2f} "
              f"points (worst plant {policy_summary['worst_plant_points']:+.2f})")
        print("  per plant (identified / true / table_i): " + ", ".join(
            f"{r['seed']}: {r['successes']['identified']}/{r['successes']['true']}/"
            f"{r['successes']['table_i']}" for r in policy_runs))


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--plants", type=int, default=48, help="hidden plants (default 48)")
    parser.add_argument("--policy-plants", type=int, default=8,
                        help="plants of the policy comparison, the first of --plants (default 8)")
    parser.add_argument("--first-seed", type=int, default=10000,
                        help="seed of the first plant (default 10000; not used for tuning)")
    parser.add_argument("--spread", type=float, default=0.2)
    parser.add_argument("--duration", type=float, default=10.0)
    parser.add_argument("--angle-noise-deg", type=float, default=1.0)
    parser.add_argument("--bootstrap", type=int, default=20)
    parser.add_argument("--json", default=None, metavar="PATH",
                        help="also merge the run into PATH (versioned JSON)")
    args = parser.parse_args(argv)
    try:
        if args.json:
            check_outputs({"--json": args.json})
            old = read_runs(args.json, SCHEMA, VERSION)
        if not 1 <= args.plants <= MAX_PLANTS:
            raise ValueError(f"--plants must lie in [1, {MAX_PLANTS}]")
        if not 0 <= args.policy_plants <= min(args.plants, MAX_POLICY_PLANTS):
            raise ValueError(f"--policy-plants must lie in [0, min(--plants, "
                             f"{MAX_POLICY_PLANTS})]")
        excitation.check_experiment(duration=args.duration, angle_noise_deg=args.angle_noise_deg,
                                    seed=args.first_seed, excitation="bang-bang",
                                    spread=args.spread)
        identify.check_bootstrap(args.bootstrap)
    except (OSError, ValueError) as exc:
        print(f"identification_study: error: {exc}", file=sys.stderr)
        return 2
    start = time.perf_counter()
    seeds = range(args.first_seed, args.first_seed + args.plants)
    rows = measure_identification(seeds, spread=args.spread, duration=args.duration,
                                  noise=args.angle_noise_deg, bootstrap=args.bootstrap,
                                  progress=True)
    ident = summarise_identification(rows)
    runs = measure_policies(rows[:args.policy_plants], progress=True) \
        if args.policy_plants else []
    pol = summarise_policies(runs) if runs else None
    _print(ident, pol, runs, args)
    if args.json:
        plain = [{k: v for k, v in r.items() if k not in ("params", "truth_params")}
                 for r in rows]
        options = {k: v for k, v in vars(args).items() if k != "json"}
        run = {"options": options, "identification": ident, "plants": plain,
               "policies": pol, "policy_runs": runs,
               "seconds": time.perf_counter() - start}
        kept = [r for r in old["runs"] if r["options"] != options]
        write_json(args.json, {"schema": SCHEMA, "version": VERSION,
                               "provenance": provenance(), "runs": kept + [run]})
        print(f"wrote {args.json}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
