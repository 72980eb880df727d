"""The fading-gain section of docs/results/fuzzy-designs.md, from
``renders/fuzzy_design/fading_gain.json`` (``docs/studies/fading_gain.py``)."""
from __future__ import annotations

from .common import SCHEMAS, _load, _table

FADING = "renders/fuzzy_design/fading_gain.json"


def _cells(c: dict) -> tuple:
    ratio = "never" if c["ratio_median"] is None else f"{c['ratio_median']:.2f}"
    return (f"{c['none']}/{c['n_none']}", ratio, f"{c['medium']}/{c['n_challenge']}",
            f"{c['hard compensated']}/{c['n_challenge']}")


def _fade(f: dict) -> str:
    return (f"floor {f['floor']:g} over {f['fade_samples']} samples, out beyond "
            f"{f['exit_deg']:g} deg or {f['exit_speed']:g} rad/s")


def fading_gain_block() -> str:
    """Per tried policy: its base cells and its best fade by ``medium`` plain, and the
    study's verdict (empty when the study's data are not committed)."""
    data = _load(FADING, SCHEMAS[FADING])
    if data is None:
        return ""
    out = ["\n## The fading gain\n\n`python docs/studies/fading_gain.py`: each design behind "
           f"a gain that fades once a joint has settled (a hold region with hysteresis, "
           f"`twolink.control.fading.FadingGain`), {len(data['runs'][0]['fades'])} fades "
           "each, measured on the tuning seeds as the tuning table is (48 poses nominal, "
           "settle / T\\* over the tuning grid, 32 poses x 8 plants under `medium` plain and "
           "`hard` compensated). The best fade of each design is the one with the most "
           "`medium` plain successes.\n\n"]
    rows, notes = [], []
    for run in data["runs"]:
        v = run["verdict"]
        rows.append((f"`{run['policy']}`", "none (the design)", *_cells(run["base"])))
        rows.append(("", _fade(v["best_fade"]), *_cells(v["best_cells"])))
        notes.append(f"`{run['policy']}`: the best fade "
                     + ("beats" if v["best_beats_base_on_medium"] else "does not beat")
                     + " the design under `medium` plain; "
                     + (f"{len(v['fades_meeting_targets'])} fades meet"
                        if v["fades_meeting_targets"] else "no fade meets")
                     + f" every target of a recommended {run['kind']} design.")
    out.append(_table(("design", "fade", "nominal", "settle / T*", "medium plain",
                       "hard compensated"), rows))
    out.append("\n\n" + "\n".join(f"- {n}" for n in notes) + "\n")
    return "".join(out)
