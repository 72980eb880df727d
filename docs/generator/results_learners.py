"""docs/results/learners.md, from ``renders/learners/learners.json`` (``twolink
learners``, :mod:`twolink.studies.learners`): what of the plan has run, the table of
:func:`twolink.studies.learners.report.rows` against the reach study's ceiling, the
targets judged from the data, the learning curves; and :func:`learners_block`, the
learners' best rows on the scaling page.
"""
from __future__ import annotations

from .common import SCHEMAS, _load, _stamp
from .results_learners_cost import BENCH, LIGHT_LEVERS, cost_target, study_time  # noqa: F401
from .results_swing_returns import reward_note

#: The study's data and its figure (written by ``twolink learners`` beside the JSON).
DATA = "renders/learners/learners.json"
FIGURE = "../renders/learners/learners.png"
#: Targets: (what, arm, decentralized only, success share on the fresh poses).
TARGETS = (("N = 6 tapered, 8 s: a decentralized learner >= 90 % on fresh poses",
            (6, "tapered"), True, 0.90),
           ("copied N = 4, 8 s: a decentralized learner >= 90 % on fresh poses",
            (4, "copied"), True, 0.90))
#: Runs outside the plan that test one lever: each ``<id>.json`` is the run's curve
#: (``twolink train``'s ``curve.json``), ``<id>.fresh.json`` its final agent's ``twolink
#: evaluate AGENT --links N --poses 256 --seed 4180000 --json`` where it was scored, and
#: ``<id>.fresh16.json`` the same with ``--horizon 16`` (failed, or settled late?).
LEVERS = "renders/learners/levers"
#: The options of ``twolink train`` a lever run's config spells out (beside the arm), in
#: this order: every field of TrainConfig and MarlConfig but ``links`` and ``rule`` (a
#: test holds the list to the two dataclasses). Each appears where its value differs from
#: the field's default; those of :data:`ALWAYS` always.
LEVER_OPTIONS = ("algo", "observe", "plant", "challenge", "base", "gamma", "start", "init",
                 "history", "action_rate", "envs", "n_steps", "batch_size", "epochs", "net",
                 "reward", "action_gain", "std_floor", "value_norm", "bound_loss", "device",
                 "threads", "eval_every", "steps", "seed")
ALWAYS = ("algo", "observe", "steps", "seed")
#: ``docs/studies/agent_saturation.py``'s records of six-link agents (study and levers),
#: and the final speed (rad/s) beyond which a joint counts as turning on.
SATURATION = "renders/learners/saturation.json"
SPINNING = 1.0
#: How the committed study is continued.
CONTINUE = "twolink learners -o renders/learners/learners.json"


def _ceiling() -> dict:
    from twolink.studies.learners.report import ceilings

    from .results_scaling import REACH

    return ceilings(_load(REACH, SCHEMAS[REACH]))


def _targets(rows: list) -> list:
    from twolink.viz.formatting import format_rate

    out = []
    for what, arm, decentral, share in TARGETS:
        cands = [r for r in rows if (r["links"], r["rule"]) == arm
                 and (not decentral or r["algo"] != "ppo")]
        if not cands:
            out.append(f"- not yet run: {what}")
            continue
        best = max(cands, key=lambda r: r["table"]["successes"] / r["table"]["n"])
        f = best["fresh"]
        levers = _lever_scores(arm, decentral)
        top = max(levers, key=lambda sg: sg[2], default=None)
        met = max([f["successes"] / f["n"]]
                  + ([] if top is None else [top[1]["successes"] / top[1]["n"]])) >= share
        late = best.get("fresh_late")
        later = ("" if not late else f"; the same poses run for 16 s: "
                 f"{format_rate(late['successes'], late['n'])}")
        lever = ("" if top is None else f"; best of {len(levers)} lever run(s) (below) by "
                 f"its final curve point: `{top[0]}` "
                 f"{format_rate(top[1]['successes'], top[1]['n'])}" + _other_seeds(top, levers))
        out.append(f"- {'met' if met else '**missed**'}: {what} (each candidate picked on "
                   "the table's poses, judged on the fresh ones): best of the study "
                   f"{best['learner']} {format_rate(f['successes'], f['n'])} over "
                   f"{len(best['seeds'])} seed(s)" + later + lever
                   + ("" if met else _beyond_reach(arm, share)))
    out.append(cost_target(rows))
    return out


