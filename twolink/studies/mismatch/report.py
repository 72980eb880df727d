"""The model-mismatch report as files: Markdown, JSON and figures, and the CLI's summary.

Presentation only: every number comes from the report that
:func:`twolink.studies.mismatch.measure.build` returns, in the order it holds them. Scores
are read through :func:`twolink.sim.metrics.score_keys`, so a report written before the one
spelling of their keys (``runs``, ``wilson95``: the committed renders/mismatch/report.json)
still reads.
"""
from __future__ import annotations

from pathlib import Path

from twolink.artifacts import staged_set, write_json, write_text
from twolink.sim.metrics import score_keys
from twolink.sim.perturbations import PERTURBABLE
from twolink.studies.mismatch.figures import (
    closed_loop_figure,
    heatmap_figure,
    robust_figure,
    robustness_figure,
)
from twolink.studies.mismatch.plan import CURVES, FAMILIES
from twolink.viz.formatting import format_rate


def summary(report: dict) -> dict:
    """What ``twolink mismatch --json`` prints."""
    return {"success_rate": {p: {pl: v["success_rate"] for pl, v in d.items()}
                             for p, d in report["closed_loop"].items()},
            "successes": {p: {pl: [v["successes"], v["states"]] for pl, v in d.items()}
                          for p, d in report["closed_loop"].items()},
            "open_loop": report["open_loop"]["summary"],
            "integration_error_full": report["open_loop"]["integration_error_full"],
            "gap_closure": report["gap_closure"],
            "margins": report["robustness"]["margins"],
            "robust": ({p: {lv: {m: [r["successes"], score_keys(r)["n"]]
                                 for m, r in d.items()}
                            for lv, d in by.items()}
                        for p, by in report["robust"]["results"].items()}
                       if "robust" in report else None),
            "throughput": report["throughput"], "plan": report["plan"],
            "seconds": report["seconds"], "stage_seconds": report["stage_seconds"]}


def _pct(v):
    return "-" if v is None else f"{100 * v:.1f} %"


def _num(v, fmt="{:.3g}", none="never"):
    return none if v is None else fmt.format(v)


def _table(header, rows) -> str:
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    lines += ["| " + " | ".join(str(c) for c in r) + " |" for r in rows]
    return "\n".join(lines)


def robustness_tables(rb: dict) -> str:
    """The margin tables: per family, then per parameter, then every joint size with its
    count, interval, worst plant and worst-case return (policies as ``rb`` orders them)."""
    fams = ("every_parameter_alone",) + FAMILIES[1:2] + ("joint_lower_bound",) + FAMILIES[2:]
    rows = []
    for p, m in rb["margins"].items():
        rows.append([p, _pct(rb["curves"][p]["nominal"])] +
                    [_num(m.get(f), "{:g}", none="none") for f in fams])
    per_family = _table(("policy", "nominal success", "each parameter alone", "joint",
                         "joint, Wilson lower bound", "noise [deg]", "delay [samples]",
                         "torque limit"), rows)
    rows = []
    for p, m in rb["margins"].items():
        rows.append([p] + [_num(m.get(f"parameter:{n}"), "{:g}", none="none")
                           for n in PERTURBABLE])
    per_parameter = _table(["policy"] + list(PERTURBABLE), rows)
    out = [per_family, "", "Margin per parameter (relative change):", "", per_parameter]
    worst, counted = rb.get("joint_worst_plant", {}), rb.get("counts", {})
    rows = []
    for p, w in worst.items():
        for size, v in w.items():
            kn = counted.get(p, {}).get("joint", {}).get(size)
            rows.append([p, f"+-{size:g}", format_rate(*kn) if kn else "-",
                         format_rate(v["successes"], v["states"]),
                         f"{v['mean_return']:.2f}", f"{v['worst_return']:.2f}"])
    if rows:
        out += ["", f"Joint perturbations, {rb.get('joint_draws', '?')} random plants per "
                    "size: success over every state of every plant, the worst plant (k of its "
                    "states), the mean return and the worst-case return (the lowest of any "
                    "run):", "",
                _table(("policy", "joint size", "success k/n [95 % Wilson]",
                        "worst plant [95 % Wilson]", "mean return", "worst-case return"),
                       rows)]
    return "\n".join(out)


def _challenge_row(name: str, ch: dict) -> list:
    return [name, f"+-{100 * ch['spread']:g} %", f"{100 * ch['torque_limit']:+g} %",
            ch["action_delay"], ch["observation_delay"], f"{ch['angle_noise_deg']:g}",
            f"{ch['speed_noise']:g}", f"{100 * ch['dropout']:g} %", f"{100 * ch['stuck']:g} %"]


