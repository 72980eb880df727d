"""``twolink identify``: fit P1, P2, P3, b1, b2 to a logged MuJoCo experiment.

A plant drawn from ``--seed`` (every physical parameter changed jointly within
``--spread``; the fit never sees it) is excited, its angles logged with noise, and the
identified model written as a parameter file (``./identified.json`` by default, kept
unless ``--force``) that ``twolink synthesize --model identified --params FILE`` reads.
``--reveal`` prints the hidden plant's values beside the fit afterwards.
"""
from __future__ import annotations

import argparse
import json

from twolink.arm import parameter_file
from twolink.arm.parameters import TS
from twolink.artifacts import check_outputs, make_folders, output_file, provenance
from twolink.commands import SUMMARIES
from twolink.commands.grammar import add_out
from twolink.commands._options import seed_option
from twolink.sim import excitation, identify

DEFAULT_OUTPUT = "identified.json"


def _number(kind, what: str):
    def parse(text: str):
        try:
            return kind(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{what}, got {text!r}") from None
    return parse


def add_parser(sub):
    p = sub.add_parser(
        "identify", help=SUMMARIES["identify"],
        description="Excite a MuJoCo arm whose parameters the command is not told (drawn "
                    "from --seed within --spread of Table I), log its angles with noise, "
                    "and fit the parameters the data determine (P1, P2, P3 of (10), b1, b2) "
                    "by least squares on the linear-in-parameters form of (6), with "
                    "bootstrap standard errors. Writes a parameter file (default "
                    f"./{DEFAULT_OUTPUT}; an existing file is kept unless --force) for "
                    "`twolink synthesize --model identified --params FILE`.")
    p.add_argument("--seed", type=_number(int, "must be a whole number"), default=0,
                   help="seed of the hidden plant, the excitation and the noise (default 0)")
    p.add_argument("--spread", type=_number(float, "must be a number"), default=0.2,
                   help="the hidden plant's physical parameters each change by a relative "
                        f"amount uniform in +-SPREAD (default 0.2; at most "
                        f"{excitation.MAX_HIDDEN_SPREAD:g})")
    p.add_argument("--duration", type=_number(float, "must be a number of seconds"),
                   default=10.0, help=f"seconds of data (default 10; "
                                      f"{excitation.MIN_DURATION:g} to "
                                      f"{excitation.MAX_DURATION:g})")
    p.add_argument("--angle-noise-deg", type=_number(float, "must be a number"), default=1.0,
                   help="standard deviation of the angle readings' noise in degrees "
                        f"(default 1; at most {excitation.MAX_NOISE_DEG:g})")
    p.add_argument("--excitation", choices=list(excitation.EXCITATIONS), default="bang-bang",
                   help="torque signal: " + "; ".join(
                       f"{k}: {v}" for k, v in excitation.EXCITATIONS.items()).replace("%", "%%"))
    p.add_argument("--bootstrap", type=_number(int, "must be a whole number"), default=20,
                   help="bootstrap replicates for the standard errors (default 20; 2 to "
                        f"{identify.MAX_BOOTSTRAP})")
    add_out(p, "identify", default=None, metavar="FILE",
            help=f"parameter file to write (default ./{DEFAULT_OUTPUT}; DIR/ writes "
                 f"DIR/{DEFAULT_OUTPUT}, making DIR)")
    p.add_argument("--force", action="store_true", help="overwrite an existing output file")
    p.add_argument("--reveal", action="store_true",
                   help="after the fit, print the hidden plant's values and the errors")
    p.add_argument("--json", action="store_true", help="print the result as JSON")
    return p


def _table(result: dict) -> str:
    """The fit as a fixed-width table (with the truth when revealed)."""
    truth = result.get("truth")
    head = f"{'parameter':<10} {'fit':>12} {'std error':>18}"
    if truth:
        head += f" {'truth':>12} {'error':>8}"
    lines = [head]
    for name, entry in result["identified"].items():
        value, se = entry["value"], entry["std_error"]
        line = f"{name:<10} {value:>12.6g} {se:>9.2g} ({100 * se / value:4.2f} %)"
        if truth:
            line += f" {truth[name]:>12.6g} {100 * result['relative_error'][name]:>+7.2f} %"
        lines.append(line)
    return "\n".join(lines)


def run(args) -> int:
    seed_option(args.seed)
    out, folders = output_file(args.output, DEFAULT_OUTPUT)
    check_outputs({"-o": out}, creatable=folders)
    if out.exists() and not args.force:
        raise OSError(f"{out} exists; give --force to overwrite it or -o another file")
    excitation.check_experiment(duration=args.duration, angle_noise_deg=args.angle_noise_deg,
                                seed=args.seed, excitation=args.excitation, spread=args.spread)
    identify.check_bootstrap(args.bootstrap)
    log = excitation.experiment(args.seed, spread=args.spread, duration=args.duration,
                                angle_noise_deg=args.angle_noise_deg, excitation=args.excitation)
    fit = identify.fit(log, bootstrap=args.bootstrap)
    params = fit.params()
    record = fit.as_dict()
    record["realisation"] = identify.REALISATION
    record["experiment"] = {
        "seed": args.seed, "spread": args.spread, "duration_s": log.duration,
        "angle_noise_deg": args.angle_noise_deg, "excitation": args.excitation,
        "excitation_description": excitation.EXCITATIONS[args.excitation],
        "reading_interval_s": log.dt, "control_period_s": TS, "readings": len(log.angles),
        "speeds_measured": False}
    make_folders(folders)
    parameter_file.save(out, params, provenance={"command": "twolink identify", **record,
                                                 "environment": provenance()})
    result = {"path": str(out), **record, "parameters": params.as_dict()}
    if args.reveal:
        truth = excitation.hidden_plant(args.seed, args.spread)
        result["truth"] = {k: getattr(truth, k) for k in identify.IDENTIFIABLE}
        result["relative_error"] = fit.relative_errors(truth)
    if args.json:
        print(json.dumps(result, indent=2))
        return 0
    print(f"identified from {log.duration:g} s of angles ({len(log.angles)} readings every "
          f"{1000 * log.dt:g} ms, {args.angle_noise_deg:g} deg noise, estimated "
          f"{fit.noise_deg_estimate:.2f} deg), {args.excitation} excitation, seed {args.seed}:")
    print(_table(result))
    print(f"condition number {fit.condition_number:.3g}; standard errors from "
          f"{fit.bootstrap} bootstrap replicates")
    print("not identifiable: " + "; ".join(f"{k} ({v})"
                                           for k, v in identify.NOT_IDENTIFIABLE.items()))
    print(f"wrote {out}")
    return 0