def scored_levers() -> list:
    """(run, its curve record, its final agent's fresh score at 8 s) of every lever run of
    :data:`LEVERS` with both files (a curve and a ``.fresh.json``)."""
    import json

    from . import common

    folder = common.ROOT / LEVERS
    out = []
    for path in sorted(folder.glob("*.fresh.json")) if folder.is_dir() else []:
        stem = path.name[:-len(".fresh.json")]
        curve = folder / f"{stem}.json"
        if curve.is_file():
            out.append((stem, json.loads(curve.read_text()), json.loads(path.read_text())))
    return out


def _lever_scores(arm: tuple, decentral: bool) -> list:
    """(run, fresh score at 8 s, final curve point's success rate) of every lever run of
    :func:`scored_levers` on ``arm`` (IPPO or MAPPO only when ``decentral``)."""
    out = []
    for stem, record, fresh in scored_levers():
        config, last = record["config"], record["curve"][-1]
        if (config["links"], config["rule"]) == arm and (
                not decentral or config["algo"] in ("ippo", "mappo")):
            out.append((stem, fresh, last["successes"] / last["n"]))
    return out


def _other_seeds(top: tuple, levers: list) -> str:
    """The fresh scores of the lever runs that differ from ``top`` only in their seed
    (``<name>_seed<S>``): is what met the target one seed or the recipe?"""
    from twolink.viz.formatting import format_rate

    stem = top[0].rsplit("_seed", 1)[0]
    others = [(s, g) for s, g, _ in levers if s != top[0] and s.rsplit("_seed", 1)[0] == stem]
    if not others:
        return " (its only seed)"
    return " (the same recipe's other seeds: " + ", ".join(
        f"`{s}` {format_rate(g['successes'], g['n'])}" for s, g in others) + ")"


def _beyond_reach(arm: tuple, share: float) -> str:
    """What the target asks of the poses beyond the own motors' reach on the scaling
    table's poses of ``arm``, and how many of them the learned agents of the own-motor
    study (``docs/studies/links_own_motor.py``) settle by 8 s; empty where that study has
    no such poses or no learned agent on the arm."""
    import math

    import numpy as np

    from .results_own_motor import OWN_MOTOR, OWN_MOTOR_EDGES

    data = _load(OWN_MOTOR, SCHEMAS[OWN_MOTOR]) or {"runs": []}
    run = next((r for r in data["runs"] if (r["links"], r["rule"]) == arm), None)
    if run is None or not run.get("learned"):
        return ""
    deadline = OWN_MOTOR_EDGES[-1]
    late = np.asarray(run["own_motor_s"]) > deadline
    if not late.any():
        return ""
    need = math.ceil(share * run["poses"]) - int((~late).sum())
    counts = {k: int(np.asarray(run["success"][k])[late].sum()) for k in run["learned"]}
    settled = ", ".join(f"`{k}` {v}" for k, v in counts.items())
    return (f". Cause, on the table's {run['poses']} poses: {int(late.sum())} are beyond "
            f"the own motors' reach (own-motor time over {deadline:g} s, "
            "[scaling page](scaling.md#what-a-joints-own-motor-can-do)), so "
            f"{share * 100:g} % asks for at least {need} of them even with every other pose "
            f"settled; the learned agents the own-motor study ran settle at most "
            f"{max(counts.values())} of them by 8 s ({settled})"
            + ("; `_slow_` in a name: trained only on such poses (`--start slow`)"
               if any("_slow_" in k for k in counts) else "") + _swing(run, late)
            + reward_note(arm))


def _swing(run: dict, late) -> str:
    """The learned agents' largest median swing of the inner joints on the poses beyond
    the own motors' reach, beside the time-optimal answers' (the scaling page's table)."""
    import numpy as np

    from .results_own_motor import _demo_swings

    swings = [float(np.median(np.asarray(run["excursion"][k])[late]))
              for k in run["learned"] if k in run.get("excursion", {})]
    optimal = _demo_swings(run["links"], run["rule"])
    if not swings or optimal is None:
        return ""
    far = float(np.median(optimal))
    return (f". On those poses their inner joints swing away from the goal by a median of "
            f"at most {max(swings):.2f} rad, where the time-optimal answers swing them "
            f"{far:.2f} rad ([scaling page](scaling.md#do-they-swing-the-inner-joints))"
            + (": none has found the manoeuvre that turns the outer joint in time"
               if max(swings) < far / 2 else ""))


