"""The README's answer block, made from a run folder of the main job (``studies/readme_answer.py``
writes it into README.md).

The block between ``<!-- answer:start -->`` and ``<!-- answer:end -->`` in README.md is the
output of :func:`render` on the run folder's ``summary.json`` and ``confirmations.json``: the
command, the run's time and phases, how many designs FE confirmed and how many were credible,
and one table row per answer (best credible, best gel, best foam core, best buildable) with
both displacement readings, the sag, the hysteresis (and for a 3D search, the contact area)
and the errors against the targets; for a 2D search checked in 3D (``--model 3d`` with a 2D
``--surrogate``), a second table of the same answers as 3D fingertips (answers_3d.json). The
prose around the block (what the numbers mean) stays hand-written: re-read it when the block
changes.
"""

from __future__ import annotations

import json
from pathlib import Path

from sim.options import options_from_dict
from sim.protocols import shown_hysteresis

from ._check3d import not_credible
from ._config import credible_at, default_checkpoint, search_trials
from ._run_folder import (
    read_answers_3d,
    read_config,
    read_studies,
    read_summary,
    read_trials,
    screened_designs,
)

__all__ = ["END", "LABELS", "START", "command", "describe", "render", "replace_block"]

START, END = "<!-- answer:start -->", "<!-- answer:end -->"
LABELS = {
    "best": "best credible",
    "gel": "best gel",
    "foam": "best foam core",
    "buildable": "best buildable",
}


def _layer(material: dict | str) -> str:
    """A layer's material in words: a catalogue name, or a family member's parameters."""
    if isinstance(material, str):
        return material
    mu = 1000.0 * material["mu_MPa"][0]
    g = sum(material.get("prony_g", []))
    kind = "foam" if material.get("model") == "hyperfoam" else "gel"
    nu = f", ν {material['nu']:.2f}" if kind == "foam" else ""
    relax = f", relaxing {100 * g:.0f} %" if g > 0 else ", elastic"  # its terms: the design file
    return f"{kind} μ0 {mu:.3g} kPa, α {material['alpha'][0]:.3g}{nu}{relax}"


def describe(design: dict) -> str:
    """A design in one line: its layers outermost first, then its outline."""
    layers = design["layers"]
    words = []
    for layer in layers:
        text = _layer(layer["material"])
        if "thickness_mm" in layer and layer["thickness_mm"] is not None:
            text = f"{layer['thickness_mm']:.2f} mm {text}"
        words.append(text)
    g = design.get("geometry", {})
    outline = (
        f"; outline {g['half_width_mm']:.2f} × {g['height_mm']:.2f} mm, exponent "
        f"{g['exponent']:.2f}"
        if g
        else ""
    )
    if g.get("half_length_mm") is not None:  # a 3D pad: its length along the finger
        outline += (
            f"; pad half-length {g['half_length_mm']:.1f} mm, length exponent "
            f"{g['length_exponent']:.2f}"
        )
    return ("one layer: " if len(layers) == 1 else "") + " over ".join(words) + outline


def _percent(e: float) -> str:
    """A relative error as the README writes it: "−54 %" (a true minus sign), "+3 %"."""
    return f"{'−' if e < 0 else '+'}{abs(100 * e):.0f} %"


def _scored(folder: Path, rounds: int) -> str:
    """What the surrogate scored: every study's quasi-random screen and the Optuna trials."""
    studies = read_studies(folder)
    screen, total = screened_designs(read_config(folder), studies)
    trials, _ = read_trials(folder)
    n_trials = len(next(iter(trials.values()))) if trials else 0
    if not total:
        return f" The surrogate scored {n_trials} Optuna trials."
    per_round = total // max(rounds, 1)
    return (
        f" The surrogate screened {total:,} designs ({per_round:,} a round: "
        f"{screen:,} for each of {len(studies) // max(rounds, 1)} studies) and scored "
        f"{n_trials} Optuna trials.".replace(",", " ")
    )


def _none_credible(summary: dict) -> str:
    """The sentence of a run that found no credible design ("" when it found one)."""
    if summary["answers"].get("best") is not None:
        return ""
    return (
        " No credible design was found: none of the FE-confirmed designs ran, settled, stayed "
        "within the validity limits and recovered between taps."
    )


def command(folder: Path, config: dict, checked_in_3d: bool) -> str:
    """The ``fingertip run`` command of the run folder, from its configuration, with the options
    that differ from the defaults: ``--model 2d`` for a 2D search, ``--model 3d`` for a 2D search
    checked in 3D, ``--surrogate`` when the search started from another checkpoint than the
    default of that ``--model`` (``explore._config.default_checkpoint``), ``--credible-at`` when
    it is not the model's default (``explore._config.credible_at``), ``--trials`` likewise
    (``explore._config.search_trials``)."""
    searched = options_from_dict(config.get("sim_options") or {}).dimension
    flag = "3d" if checked_in_3d else ("2d" if searched == "2d" else None)
    words = ["fingertip run"] + ([f"--model {flag}"] if flag else [])
    surrogate = config.get("surrogate")
    if surrogate and Path(surrogate).resolve() != default_checkpoint(flag).resolve():
        words.append(f"--surrogate {surrogate}")
    given = config.get("credible_at") or "median"  # none recorded: the median (older folders)
    if given != credible_at(None, searched):
        words.append(f"--credible-at {given}")
    trials = config.get("trials")
    if trials is not None and trials != search_trials(None, searched):
        words.append(f"--trials {trials}")
    return " ".join([*words, f"--out {folder.as_posix()}"])


