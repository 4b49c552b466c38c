"""The one-page Markdown report of a search run (``report.md`` next to ``figures/``).

Reads the run folder (``explore._run_folder`` describes it) through ``explore._plots.load_run``,
writes every figure with ``write_figures`` and links them relatively, so the folder can be
moved or browsed on GitHub as it is.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from sim.options import SimOptions
from sim.protocols import shown_hysteresis
from sim.provenance import write_if_changed
from sim.targets import Targets

from ._objective import TAPPING, WEDGE_REFERENCE_N, WEDGE_WEIGHT
from ._plots import FIGURES, RunData, load_run, run_options, run_targets, write_figures
from ._run_folder import screened_designs

__all__ = ["write_report"]

_TARGET_WORDS = {
    "disp_at_1N_mm": ("displacement at 1 N", "mm"),
    "disp_at_4N_mm": ("displacement at 4 N", "mm"),
    "hysteresis_Nmm": ("energy lost per tap (loop area)", "N mm"),
}
_ANSWERS = {
    "best": "Best credible design (closest to the targets, confirmed by FE)",
    "gel": "Best gel-only design (every layer a silicone gel, confirmed by FE)",
    "foam": "Best foam-core design (a soft foam core, confirmed by FE)",
    "buildable": "Best buildable design (catalogue materials only, confirmed by FE)",
}
_ROUND_ORDER = ("round", "n_confirmed", "max_rel_error", "median_rel_error", "agreed")
_UNIT_SUFFIXES = (("_MPa", "MPa"), ("_mm", "mm"), ("_s", "s"), ("_N", "N"))


def _fmt(x: Any, spec: str = ".3g") -> str:
    """A number for a table cell ("–" when missing or not finite)."""
    if isinstance(x, bool):
        return "yes" if x else "no"
    if isinstance(x, int | float) and math.isfinite(x):
        return format(x, spec)
    return "–"


def _pct(x: Any) -> str:
    """A fraction as a signed percentage ("–" when missing)."""
    return _fmt(100 * x, "+.1f") + " %" if isinstance(x, int | float) and math.isfinite(x) else "–"


# ---------------------------------------------------------------------------------------------
# Designs in words
# ---------------------------------------------------------------------------------------------


def _quantity(key: str, value: Any) -> str:
    """``mu_MPa``, [0.01] -> "mu 0.01 MPa" (lists of one value shown as the value)."""
    if isinstance(value, list | tuple):
        value = value[0] if len(value) == 1 else "[" + ", ".join(_fmt(v) for v in value) + "]"
    text = _fmt(value) if isinstance(value, int | float) else str(value)
    for suffix, unit in _UNIT_SUFFIXES:
        if key.endswith(suffix):
            return f"{key[: -len(suffix)]} {text} {unit}"
    return f"{key} {text}"


def _material_words(material: Any) -> str:
    """A catalogue name, or an inline table (``Material.to_dict()``) in words."""
    if isinstance(material, str):
        return f"`{material}` (catalogue)"
    if not isinstance(material, Mapping):
        return "unknown material"
    skip = {"model", "name", "source", "moduli", "prony_g", "prony_tau_s", "prony_k", "provenance"}
    law = ", ".join(_quantity(k, v) for k, v in material.items() if k not in skip)
    text = f"{material.get('name') or 'a custom'} {material.get('model', 'material')} ({law})"
    g, tau = material.get("prony_g") or [], material.get("prony_tau_s") or []
    if g and tau:
        text += (
            f", relaxing by {100 * sum(g):.0f} % with time constants "
            f"{min(tau):.3g} to {max(tau):.3g} s"
        )
    else:
        text += ", no relaxation"
    return text


def _layer_words(layers: Sequence[Mapping[str, Any]]) -> list[str]:
    out = []
    for k, layer in enumerate(layers):
        last = k == len(layers) - 1
        size = "fills the rest (core)" if last else f"{_fmt(layer.get('thickness_mm'))} mm thick"
        out.append(f"  {k + 1}. {size}: {_material_words(layer.get('material'))}")
    return out


def _design_words(answer: Mapping[str, Any]) -> list[str]:
    """The design's outline and layers (outermost first), or its design-space point."""
    design = answer.get("design")
    if isinstance(design, Mapping):
        geo = design.get("geometry", {})
        layers = design.get("layers", [])
        return [
            f"- **Outline**: superellipse, half-width {_fmt(geo.get('half_width_mm'))} mm, "
            f"height {_fmt(geo.get('height_mm'))} mm, exponent {_fmt(geo.get('exponent'))}.",
            f"- **Layers** ({len(layers)}, outermost first):",
            *_layer_words(layers),
        ]
    point = answer.get("point") or {}
    items = [
        f"{k} = {_fmt(v) if isinstance(v, int | float) else v}"
        for k, v in point.items()
        if v not in (None, "") and not (isinstance(v, float) and math.isnan(v))
    ]
    return ["- **Design-space point**: " + ("; ".join(items) or "not recorded") + "."]