def _transfer(rows: list) -> str:
    """The transfer gap per arm: PPO trained on the model (6) scored on the model and on
    MuJoCo, beside PPO trained on MuJoCo scored on both, on the same fresh poses."""
    from twolink.viz.formatting import format_rate

    def cell(r, key):
        m = r.get(key) if r else None
        return "—" if not m else format_rate(m["successes"], m["n"])

    out = ["PPO (centralized) trained on the rigid-body model (6) (`twolink train --plant "
           "model`) and on MuJoCo, each final agent scored on the same fresh poses on both "
           "plants; the paper's policies' gap between model and MuJoCo is on the "
           "[mismatch page](mismatch.md).", "",
           "| N | links | trained on | on the model (6) | on MuJoCo |", "|---|---|---|---|---|"]
    arms = sorted({(r["links"], r["rule"]) for r in rows if r["plant"] == "model"},
                  key=lambda a: (a[0], a[1] != "tapered"))
    for arm in arms:
        for plant in ("model", "mujoco"):
            r = next((r for r in rows if (r["links"], r["rule"]) == arm and r["algo"] == "ppo"
                      and r["base"] == "none" and r["plant"] == plant), None)
            if r is not None:
                out.append(f"| {arm[0]} | {arm[1]} | {'the model (6)' if plant == 'model' else 'MuJoCo'} "
                           f"({len(r['seeds'])} seed(s)) | {cell(r, 'fresh_model')} | "
                           f"{cell(r, 'fresh')} |")
    return "\n".join(out) if arms else "Not yet run: no learner trained on the model."


def _lever_command(config: dict) -> str:
    """The ``twolink train`` command line of a lever run's config: the arm, then every
    option of :data:`LEVER_OPTIONS` whose value is not the default of the run's config
    class (MarlConfig for IPPO/MAPPO, else TrainConfig)."""
    import dataclasses

    from twolink.training.config import TrainConfig
    from twolink.training.marl import MARL_ALGOS, MarlConfig

    cls = MarlConfig if config.get("algo") in MARL_ALGOS else TrainConfig
    defaults = {f.name: f.default for f in dataclasses.fields(cls)}
    words = ["twolink train", f"--links {config['links']}"]
    if config["links"] > 2:
        words.append(f"--rule {config['rule']}")
    for key in LEVER_OPTIONS:
        value = config.get(key)
        if value is None or (key not in ALWAYS and defaults.get(key, object()) == value):
            continue
        if value is True:                                 # a flag
            words.append(f"--{key.replace('_', '-')}")
            continue
        if isinstance(value, (list, tuple)):
            value = ",".join(map(str, value))
        words.append(f"--{key.replace('_', '-')} {value:g}" if isinstance(value, float)
                     else f"--{key.replace('_', '-')} {value}")
    return " ".join(words)


def levers_block() -> str:
    """The lever runs of :data:`LEVERS`: each run's command, its final curve point (64
    poses of the table) and its final agent on the fresh poses where scored; an agent
    scored without a training curve (made outside ``twolink train``) has its scores only."""
    import json

    from twolink.viz.formatting import format_rate

    from . import common

    folder = common.ROOT / LEVERS
    files = sorted(folder.glob("*.json")) if folder.is_dir() else []
    stems = sorted({p.name[:p.name.index(".fresh")] if ".fresh" in p.name else p.stem
                    for p in files})
    if not stems:
        return ""
    out = ["## Levers tried outside the plan\n\n",
           f"Each run's curve is `{LEVERS}/<run>.json`; its final agent on the 256 fresh poses "
           "(seed 4180000 + N), where scored, is `<run>.fresh.json` (`twolink evaluate AGENT "
           "--links N [--rule R] --poses 256 --seed 4180000 --json`), and `<run>.fresh16.json` the "
           "same poses run for 16 s (`--horizon 16`). A row without a command is an agent "
           "made outside `twolink train` ([the guide](../guides/learners-study.md"
           "#levers-tried-outside-the-plan) says how).\n\n",
           "| run | command | final curve point (64 table poses) | fresh poses at 8 s | "
           "fresh poses by 16 s | CPU per step |\n|---|---|---|---|---|---|\n"]
    for stem in stems:
        path = folder / f"{stem}.json"
        command = point = cpu = "—"
        if path.is_file():
            try:
                run = json.loads(path.read_text())
                last = run["curve"][-1]
                command = f"`{_lever_command(run['config'])}`"
                done = bool(run.get("done"))        # a run stopped early: its last point
                cpu_s, steps = ((run["cpu_s"], run["steps"]) if done
                                else (last["cpu_s"], last["steps"]))
                cpu = f"{1e6 * cpu_s / steps:.0f} µs"
            except (ValueError, KeyError, TypeError, ZeroDivisionError, IndexError) as exc:
                raise ValueError(f"{path}: not a twolink train curve ({exc})") from None
            point = (f"{format_rate(last['successes'], last['n'])} at "
                     f"{last['steps'] / 1e6:.2f} M steps"
                     + ("" if done else f" (stopped there; "
                        f"{run['steps_requested'] / 1e6:.2f} M asked)"))
        fresh = []
        for suffix in (".fresh.json", ".fresh16.json"):
            f_path = folder / f"{stem}{suffix}"
            f = json.loads(f_path.read_text()) if f_path.is_file() else None
            fresh.append("—" if f is None else format_rate(f["successes"], f["n"]))
        out.append(f"| `{stem}` | {command} | {point} | {' | '.join(fresh)} | {cpu} |\n")
    return "".join(out) + "\n"