def render(folder: str | Path) -> str:
    """The README block for the run folder ``folder``."""
    folder = Path(folder)
    summary = read_summary(folder)
    config = read_config(folder) or {}
    options = options_from_dict(config.get("sim_options") or {})
    searched_3d = options.dimension == "3d"
    confirmations = json.loads((folder / "confirmations.json").read_text())
    credible = sum(1 for c in confirmations if c.get("trusted"))
    t = summary.get("timings") or {}
    three = read_answers_3d(folder)
    area_head, area_rule = (" contact area 1 N / 4 N (mm²) |", "---|") if searched_3d else ("", "")
    lines = [
        f"`{command(folder, config, bool(three))}`: {len(summary['rounds'])} rounds, "
        f"{summary['wall_time_s']:.0f} s (search {t.get('search_s', 0):.0f} s, FE "
        f"{t.get('fe_s', 0):.0f} s, retraining {t.get('retrain_s', 0):.0f} s); "
        f"{len(confirmations)} designs confirmed with full FE, {credible} of them trusted."
        + _scored(folder, len(summary["rounds"]))
        + _none_credible(summary),
        "",
        "| answer | design | 1 N / 4 N from touch (mm) | from the top (mm) | sag (mm) | "
        f"hysteresis (N mm) |{area_head} errors |",
        f"|---|---|---|---|---|---|{area_rule}---|",
    ]
    rows = _shared_rows(summary["answers"])
    for kind, label in LABELS.items():
        a = summary["answers"].get(kind)
        if a is None:
            empty = " |" * (5 + searched_3d)
            lines.append(f"| {label} | none credible confirmed by FE |{empty}")
            continue
        if kind not in rows:  # the same design as an answer above: in its row
            continue
        label = rows[kind]
        r = a["readings"]
        touch, top = r["from_first_touch"], r["from_undeformed_top"]
        errors = ", ".join(_percent(e) for e in a["errors_vs_targets"].values())
        # 0 below what the FE's tolerances resolve: never a negative loop area
        hysteresis = shown_hysteresis(a["fe_metrics"], a["design"], options)
        fe = a["fe_metrics"]
        area = (
            f" {fe['contact_area_at_1N_mm2']:.0f} / {fe['contact_area_at_4N_mm2']:.0f} |"
            if searched_3d
            else ""
        )
        lines.append(
            f"| {label} | {describe(a['design'])} | {touch['disp_at_1N_mm']:.2f} / "
            f"{touch['disp_at_4N_mm']:.2f} | {top['disp_at_1N_mm']:.2f} / "
            f"{top['disp_at_4N_mm']:.2f} | {r['sag_mm']:.2f} | "
            f"{hysteresis:.3g} |{area} {errors} |"
        )
    if three:
        lines += _rows_3d(three)
    return "\n".join(lines) + "\n"


def _shared_rows(answers: dict) -> dict[str, str]:
    """The row label of each answer that opens a row: answers that are one design (the same
    FE record) share the first one's row, "best credible = best gel"."""
    first: dict[str, str] = {}
    labels: dict[str, list[str]] = {}
    for kind, label in LABELS.items():
        a = answers.get(kind)
        if a:
            opener = first.setdefault(a["fe_record"], kind)
            labels.setdefault(opener, []).append(label)
    return {kind: " = ".join(names) for kind, names in labels.items()}


def _rows_3d(three: dict) -> list[str]:
    """The answers as 3D fingertips (answers_3d.json, ``explore._check3d``): one row each."""
    answers = three.get("answers") or {}
    unique = {a["fe_record"] for a in answers.values() if a}
    lines = [
        "",
        "The same answers as 3D fingertips (the pad's default length and profile, every "
        f"protocol run to its end; {len(unique)} designs, "
        f"{three.get('fe_wall_time_s', 0):.0f} s of one core in all):",
        "",
        "| answer | 1 N / 4 N from touch (mm) | hysteresis (N mm) | errors | change from 2D at "
        "1 N | contact area 1 N / 4 N (mm²) | credible in 3D |",
        "|---|---|---|---|---|---|---|",
    ]
    rows = _shared_rows(answers)
    for kind in LABELS:
        a = answers.get(kind)
        if not a or kind not in rows:
            continue
        label = rows[kind]
        fe = a.get("fe_metrics") or {}
        if a.get("status") != "ok" or fe.get("disp_at_1N_from_touch_mm") is None:
            lines.append(f"| {label} | no tapping result: {a.get('reason') or '?'} | | | | | |")
            continue
        errors = ", ".join(_percent(e) for e in a["errors_vs_targets"].values())
        reasons = not_credible(a)
        why = "no: " + "; ".join(reasons) if reasons else "yes"
        lines.append(
            f"| {label} | {fe['disp_at_1N_from_touch_mm']:.2f} / "
            f"{fe['disp_at_4N_from_touch_mm']:.2f} | {fe['hysteresis_Nmm']:.3g} | {errors} | "
            f"{_percent(a['change_from_2d']['disp_at_1N_mm'])} | "
            f"{fe['contact_area_at_1N_mm2']:.0f} / {fe['contact_area_at_4N_mm2']:.0f} | {why} |"
        )
    return lines


def replace_block(text: str, block: str) -> str:
    """``text`` with the part between the markers replaced by ``block``."""
    head, rest = text.split(START, 1)
    _, tail = rest.split(END, 1)
    return f"{head}{START}\n{block}{END}{tail}"