# ---------------------------------------------------------------------------------------------
# Sections
# ---------------------------------------------------------------------------------------------


def _grouped(n: int) -> str:
    """``n`` with its thousands apart, as the README writes them: 65 536."""
    return f"{n:,}".replace(",", " ")


def _intro(run: RunData) -> list[str]:
    rounds = {int(r) for r in run.column("round") if math.isfinite(r)}
    n_ok = sum(c.status == "ok" for c in run.confirmations)
    screen, total = screened_designs(run.config, run.studies)
    screened = (
        f"screened {_grouped(total)} quasi-random designs "
        f"({_grouped(screen)} for each of "
        f"its {len(run.studies)} studies) and "
        if total
        else ""
    )
    best = " (the screens' best among them)" if screened else ""
    return [
        f"# Fingertip skin search: `{run.run_dir.name}`",
        "",
        f"With the neural surrogate, the search {screened}scored {run.n_trials} Optuna trials"
        f"{best} over {len(rounds)} "
        f"round(s), then re-ran {len(run.confirmations)} of them with the full "
        f"finite-element (FE) solver ({n_ok} succeeded). Only FE-confirmed designs count as "
        "answers: the surrogate proposes, the FE model decides. A design's score is the rms "
        f"relative error to the three tapping targets plus {WEDGE_WEIGHT:g} x its wedge effort "
        "(0 is perfect, lower is better).",
        "",
    ]


def _targets_section(targets: Targets | None, tolerance: Any) -> list[str]:
    lines = ["## Targets", ""]
    if targets is None:
        return [*lines, "No targets were recorded for this run.", ""]
    lines += ["| target | value | meaning |", "|---|---|---|"]
    for name in TAPPING:
        words, unit = _TARGET_WORDS[name]
        lines.append(f"| `{name}` | {_fmt(targets.values[name])} {unit} | {words} |")
    lines.append(
        "| `wedge_peak_force_N` | as low as possible | force to press a wedge into the skin "
        f"(wedge effort = force / {WEDGE_REFERENCE_N} N, the paper's silicone) |"
    )
    reading = {"from_first_touch": "from the first touch of each tap"}.get(
        targets.reading, "from the undeformed top of the fingertip"
    )
    tol = f"±{100 * tolerance:.0f} %" if isinstance(tolerance, int | float) else "not recorded"
    lines += ["", f"Displacements are read {reading}. Tolerance on each target: {tol}."]
    if targets.max_sag_mm is not None:
        lines.append(
            f"A credible answer also recovers between taps: its sag (the displacement left at "
            f"the start of a tap by the earlier ones) is at most {_fmt(targets.max_sag_mm)} mm."
        )
    return [*lines, ""]


def _readings_rows(answer: Mapping[str, Any]) -> list[str]:
    """Both readings of the tapping displacements, and the sag between them."""
    r = answer.get("readings")
    if not r:
        return []
    top, touch = r.get("from_undeformed_top", {}), r.get("from_first_touch", {})
    d = answer.get("diagnostics") or {}
    return [
        "| reading | at 1 N (mm) | at 4 N (mm) |",
        "|---|---|---|",
        f"| from first touch | {_fmt(touch.get('disp_at_1N_mm'))} | "
        f"{_fmt(touch.get('disp_at_4N_mm'))} |",
        f"| from the undeformed top | {_fmt(top.get('disp_at_1N_mm'))} | "
        f"{_fmt(top.get('disp_at_4N_mm'))} |",
        "",
        f"- **Sag** (left by earlier taps): {_fmt(r.get('sag_mm'))} mm; settled: "
        f"{_fmt(d.get('settled'))}; within the validity limits: {_fmt(d.get('valid'))} "
        f"(largest compressive log strain in tapping "
        f"{_fmt(d.get('tapping_max_compressive_log_strain'))}, smallest J "
        f"{_fmt(d.get('tapping_min_J'))}).",
        "",
    ]