def saturation_block() -> str:
    """The agents of :data:`SATURATION`: per agent its successes, the joint that turns
    fastest at the end (median |speed| over poses) and that joint's share of the last 2 s
    at its torque limit; and how many of the agents that settle nothing end with a joint
    turning faster than :data:`SPINNING` rad/s, against how many of those that settle
    some."""
    import json

    from . import common

    path = common.ROOT / SATURATION
    if not path.is_file():
        return ""
    try:
        data = json.loads(path.read_text())
        poses, tail = data["poses"], data["tail_s"]
        rows = [(r["file"].split("/")[-2] if "/" in r["file"] else r["file"],
                 r["successes"], r["n"], r["at_limit"], r["speed"], r["angle"])
                for r in data["records"]]
    except (ValueError, KeyError, TypeError) as exc:
        raise ValueError(f"{path}: not agent_saturation records ({exc})") from None

    def spins(speed):
        return max(speed) > SPINNING

    def far(row):
        return max(range(len(row[5])), key=lambda i: row[5][i])

    lost = [r for r in rows if r[1] == 0]
    some = [r for r in rows if r[1] > 0]
    out = ["## Runs that settle nothing\n\n",
           f"`python docs/studies/agent_saturation.py AGENT ... --poses {poses} --json "
           f"{SATURATION}`: each six-link agent on {poses} of the fresh poses for 8 s; the "
           f"joint that turns fastest at the end (median |speed| over the poses; the goal "
           f"band asks for 0.1 rad/s), and the share of the last {tail:g} s in which that "
           f"joint's torque lies within 1 % of its limit. "
           f"**{sum(spins(r[4]) for r in lost)} of the {len(lost)} agents that settle "
           f"nothing end with a joint turning faster than {SPINNING:g} rad/s; "
           f"{sum(spins(r[4]) for r in some)} of the {len(some)} that settle some do.** "
           + (f"Every one of the {len(lost)} leaves joint "
              f"{' or '.join(sorted({str(far(r) + 1) for r in lost}))} farthest from the goal, "
              f"at least {min(r[5][far(r)] for r in lost):.2f} rad away (median over the "
              f"poses); the agents that settle some leave every joint within "
              f"{max(r[5][far(r)] for r in some):.2f} rad. " if lost and some else "")
           + 
           "The `--bound-loss` and `--std-floor` lever runs above test two remedies (the "
           "[guide](../guides/learners-study.md#levers-tried-outside-the-plan) says what "
           "they found).\n\n",
           "| run | settled | fastest joint at the end | its share of the last "
           f"{tail:g} s at the torque limit | joint farthest from the goal at the end |\n"
           "|---|---|---|---|---|\n"]
    for run, k, n, at, speed, angle in sorted(rows, key=lambda r: (r[1], r[0])):
        j = max(range(len(speed)), key=lambda i: speed[i])
        far = max(range(len(angle)), key=lambda i: angle[i])
        out.append(f"| `{run}` | {k}/{n} | joint {j + 1}: {speed[j]:.2f} rad/s | "
                   f"{at[j]:.0%} | joint {far + 1}: {angle[far]:.2f} rad |\n")
    return "".join(out) + "\n"