def robust_tables(section: dict) -> str:
    """The robust section's tables: the levels and every policy x level x mode."""
    levels = _table(("level", "parameters (jointly)", "torque limits", "actuation delay",
                     "observation delay", "angle noise [deg]", "speed noise [rad/s]",
                     "dropped readings", "stuck readings"),
                    [_challenge_row(n, ch) for n, ch in section["levels"].items()])
    rows = []
    for p, by_level in section["results"].items():
        for level, by_mode in by_level.items():
            for mode, r in by_mode.items():
                r = score_keys(r)
                worst = min(r["plant_successes"])
                rows.append([p, level, mode, format_rate(r["successes"], r["n"]),
                             r["plants"], format_rate(worst, r["states"]),
                             f"{r['mean_return']:.2f}", f"{r['worst_return']:.2f}",
                             _num(r["median_settle"], "{:.2f}"),
                             _num(r["p90_settle"], "{:.2f}")])
    results = _table(("policy", "level", "run", "success k/n [95 % Wilson]", "plants",
                      "worst plant [95 % Wilson]", "mean return", "worst-case return",
                      "median settle [s]", "p90 settle [s]"), rows)
    return "\n".join(["Challenge levels (twolink.sim.challenges.LEVELS):", "", levels, "",
                      results])


def markdown(report: dict, figures: dict, command: str) -> str:
    """The report as Markdown; every number comes from ``report``."""
    ol, cl, rb = report["open_loop"], report["closed_loop"], report["robustness"]
    out = ["# Model mismatch and robustness", "",
           f"Produced by `{command}` in {report['seconds']:.0f} s "
           f"(twolink {report['provenance']['twolink_version']}, "
           f"MuJoCo {report['provenance']['mujoco_version']}, "
           f"{report['provenance']['cpu_count']} CPUs). The numbers below are recomputed "
           "from rollouts each time; report.json holds them all.", "",
           "## 1. Open-loop model error", "",
           f"One sample period (Ts = 0.05 s) from every bin centre of the centralized grid "
           f"under every action ({ol['transitions']} transitions), each prediction minus "
           "MuJoCo (angles in rad, speeds in rad/s).", ""]
    rows = []
    for name, comps in ol["summary"].items():
        for comp, v in comps.items():
            rows.append((name, comp, f"{v['max']:.3g}", f"{v['rms']:.3g}"))
    out += [_table(("prediction", "component", "max |error|", "RMS error"), rows), ""]
    ie = ol["integration_error_full"]
    out += [f"Integration accuracy of the numpy plants (RK4, {ie['substeps']} substeps, against "
            f"{ie['reference_substeps']} substeps) over the same transitions: max "
            f"{max(ie['max']):.2g}. MuJoCo runs the same RK4 step, so (6) agrees with it to "
            f"round-off (max {max(v['max'] for v in ol['summary']['full'].values()):.2g}), "
            "well inside integration accuracy; the simplified model (11) is off by up to "
            f"{max(v['max'] for v in ol['summary']['simplified'].values()):.3g} rad/s "
            "in one sample.", "", f"![one-step error heat maps]({figures['heatmaps']})", ""]
    out += ["## 2. Closed-loop gap", "",
            f"Each policy on each plant from the {report['evaluation_set']['closed_loop']} "
            "states of the evaluation set (paper x0 + 8x8 grid of angle pairs at rest), "
            "5 s horizon. Gap = RMS over time of the wrapped angle difference to the MuJoCo "
            "trajectory from the same x0, mean over states.", ""]
    rows = []
    for p, d in cl.items():
        for plant, v in d.items():
            st = v["settle_time"]
            gap = v.get("gap_to_mujoco", {}).get("angle_rms")
            rows.append((p, plant, format_rate(v["successes"], v["states"]),
                         _num(v["x0_settle_time"]),
                         _pct(st["settled"]), _num(st["median"], none="-"),
                         _num(st["p90"], none="-"), f"{v['mean_return']:.2f}",
                         "-" if gap is None else f"{gap:.3g}"))
    out += [_table(("policy", "plant", "success k/n [95 % Wilson]", "settle from x0 [s]", "settled",
                    "median settle [s]", "p90 settle [s]", "mean return",
                    "angle gap to MuJoCo [rad]"), rows), "",
            f"![closed loop]({figures['closed_loop']})", ""]
    out += ["## 3. Closing the gap: synthesis on the full model (6)", "",
            "`centralized_full` is the centralized policy synthesised on (6). "
            "`decentralized_full` keeps the paper's information structure: agent 2 sees only "
            "link 2 and assumes link 1 at rest (dtheta1 = 0, tau1 = 0) in its model (6); "
            "agent 1 uses (6) with link 2 held at rest over its transition (frozen context). "
            "The open-loop cost of agent 2's assumption is the `agent2_assumption` row above.",
            ""]
    rows = []
    for p, g in report["gap_closure"].items():
        rows.append((p, _pct(g["success_simplified_plant"]), _pct(g["success_mujoco"]),
                     g["full_model_policy"], _pct(g["success_mujoco_full_model_policy"]),
                     f"{100 * g['gain_on_mujoco']:+.1f} pp",
                     f"{_num(g['x0_settle_time_mujoco'])} -> "
                     f"{_num(g['x0_settle_time_mujoco_full_model_policy'])}"))
    out += [_table(("paper policy", "success, simplified plant", "success, MuJoCo",
                    "synthesised on (6)", "its success, MuJoCo", "gain on MuJoCo",
                    "settle from x0 on MuJoCo [s]"), rows), ""]
    out += ["## 4. Robustness", "",
            f"MuJoCo plant perturbed; success over {report['evaluation_set']['sweeps']} initial "
            f"states per plant; {rb['cells']} cells. Margin = the largest tested perturbation "
            f"such that every tested size up to it (both signs) keeps success >= "
            f"{100 * rb['threshold']:.0f} %; `none` = the policy falls short of that "
            "already on the nominal plant. Joint: the ten physical parameters of Table I at "
            "once (not the torque limits), each uniform in "
            f"[-size, size], {rb['joint_draws']} random plants per size; the column `joint, "
            "Wilson lower bound` applies the same rule to the lower end of each perturbed size's "
            "95 % Wilson interval (a size counts only when its success is known to be >= "
            f"{100 * rb['threshold']:.0f} %; the nominal plant is judged by its rate), so "
            "two neighbouring sizes count as different only when the data tell them apart. Noise: angle std in "
            "degrees, speed std scaled so that 5 deg <-> 0.1 rad/s.", ""]
    out += [robustness_tables(rb), "",
            f"![robustness, parameters]({figures['robustness_parameters']})", "",
            f"![robustness, other]({figures['robustness_other']})", ""]
    if "robust" in report:
        rs = report["robust"]
        out += ["## 5. Robust section: every policy under every challenge level", "",
                f"Each policy on MuJoCo under each challenge level, {rs['plants']} random "
                f"plants per level (one for a level that draws nothing) x {rs['states']} "
                f"initial states, plants and noise drawn from seed {rs['seed']} (fixed in the "
                "plan, used for nothing else, never tuned on); `plain` runs the policy as it "
                "is, `compensated` behind the run-time delay predictor and state observer "
                "(twolink.sim.estimation). Every row is one call of twolink.sim.evaluation.evaluate. "
                "Worst plant: the plant with the fewest successes (k of its states); "
                "worst-case return: the lowest discounted return of any run; settle times "
                f"over every row (`never` when fewer settle). The paper's policies, which fail "
                "on the nominal MuJoCo arm already (section 2), run only as they are. "
                f"Time: {rs['seconds']:.0f} s wall, {rs['cpu_seconds']:.0f} s of CPU "
                "(all threads of the run; the wall time includes waiting for a shared "
                "machine).", "",
                robust_tables(rs), "", f"![robust section]({figures['robust']})", ""]
    tp = report["throughput"]
    out += ["## Sweep throughput", "",
            f"{tp['rows']} rollouts x {tp['samples']} samples = {tp['mujoco_steps']} MuJoCo "
            f"steps, {tp['nthread']} threads: closed loop (batched policy + `mujoco.rollout` "
            f"per sample) {tp['closed_loop_steps_per_s']:.3g} steps/s, open-loop "
            f"`mujoco.rollout` of the same steps {tp['open_loop_steps_per_s']:.3g} steps/s: "
            f"ratio {tp['ratio_closed_to_open']:.2f}.", ""]
    return "\n".join(out)


def write(report: dict, data: dict, outdir: Path, command: str) -> dict:
    """Figures, report.json and report.md into ``outdir``, all of them or none: written
    into a staging folder and moved in together (:func:`twolink.artifacts.staged_set`);
    other files of ``outdir`` (the sweep.jsonl) are kept."""
    with staged_set(outdir) as stage:
        figures = {
            "heatmaps": heatmap_figure(data["error"], stage / "model_error.png"),
            "closed_loop": closed_loop_figure(report, data["settle"],
                                              stage / "closed_loop.png"),
            "robustness_parameters": robustness_figure(
                report, [k for k in CURVES if k.startswith("parameter:")],
                stage / "robustness_parameters.png",
                "success vs one Table I parameter changed"),
            "robustness_other": robustness_figure(
                report, [k for k in CURVES if not k.startswith("parameter:")],
                stage / "robustness_other.png",
                "success vs joint random parameters, state noise, actuation delay, "
                "torque limits"),
        }
        if "robust" in report:
            figures["robust"] = robust_figure(report["robust"], data["robust_settle"],
                                              stage / "robust.png")
        report = dict(report, figures=figures, command=command)
        write_json(stage / "report.json", report)
        write_text(stage / "report.md", markdown(report, figures, command) + "\n")
    return report