def _answer_rows(
    answer: Mapping[str, Any], targets: Targets, tolerance: Any, options: SimOptions
) -> list[str]:
    fe = answer.get("fe_metrics") or {}
    errors = answer.get("errors_vs_targets") or {}
    within = answer.get("within_tolerance") or {}
    predicted = answer.get("predicted") or {}
    rows = [
        "| metric | target | FE | error vs target | within tolerance | surrogate (90 % interval) |",
        "|---|---|---|---|---|---|",
    ]
    for name in (*TAPPING, "wedge_peak_force_N"):
        metric = targets.metric(name) if name in TAPPING else name
        value = fe.get(metric)
        if metric == "hysteresis_Nmm":  # 0 below what the solver's tolerances resolve
            value = shown_hysteresis(fe, answer.get("design"), options)
        target = targets.values.get(name)
        err = errors.get(name)
        if err is None and target and isinstance(value, int | float):
            err = (value - target) / target
        ok = within.get(name)
        if ok is None and isinstance(err, int | float) and isinstance(tolerance, int | float):
            ok = abs(err) <= tolerance
        mark = "–" if ok is None or name not in TAPPING else ("✓" if ok else "✗")
        p = predicted.get(metric) or {}
        point = _fmt(p.get("median", p.get("mean")))
        pred = f"{point} ({_fmt(p.get('lower_90'))} to {_fmt(p.get('upper_90'))})"
        target_text = _fmt(target) if name in TAPPING else "lower is better"
        err_text = _pct(err) if name in TAPPING else "–"
        rows.append(
            f"| `{metric}` | {target_text} | {_fmt(value)} | {err_text} | {mark} | {pred} |"
        )
    return rows


def _answer_section(
    kind: str,
    answer: Mapping[str, Any] | None,
    targets: Targets | None,
    tolerance: Any,
    options: SimOptions,
) -> list[str]:
    lines = [f"### {_ANSWERS[kind]}", ""]
    if not answer:
        return [*lines, f"No credible {kind} design was confirmed by FE in this run.", ""]
    lines += _design_words(answer)
    lines += [f"- **FE score**: {_fmt(answer.get('fe_score'))} (0 = every target met).", ""]
    if answer.get("credible") is False:
        lines += ["**Not credible** (let in by `--allow-untrusted`): see its diagnostics.", ""]
    if targets is not None:
        lines += [*_answer_rows(answer, targets, tolerance, options), ""]
    lines += _readings_rows(answer)
    return lines


def _answers_section(run: RunData, targets: Targets | None) -> list[str]:
    answers = run.summary.get("answers") or {}
    tolerance = run.summary.get("tolerance")
    lines = ["## Answers", ""]
    if not run.summary:
        return [*lines, "No summary.json: the run did not finish its confirmations.", ""]
    options = run_options(run)
    for kind in _ANSWERS:
        lines += _answer_section(kind, answers.get(kind), targets, tolerance, options)
    return lines


#: a round's ``best_fe_score`` when it confirmed no credible design (summary.json: null)
_NO_CREDIBLE = "no credible design"


def _cell(key: str, value: Any) -> str:
    if value is None:
        return _NO_CREDIBLE if key == "best_fe_score" else "–"
    if "rel_error" in key and isinstance(value, int | float) and not isinstance(value, bool):
        return _fmt(100 * value, ".1f") + " %" if math.isfinite(value) else "–"
    return _fmt(value) if isinstance(value, int | float) else str(value)


def _rounds_section(run: RunData) -> list[str]:
    rounds = [r for r in run.summary.get("rounds") or [] if isinstance(r, Mapping)]
    lines = ["## Surrogate vs FE, per round", ""]
    if not rounds:
        return [*lines, "No rounds recorded.", ""]
    keys = [k for k in _ROUND_ORDER if any(k in r for r in rounds)]
    keys += sorted({k for r in rounds for k in r} - set(keys))
    lines += ["| " + " | ".join(keys) + " |", "|" + "---|" * len(keys)]
    lines += ["| " + " | ".join(_cell(k, r.get(k, "–")) for k in keys) + " |" for r in rounds]
    lines += [
        "",
        "Relative error = (surrogate prediction (median) − FE) / |FE| over the scored "
        "metrics; a round agrees "
        "when the surrogate is close enough to FE to trust its ranking.",
    ]
    empty = [str(r.get("round", "?")) for r in rounds if r.get("best_fe_score", 0) is None]
    if empty:
        lines.append(
            f"No credible design was found in round(s) {', '.join(empty)}: none of the designs "
            "FE confirmed there ran, settled, stayed within the validity limits and recovered "
            "between taps (see the notes and confirmations.json, `diagnostics`)."
        )
    return [*lines, ""]