def learners_page(data: dict) -> str:
    from twolink.studies.learners.plan import plan
    from twolink.studies.learners.report import rows, table

    ceiling = _ceiling()
    rs = rows(data, ceiling)
    done = len(data["runs"])
    planned = len(plan())
    seeds = sorted({r["run"]["seed"] for r in data["runs"]})
    return "".join([
        _stamp(DATA), "# Today's learners on N links\n\n",
        "Table II for deep RL: centralized PPO (Stable-Baselines3) and IPPO / MAPPO (skrl) "
        "with the `local` (own joint only) and `neighbours` (one hop) observation models, "
        "trained by `twolink train` with one hyperparameter set per algorithm on the "
        "MuJoCo arm (cos/sin angles, normalized actions, the shaped reward, random poses "
        "at rest), scored as their final agents (never one picked by its curve) on 256 "
        "poses of the scaling table (the reach study's poses) and on 256 fresh poses "
        f"(seed {data['fresh_seed']} + N, read by nothing else) at 8 s (two links: 5 s).\n\n",
        f"**{done} of the plan's {planned} runs** are in `{DATA}` (seeds "
        f"{', '.join(map(str, seeds)) or 'none'}). The study resumes: `{CONTINUE}` "
        "runs what is missing, a run at a time, rewriting the file after each (`--seeds "
        "0` is the one-seed version, `--list` shows each run's state).\n\n",
        "Columns: successes pooled over seeds with the Wilson 95 % interval; the "
        "interquartile mean of the seeds' rates with a 95 % percentile bootstrap interval "
        "(rliable's protocol); the ceiling is the reach study's reachable share of the "
        "table's poses (— where it was not run); steps to 90 % of it per seed, on the "
        "curve's 64 poses; CPU per environment step includes the updates and the "
        "curve's evaluations; peak memory is the training process's resident set; "
        "fresh poses by 16 s are the same poses run twice as long (a pose missed at 8 s "
        "but settled by 16 s was late, not lost; — where the run's agent was not kept "
        "to score it, `docs/studies/learners_late.py`).\n\n",
        table(rs) if rs else "No run has finished yet.", "\n\n",
        "## Targets\n\n", "\n".join(_targets(rs) + [study_time(data)]), "\n\n",
        "## Transfer: trained on the model, run on MuJoCo\n\n", _transfer(rs), "\n\n",
        levers_block(), saturation_block(),
        "## Learning curves\n\n", f"![learning curves]({FIGURE})\n\n",
        "Thin lines: one seed each, success of the deterministic policy on the curve's 64 "
        "poses of the scaling table; dashed: the ceiling.\n"])


def learners_block() -> str:
    """The scaling page's section on the learners: the best learned row per arm beside
    the ceiling (empty until the study has runs)."""
    from twolink.studies.learners.report import rows
    from twolink.viz.formatting import format_rate

    data = _load(DATA, SCHEMAS[DATA])
    if not data or not data["runs"]:
        return ""
    ceiling = _ceiling()
    rs = rows(data, ceiling)
    out = ["## Today's learners\n\n",
           "The best final agent per arm of `twolink learners` on the same poses "
           "(details, fresh poses and learning curves: [Learners](learners.md)), with what "
           "it cost to learn: environment steps until its curve first reached 90 % of the "
           "ceiling (of all poses where the ceiling was not run; \"never\" within the run), "
           "and the CPU time of its run (mean over seeds; updates and the curve's "
           "evaluations included).\n\n",
           "| N | links | best centralized (PPO) | best decentralized (IPPO / MAPPO) | "
           "ceiling |\n|---|---|---|---|---|\n"]
    for arm in sorted({(r["links"], r["rule"]) for r in rs},
                      key=lambda a: (a[0], a[1] != "tapered")):
        def best(central):
            c = [r for r in rs if (r["links"], r["rule"]) == arm
                 and (r["algo"] == "ppo") == central]
            if not c:
                return "—"
            b = max(c, key=lambda r: r["table"]["successes"] / r["table"]["n"])
            t = b["table"]
            steps = ", ".join("never" if v is None else f"after {v / 1e6:.2f} M steps"
                              for v in b["steps_to_90pct_ceiling"])
            return (f"{b['learner']}: {format_rate(t['successes'], t['n'])}; 90 % {steps}, "
                    f"{b['cpu_s'] / 60:.0f} min CPU")
        top = ceiling.get(arm)
        out.append(f"| {arm[0]} | {arm[1]} | {best(True)} | {best(False)} | "
                   f"{'—' if top is None else f'{100 * top:.0f} %'} |\n")
    return "".join(out) + "\n"
