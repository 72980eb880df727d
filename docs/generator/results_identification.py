"""docs/results/identification.md, from
``renders/identification/identification.json`` (:func:`identification_page`).
"""
from __future__ import annotations

from .common import _duration, _machine, _overlap, _stamp, _table


def identification_page(data: dict) -> str:
    """docs/studies/identification_study.py's runs: parameter errors over hidden plants
    and the policies synthesised on the identified parameters."""
    from twolink.viz.formatting import format_rate

    src = "renders/identification/identification.json"
    runs = sorted(data["runs"], key=lambda r: r["options"]["first_seed"])
    text = [_stamp(src), "# Identification: how well `twolink identify` does\n\n",
            "`docs/studies/identification_study.py` runs `twolink identify`'s experiment on "
            "hidden MuJoCo plants (every physical parameter changed jointly within the "
            "spread of Table I, drawn from the plant's seed), fits P1, P2, P3, b1, b2 and "
            "compares them with the truth: the largest, median and 95th-percentile relative "
            "error over the plants, and how often the error lies within 2 bootstrap "
            "standard errors (whether the standard errors are honest). Then, on the first "
            "plants of each run, it synthesises the centralized full-model policy on the "
            "identified parameters, on the true ones and on Table I, and runs each on a "
            "MuJoCo plant with the true parameters from the 65 states of the evaluation "
            "set. The plants' seeds were not used to choose the method or its settings. "
            "How the fit works: [Identification](../guides/identification.md).\n\n"]
    for run in runs:
        o, ident, pol = run["options"], run["identification"], run["policies"]
        last = o["first_seed"] + o["plants"] - 1
        per = ident["per_parameter"]
        text.append(f"## Seeds {o['first_seed']}–{last}\n\n{ident['plants']} hidden plants "
                    f"(±{100 * o['spread']:g} %), {o['duration']:g} s of data each with "
                    f"{o['angle_noise_deg']:g}° angle noise, {o['bootstrap']} bootstrap "
                    f"replicates; {_duration(run['seconds'])} for the run, "
                    f"{ident['median_seconds']:.2f} s per identification (median).\n\n")
        text += [_table(("parameter", "largest error", "median", "95th percentile",
                         "within 2 standard errors"),
                        [(k, f"{v['max_abs_percent']:.2f} %", f"{v['median_abs_percent']:.2f} %",
                          f"{v['p95_abs_percent']:.2f} %",
                          f"{v['within_2_std_errors']}/{ident['plants']}")
                         for k, v in per.items()]), "\n\n"]
        meds = [v["median_abs_percent"] for v in per.values()]
        worst = max(per, key=lambda k: per[k]["max_abs_percent"])
        text.append(f"The largest error of any parameter was {per[worst]['max_abs_percent']:.2f} % "
                    f"({worst}; medians {min(meds):.2f}–{max(meds):.2f} %); all five within 2 % "
                    f"on {format_rate(ident['all_within_2_percent'], ident['plants'])} of "
                    "the plants.\n\n")
        if pol:
            n = pol["runs"]
            same = sum(r["successes"]["identified"] == r["successes"]["true"]
                       for r in run["policy_runs"])
            text.append(f"The centralized full-model policy on the true MuJoCo plants "
                        f"({pol['plants']} plants × 65 states), synthesised on\n\n")
            text += [f"- {label}: {format_rate(pol['successes'][key], n)}\n"
                     for key, label in (("identified", "the identified parameters"),
                                        ("true", "the true parameters"),
                                        ("table_i", "Table I"))]
            verdict = ("overlapping" if _overlap((pol["successes"]["identified"], n),
                                                 (pol["successes"]["true"], n))
                       else "not overlapping")
            text.append(f"\nIdentified − true: {pol['identified_minus_true_points']:+.2f} "
                        f"points (intervals {verdict}; worst plant "
                        f"{pol['worst_plant_points']:+.2f} points); the two reach the same "
                        f"count on {same} of the {pol['plants']} plants. Per plant "
                        "(identified / true / Table I):\n\n")
            text += [_table(("seed", "identified", "true", "Table I"),
                            [(r["seed"], *(f"{r['successes'][k]}/{r['states']}"
                                           for k in ("identified", "true", "table_i")))
                             for r in run["policy_runs"]]), "\n\n"]
    text.append(f"Machine: {_machine(data['provenance'])}. Re-create the data with "
                + "; ".join(f"`python docs/studies/identification_study.py --plants "
                            f"{r['options']['plants']} --policy-plants "
                            f"{r['options']['policy_plants']} --first-seed "
                            f"{r['options']['first_seed']} --json {src}` ({_duration(r['seconds'])})"
                            for r in runs)
                + " (each run is merged into the file by its options), then "
                "`python docs/generate.py`.\n")
    return "".join(text)