def _trust_lines(run: RunData) -> list[str]:
    lines = []
    trusted = run.column("trusted")
    known = trusted[np.isfinite(trusted)]
    if len(known):
        lines.append(
            f"- {int(known.sum())} of {len(known)} trials were trusted by the guard (inside the "
            "surrogate's training domain and low ensemble disagreement)."
        )
    for c in run.confirmations:
        if c.candidate.flags:
            where = f"round {c.candidate.round}, trial {c.candidate.trial} ({c.candidate.reason})"
            lines.append(f"- {where}: " + "; ".join(c.candidate.flags) + ".")
    return lines


def _notes_section(run: RunData) -> list[str]:
    lines = ["## Trust guard and notes", ""]
    body = _trust_lines(run) + [f"- {n}" for n in run.summary.get("notes") or []]
    return [*lines, *(body or ["Nothing to report."]), ""]


def _figures_section(paths: Mapping[str, Path]) -> list[str]:
    lines = ["## Figures", ""]
    for name in paths:
        caption = FIGURES.get(name, name)
        lines += [f"**{name}**: {caption}", "", f"![{name}](figures/{name}.png)", ""]
    return lines


def _study_section(run_dir: Path, storage: object) -> list[str]:
    """Where the studies are and the command that opens them (the configured storage; a run
    folder without one in its config.json: its own journal)."""
    from ._storage import JOURNAL_NAME, dashboard_command

    spec = storage if isinstance(storage, str) else (run_dir / JOURNAL_NAME).as_posix()
    return [
        "## Explore the study",
        "",
        f"Every trial of every round is in the Optuna studies (`{spec}`). Open them with "
        f"`{dashboard_command(spec)}`; the raw data are in "
        "`trials.csv`, `confirmations.json` and `fe/records/`.",
        "",
    ]


_SCORED = ("disp_at_1N_mm", "disp_at_4N_mm", "hysteresis_Nmm", "wedge_peak_force_N")


def _confirmations_section(run: RunData) -> list[str]:
    """Surrogate vs FE per confirmed design and scored metric."""
    lines = ["## Confirmed designs: surrogate vs FE", ""]
    if not run.confirmations:
        return [*lines, "No design was confirmed by FE yet.", ""]
    head = ["round", "trial", "chosen as", "FE status", "FE score"]
    lines += [
        "| " + " | ".join(head + [f"`{m}` error" for m in _SCORED]) + " |",
        "|" + "---|" * (len(head) + len(_SCORED)),
    ]
    for c in run.confirmations:
        cells = [
            str(c.candidate.round),
            str(c.candidate.trial),
            f"{c.candidate.reason} ({c.candidate.search})",
            c.status,
            _fmt(c.fe_score),
        ]
        for m in _SCORED:
            err, inside = c.rel_error.get(m), c.inside_90.get(m)
            mark = "" if inside is None else (" ✓" if inside else " ✗")
            cells.append("–" if err is None else f"{100 * err:+.1f} %{mark}")
        lines.append("| " + " | ".join(cells) + " |")
    lines += [
        "",
        "Error = (surrogate prediction − FE) / |FE|; ✓ / ✗: the FE value lies inside / outside "
        "the surrogate's 90 % interval.",
        "",
    ]
    return lines


def _workers(value: Any) -> int:
    """The run's FE worker count, also used to draw its figures (1 if absent or odd)."""
    return value if isinstance(value, int) and value > 0 else 1


def write_report(run_dir: str | Path) -> Path:
    """Write ``run_dir/report.md`` (and ``run_dir/figures/*.png``); returns the report's path.

    Works on any run folder, also an unfinished or empty one (sections then say what is
    missing)."""
    run_dir = Path(run_dir)
    run = load_run(run_dir)
    targets = run_targets(run)
    paths = write_figures(run_dir, workers=_workers(run.config.get("workers")))
    lines = [
        *_intro(run),
        *_targets_section(targets, run.summary.get("tolerance")),
        *_answers_section(run, targets),
        *_rounds_section(run),
        *_confirmations_section(run),
        *_notes_section(run),
        *_study_section(run_dir, run.config.get("storage")),
        *_figures_section(paths),
    ]
    path = run_dir / "report.md"
    text = "\n".join(lines).rstrip() + "\n"
    write_if_changed(path, text)  # the same: left alone
    return path
