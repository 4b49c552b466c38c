"""The one-page Markdown report of a search run (``report.md`` next to ``figures/``).

Reads the run folder (``explore._run_folder`` describes it) through ``explore._plots.load_run``,
writes every figure with ``write_figures`` and links them relatively, so the folder can be
moved or browsed on GitHub as it is.

It leads with the verdict (:func:`_verdict`): one paragraph naming the closest credible design,
its error on each target, what limits it (the validity limit or the sag limit it is at, and how
many confirmed designs went beyond them) and the best buildable design. Materials are named as
the search drew them: a catalogue name, or a family of the design space (``gel``, ``foam``)
with its parameters. Displacements are shown in the one reading the targets use.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from sim.design import Targets
from sim.options import SimOptions
from sim.protocols import ValidityOptions, shown_hysteresis
from sim.protocols.validity import binding_strain_limit, strain_limits, strain_summary
from sim.provenance import nan_if_none, write_if_changed

from ._check3d import not_credible
from ._objective import TAPPING, WEDGE_REFERENCE_3D_N, WEDGE_REFERENCE_N, WEDGE_WEIGHT
from ._plots import FIGURES, RunData, load_run, run_options, run_targets, write_figures
from ._run_folder import ANSWERS, read_answers_3d, screened_designs
from ._summary import ANSWER_WORDS, READING_WORDS, LayerMaterial, layer_materials
from ._types import Confirmation

__all__ = ["write_report"]

_TARGET_WORDS = {
    "disp_at_1N_mm": ("displacement at 1 N", "mm"),
    "disp_at_4N_mm": ("displacement at 4 N", "mm"),
    "hysteresis_Nmm": ("energy lost per tap (loop area)", "N mm"),
}
_ANSWERS = ANSWER_WORDS
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


def _law_words(material: Mapping[str, Any]) -> str:
    """An inline material table (``Material.to_dict()``) in words: its law, parameters and
    relaxation."""
    skip = {"model", "name", "source", "moduli", "prony_g", "prony_tau_s", "prony_k", "provenance"}
    law = ", ".join(_quantity(k, v) for k, v in material.items() if k not in skip)
    text = f"{material.get('model', 'material')} ({law})"
    g, tau = material.get("prony_g") or [], material.get("prony_tau_s") or []
    if g and tau:
        text += (
            f", relaxing by {100 * sum(g):.0f} % with time constants "
            f"{min(tau):.3g} to {max(tau):.3g} s"
        )
    else:
        text += ", no relaxation"
    return text


def _family_words(origin: LayerMaterial) -> str:
    """``the `gel` family (mu0_MPa 0.0105, alpha 3.8, ...)``, or `` `name` (catalogue)``."""
    if origin.family is None:
        return f"`{origin.name}` (catalogue)" if origin.name else "an inline material"
    values = ", ".join(f"{k} {_fmt(v)}" for k, v in origin.parameters)
    return f"the `{origin.family}` family" + (f" ({values})" if values else "")


def _material_words(material: Any, origin: LayerMaterial | None = None) -> str:
    """A layer's material: its catalogue name, or the family the search drew it from with the
    family's parameters, then the law the solver takes (an inline table)."""
    if isinstance(material, str):
        return f"`{material}` (catalogue)"
    if not isinstance(material, Mapping):
        return "unknown material"
    if origin is not None and origin.family is not None:
        what = f": {origin.description}" if origin.description else ""
        return f"{_family_words(origin)}{what}; as simulated, {_law_words(material)}"
    name = material.get("name") or (origin.name if origin is not None else None)
    head = f"`{name}` (user catalogue)" if name else "an inline material"
    return f"{head}: {_law_words(material)}"


def _layer_words(
    layers: Sequence[Mapping[str, Any]], origins: Sequence[LayerMaterial] = ()
) -> list[str]:
    out = []
    for k, layer in enumerate(layers):
        last = k == len(layers) - 1
        size = "fills the rest (core)" if last else f"{_fmt(layer.get('thickness_mm'))} mm thick"
        origin = origins[k] if k < len(origins) else None
        out.append(f"  {k + 1}. {size}: {_material_words(layer.get('material'), origin)}")
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
            *_layer_words(layers, layer_materials(answer)),
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


# ---------------------------------------------------------------------------------------------
# The verdict: the first paragraph
# ---------------------------------------------------------------------------------------------

#: a design this close to a limit (its value over the limit, or the limit over it for J) is
#: held at it: the limit binds
_AT_LIMIT = 0.95
#: a sag this close to the targets' limit binds
_SAG_AT_LIMIT = 0.8
#: the protocols whose validity diagnostics an FE result records
_PROTOCOLS = ("tapping", "plate", "wedge")


def _stack_words(answer: Mapping[str, Any]) -> str:
    """The layers in one phrase: "a 0.393 mm skin of `x` (catalogue) over a core of the `gel`
    family (mu0_MPa 0.0105, ...)"."""
    layers = (answer.get("design") or {}).get("layers") or []
    origins = layer_materials(answer)
    parts = []
    for k, (layer, origin) in enumerate(zip(layers, origins, strict=False)):
        what = _family_words(origin)
        if k == len(layers) - 1:
            parts.append(f"a one-layer body of {what}" if k == 0 else f"a core of {what}")
        else:
            role = "skin" if k == 0 else "middle layer"
            parts.append(f"a {_fmt(layer.get('thickness_mm'))} mm {role} of {what}")
    if len(parts) > 1:
        return ", ".join(parts[:-1]) + " over " + parts[-1]
    return parts[0] if parts else "a design"


def _outline_words(answer: Mapping[str, Any]) -> str:
    geo = (answer.get("design") or {}).get("geometry") or {}
    return (
        f"on a {_fmt(geo.get('half_width_mm'))} mm half-width, {_fmt(geo.get('height_mm'))} mm "
        f"high outline (exponent {_fmt(geo.get('exponent'))})"
    )


def _error_words(answer: Mapping[str, Any], targets: Targets) -> str:
    """Each target's error, with the FE value against the target."""
    fe = answer.get("fe_metrics") or {}
    errors = answer.get("errors_vs_targets") or {}
    parts = []
    for name in TAPPING:
        words, unit = _TARGET_WORDS[name]
        value, target = fe.get(targets.metric(name)), targets.values.get(name)
        parts.append(
            f"{_pct(errors.get(name))} on the {words.split(' (')[0]} ({_fmt(value)} vs "
            f"{_fmt(target)} {unit})"
        )
    return ", ".join(parts[:-1]) + " and " + parts[-1]


def _direction_words(answer: Mapping[str, Any], tolerance: float) -> str:
    """What the errors mean: stiffer or softer than the finger, too little or too much energy
    lost per tap ("" when every target is met)."""
    e = answer.get("errors_vs_targets") or {}
    disp = [e.get(m) for m in ("disp_at_1N_mm", "disp_at_4N_mm") if isinstance(e.get(m), float)]
    words = []
    if disp and all(x < -tolerance for x in disp):
        words.append("stiffer than the finger")
    elif disp and all(x > tolerance for x in disp):
        words.append("softer than the finger")
    h = e.get("hysteresis_Nmm")
    if isinstance(h, float) and h < -tolerance:
        words.append("losing too little energy per tap")
    elif isinstance(h, float) and h > tolerance:
        words.append("losing too much energy per tap")
    return " and ".join(words)


def _rejected(run: RunData, targets: Targets, validity: ValidityOptions) -> dict[str, int]:
    """How many FE-confirmed designs are no answer, and why: "strain" (beyond the strain
    limit), "J" (beyond the volume-ratio limit), "other" (another validity limit), "unsettled",
    "sag" (sagging over the targets' limit), "failed"."""
    out = dict.fromkeys(("strain", "J", "other", "unsettled", "sag", "failed"), 0)
    for c in run.confirmations:
        d = c.diagnostics
        if c.status != "ok":
            out["failed"] += 1
        elif d.get("valid") is False:
            js = [d.get(f"{p}_min_J") for p in _PROTOCOLS]
            if _beyond_strain_limit(d, validity):
                out["strain"] += 1
            elif any(isinstance(x, int | float) and x < validity.min_J for x in js):
                out["J"] += 1
            else:
                out["other"] += 1
        elif d.get("settled") is False:
            out["unsettled"] += 1
        elif not targets.sag_ok(nan_if_none(c.fe_metrics.get("sag_mm"))):
            out["sag"] += 1
    return out


def _strain_limits(d: Mapping[str, Any], validity: ValidityOptions) -> dict[str, Any]:
    """Per strain-limited protocol, the layer whose compressive limit binds an FE result's
    diagnostics (``sim.protocols.validity.binding_strain_limit``: each layer against its own
    tested limit, or the override; a record without per-layer figures on its largest strain)."""
    out = {}
    for p in validity.strain_limited:
        summary = strain_summary(d, p)
        if summary is not None:
            out[p] = binding_strain_limit(summary, validity)
    return out


def _beyond_strain_limit(d: Mapping[str, Any], validity: ValidityOptions) -> bool:
    """Whether an FE result's diagnostics put a layer beyond its compressive limit."""
    return any(
        s.strain > s.limit
        for p in validity.strain_limited
        if (summary := strain_summary(d, p)) is not None
        for s in strain_limits(summary, validity)
    )


def _strain_limit_words(s: Any) -> str:
    """A layer's limit (``StrainLimit``) in words: "its limit of 0.53 (argued: ...)"; "the
    validity limit of 0.60 (...)" for a record without per-layer figures."""
    what = {
        "measured": "the strain its material was tested to",
        "argued": "argued for its material: no test compressed it that far",
        "untested": "the paper's: its material has no tested range",
        "overridden": "one limit for every layer: the training sweep's options or --set "
        "validity.max_compressive_log_strain",
        "": "the strain the materials were tested to",
    }.get(s.basis, s.basis)
    whose = "its" if s.label else "the validity"
    return f"{whose} limit of {s.limit:.2f} ({what})"


def _binding_words(d: Mapping[str, Any], validity: ValidityOptions) -> str:
    """The tapping's binding layer (``_strain_limits``) in words: "; layer 1 (core,
    family.gel) at 0.512 against its limit of 0.53 (argued ...)", or "" without one."""
    s = _strain_limits(d, validity).get("tapping")
    if s is None:
        return ""
    if not s.label:  # a record without per-layer figures: its largest strain is all there is
        return ""
    return f"; {s.label} at {s.strain:.3f} against {_strain_limit_words(s)}"


def _limit_words(answer: Mapping[str, Any], run: RunData, targets: Targets) -> str:
    """What holds the best design where it is: the validity limit or the sag limit it is at,
    and how many other confirmed designs went beyond those limits."""
    validity = run_options(run).validity
    min_j = validity.min_J
    d = answer.get("diagnostics") or {}
    strains = _strain_limits(d, validity)
    js = {p: d[f"{p}_min_J"] for p in _PROTOCOLS if isinstance(d.get(f"{p}_min_J"), int | float)}
    sag = (answer.get("readings") or {}).get("sag_mm")
    max_sag = targets.max_sag_mm
    binding, free = [], []
    if strains:
        where, s = max(strains.items(), key=lambda kv: kv[1].strain / max(kv[1].limit, 1e-12))
        layer = f" {s.label}" if s.label else ""
        text = (
            f"its {where} compresses{layer or ' it'} to a log strain of {s.strain:.3f} against "
            + _strain_limit_words(s)
        )
        (binding if s.strain >= _AT_LIMIT * s.limit else free).append(text)
    if js:
        where, j = min(js.items(), key=lambda kv: kv[1])
        if min_j >= _AT_LIMIT * j:
            binding.append(f"its {where} brings the volume ratio J to {j:.2f}, the limit {min_j}")
    if isinstance(sag, int | float) and max_sag is not None:
        text = f"its sag between taps is {_fmt(sag)} mm against the {_fmt(max_sag)} mm limit"
        (binding if sag >= _SAG_AT_LIMIT * max_sag else free).append(text)
    n = len(run.confirmations)
    why = _rejected(run, targets, validity)
    beyond = [
        f"{why[k]} went beyond {words}"
        for k, words in (
            ("strain", "the strain limit"),
            ("J", "the volume limit"),
            ("other", "another validity limit"),
        )
        if why[k]
    ]
    if why["sag"]:
        beyond.append(f"{why['sag']} sagged over the limit")
    if why["unsettled"]:
        beyond.append(f"{why['unsettled']} did not settle")
    if why["failed"]:
        beyond.append(f"{why['failed']} failed")
    others = f" Of the {n} FE-confirmed designs, " + ", ".join(beyond) + "." if beyond else ""
    if binding:
        softer = ""
        e = answer.get("errors_vs_targets") or {}
        if any("strain" in b for b in binding) and all(
            isinstance(e.get(m), float) and e[m] < 0 for m in ("disp_at_1N_mm", "disp_at_4N_mm")
        ):
            softer = (
                ": a softer design, nearer the displacement targets, would strain more and go "
                "beyond it"
            )
        text = "What limits it: " + "; ".join(binding) + softer
        if free:
            text += " (" + "; ".join(free) + ")"
        return text + "." + others
    return (
        "No validity or sag limit holds it (" + "; ".join(free) + "): the bounds of the design "
        "space and the trade-off between the targets do (see the notes)." + others
        if free
        else "The run records no validity diagnostics for it." + others
    )


def _verdict(run: RunData, targets: Targets | None) -> list[str]:
    """The first paragraph: the closest credible design, its error on each target and what
    limits it, and the best buildable design."""
    if not run.summary:
        return ["**Verdict**: none yet: the run has no summary.json (it has not finished).", ""]
    answers = run.summary.get("answers") or {}
    best, build = answers.get("best"), answers.get("buildable")
    tolerance = run.summary.get("tolerance")
    tol = tolerance if isinstance(tolerance, int | float) else 0.0
    if not best:
        notes = run.summary.get("notes") or ["no design was confirmed by FE"]
        return [f"**Verdict: no credible design.** {notes[0][0].upper()}{notes[0][1:]}.", ""]
    met = all((best.get("within_tolerance") or {}).values())
    tol_text = f"±{100 * tol:.0f} %"
    noun = (
        "closest design (NOT CREDIBLE: let in by `--allow-untrusted`)"
        if best.get("credible") is False
        else "closest credible design"
    )
    head = (
        f"**Verdict**: the {noun} meets every target within {tol_text}"
        if met
        else f"**Verdict**: no design of this run meets the targets within {tol_text}"
    )
    text = (
        f"{head}. The {noun} (FE score {_fmt(best.get('fe_score'))}, "
        f"[`{ANSWERS}/best.toml`]({ANSWERS}/best.toml)) is {_stack_words(best)}, "
        f"{_outline_words(best)}."
    )
    if targets is not None:
        direction = _direction_words(best, tol)
        text += (
            f" Against the targets (displacements read {READING_WORDS[targets.reading]}) it is "
            f"{_error_words(best, targets)}" + (f": {direction}." if direction else ".")
        )
        if not met:
            text += " " + _limit_words(best, run, targets)
    if build:
        errors = ", ".join(_pct(v) for v in (build.get("errors_vs_targets") or {}).values())
        text += (
            f" The best buildable design (catalogue materials only; FE score "
            f"{_fmt(build.get('fe_score'))}, "
            f"[`{ANSWERS}/buildable.toml`]({ANSWERS}/buildable.toml)) is "
            f"{_stack_words(build)}: {errors} on the same targets."
        )
    else:
        text += " No buildable design (catalogue materials only) was confirmed credible."
    return [text, ""]


def _intro(run: RunData, targets: Targets | None = None) -> list[str]:
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
    dimension = run_options(run).dimension
    return [
        f"# Fingertip skin search: `{run.run_dir.name}`",
        "",
        *_verdict(run, targets),
        f"With the {_SURROGATE_WORDS[dimension]}, the search {screened}scored {run.n_trials} "
        f"Optuna trials{best} over {len(rounds)} "
        f"round(s), then re-ran {len(run.confirmations)} of them with the full "
        f"{_FE_WORDS[dimension]} ({n_ok} succeeded). Only FE-confirmed designs count as "
        "answers: the surrogate proposes, the FE model decides. A design's score is the rms "
        f"relative error to the three tapping targets plus {WEDGE_WEIGHT:g} x its wedge effort "
        "(0 is perfect, lower is better).",
        "",
    ]


def _targets_section(targets: Targets | None, tolerance: Any, dimension: str = "2d") -> list[str]:
    lines = ["## Targets", ""]
    if targets is None:
        return [*lines, "No targets were recorded for this run.", ""]
    lines += ["| target | value | meaning |", "|---|---|---|"]
    for name in TAPPING:
        words, unit = _TARGET_WORDS[name]
        lines.append(f"| `{name}` | {_fmt(targets.values[name])} {unit} | {words} |")
    reference = (
        f"{WEDGE_REFERENCE_3D_N} N, the paper's silicone as the default 3D pad"
        if dimension == "3d"
        else f"{WEDGE_REFERENCE_N} N, the paper's silicone"
    )
    lines.append(
        "| `wedge_peak_force_N` | as low as possible | force to press a wedge into the skin "
        f"(wedge effort = force / {reference}) |"
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


def _readings_rows(
    answer: Mapping[str, Any], targets: Targets | None, validity: ValidityOptions
) -> list[str]:
    """The sag between the two readings of the displacements (those above are in the targets'
    reading) and the validity of the FE result, with the layer whose limit binds it."""
    r = answer.get("readings") or {}
    d = answer.get("diagnostics") or {}
    if not r and not d:
        return []
    reading = targets.reading if targets is not None else "from_undeformed_top"
    other = "from_undeformed_top" if reading == "from_first_touch" else "from_first_touch"
    shown = r.get(other) or {}
    sag = r.get("sag_mm")
    return [
        f"- **Sag** (the displacement left by the earlier taps): {_fmt(sag)} mm. The "
        f"displacements above are read {READING_WORDS[reading]}, as the targets are; read "
        f"{READING_WORDS[other]} they are {_fmt(shown.get('disp_at_1N_mm'))} and "
        f"{_fmt(shown.get('disp_at_4N_mm'))} mm (they differ by the sag).",
        f"- **Settled**: {_fmt(d.get('settled'))}; **within the validity limits**: "
        f"{_fmt(d.get('valid'))} (largest compressive log strain in tapping "
        f"{_fmt(d.get('tapping_max_compressive_log_strain'))}{_binding_words(d, validity)}, "
        f"smallest J {_fmt(d.get('tapping_min_J'))}).",
        "",
    ]


def _validity_override_lines(options: SimOptions) -> list[str]:
    """A run whose FE held every layer to one limit (its surrogate's training sweep's option,
    ``--set validity...`` when that sweep was made) says so under the targets."""
    return [
        f"**Validity override**: this run's FE held every layer to `validity.{option}` = "
        f"{value:g} (the option of the surrogate's training sweep), not to the limit its "
        "material was tested to.\n"
        for option, value in options.validity.overridden.items()
    ]


#: the surrogate and the FE model of a run, by the model it searched (``run_options``)
_SURROGATE_WORDS = {
    "2d": "neural surrogate",
    "3d": "multi-fidelity neural surrogate (3D metrics from many 2D and few 3D designs)",
}
_FE_WORDS = {
    "2d": "finite-element (FE) solver",
    "3d": "3D finite-element (FE) model of the pad",
}
#: the 3D answers' contact areas, shown beside the tapping targets
CONTACT_AREAS = ("contact_area_at_1N_mm2", "contact_area_at_4N_mm2")
#: where the search for the human finger's contact area is written up
HUMAN_CONTACT_DOC = "docs/fingertip_3d.md"


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
    for metric in CONTACT_AREAS:  # a 3D answer's contact patch (no human value was found)
        if metric in fe:
            p = predicted.get(metric) or {}
            point = _fmt(p.get("median", p.get("mean")))
            pred = f"{point} ({_fmt(p.get('lower_90'))} to {_fmt(p.get('upper_90'))})"
            rows.append(
                f"| `{metric}` | no human value found (`{HUMAN_CONTACT_DOC}`) | "
                f"{_fmt(fe.get(metric))} | – | – | {pred} |"
            )
    return rows


def _answer_section(
    kind: str,
    answer: Mapping[str, Any] | None,
    targets: Targets | None,
    tolerance: Any,
    options: SimOptions,
) -> list[str]:
    lines = [f"### {_ANSWERS.get(kind, kind)}", ""]
    if not answer:
        return [*lines, f"No credible {kind} design was confirmed by FE in this run.", ""]
    lines += _design_words(answer)
    lines += [
        f"- **FE score**: {_fmt(answer.get('fe_score'))} (0 = every target met).",
        f"- **Design file**: [`{ANSWERS}/{kind}.toml`]({ANSWERS}/{kind}.toml) "
        f"(`fingertip simulate {ANSWERS}/{kind}.toml`).",
        "",
    ]
    if answer.get("credible") is False:
        lines += ["**Not credible** (let in by `--allow-untrusted`): see its diagnostics.", ""]
    if targets is not None:
        lines += [*_answer_rows(answer, targets, tolerance, options), ""]
    lines += _readings_rows(answer, targets, options.validity)
    return lines


def _answers_section(run: RunData, targets: Targets | None) -> list[str]:
    answers = run.summary.get("answers") or {}
    tolerance = run.summary.get("tolerance")
    lines = ["## Answers", ""]
    if not run.summary:
        return [*lines, "No summary.json: the run did not finish its confirmations.", ""]
    options = run_options(run)
    for kind in (*_ANSWERS, *(k for k in answers if k not in _ANSWERS)):
        lines += _answer_section(kind, answers.get(kind), targets, tolerance, options)
    return lines


def _answers_3d_section(run: RunData, targets: Targets | None) -> list[str]:
    """``--model 3d``: each answer simulated with the 3D pad (answers_3d.json), set against the
    targets; nothing when the run's answers were not."""
    data = read_answers_3d(run.run_dir)
    answers = data.get("answers") or {}
    if not answers:
        return []
    reading = targets.reading if targets is not None else "from_undeformed_top"
    lines = [
        "## The answers as 3D fingertips",
        "",
        "Each answer above simulated with the 3D pad (its section and layers, the pad's default "
        "length and profile; `fingertip run --model 3d`, `answers_3d.json`): the same design "
        "as a fingertip rather than a plane-strain section times 10 mm. The answers were chosen "
        f"in 2D; displacements read {READING_WORDS[reading]}.",
        "",
        "| answer | d(1 N) mm | d(4 N) mm | hysteresis N mm | error vs targets (1 N, 4 N, "
        "hysteresis) | change from 2D | contact area at 1 N / 4 N mm² | credible in 3D |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for kind, a in answers.items():
        label = f"[{kind}]({ANSWERS}/{kind}.toml)"
        if not a:
            continue
        if a.get("status") != "ok":
            lines.append(f"| {label} | FE failed: {a.get('reason') or '?'} | | | | | | |")
            continue
        fe = a.get("fe_metrics") or {}
        metric = targets.metric if targets is not None else (lambda m: m)
        errors = a.get("errors_vs_targets") or {}
        change = a.get("change_from_2d") or {}
        reasons = not_credible(a)
        why = "no: " + ", ".join(reasons) if reasons else "yes"
        lines.append(
            f"| {label} | {_fmt(fe.get(metric('disp_at_1N_mm')))} | "
            f"{_fmt(fe.get(metric('disp_at_4N_mm')))} | {_fmt(fe.get('hysteresis_Nmm'))} | "
            + ", ".join(_pct(errors.get(m)) for m in TAPPING)
            + " | "
            + ", ".join(_pct(change.get(m)) for m in TAPPING)
            + f" | {_fmt(fe.get('contact_area_at_1N_mm2'))} / "
            f"{_fmt(fe.get('contact_area_at_4N_mm2'))} | {why} |"
        )
    wall = data.get("fe_wall_time_s")
    lines += [
        "",
        '"Change from 2D" is the 3D value over the 2D one, less 1 (the 2D displacements read '
        "from the undeformed top; the hysteresis per 10 mm of finger in 2D, the whole pad's in "
        f"3D). The 3D simulations took {_fmt(wall)} s (one core each).",
        "",
    ]
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


def _no_score(c: Confirmation) -> str:
    """Why a confirmed design has no FE score: its FE failed, it went beyond the validity
    limits (and stopped there), its taps did not settle, or a scored metric was not reached."""
    d = c.diagnostics
    if c.status != "ok":
        return f"FE failed: {c.reason or 'no reason recorded'}"
    if d.get("valid") is False:
        stopped = d.get("stopped")
        stopped = f"; stopped there: {stopped.replace(',', ', ')}" if stopped else ""
        return f"invalid: {d.get('violations') or 'beyond the validity limits'}{stopped}"
    if d.get("settled") is False:
        return "unsettled: the taps did not reach their periodic state"
    missing = [m for m in _SCORED if c.fe_metrics.get(m) is None]
    return "not reached: " + ", ".join(missing) if missing else "no score recorded"


def _score_cell(c: Confirmation, targets: Targets | None) -> str:
    """A confirmation's FE score, with why there is none, or why a scored design is no
    answer (it sags more than the targets allow)."""
    if not math.isfinite(c.fe_score):
        return f"– ({_no_score(c)})"
    sag = c.fe_metrics.get("sag_mm")
    if (
        targets is not None
        and c.trusted
        and isinstance(sag, int | float)
        and not targets.sag_ok(sag)
    ):
        return f"{_fmt(c.fe_score)} (not credible: sag {_fmt(sag)} > {_fmt(targets.max_sag_mm)} mm)"
    if not c.trusted:
        return f"{_fmt(c.fe_score)} (not credible: {_no_score(c)})"
    return _fmt(c.fe_score)


def _confirmations_section(run: RunData, targets: Targets | None) -> list[str]:
    """Surrogate vs FE per confirmed design and scored metric (the displacements in the
    targets' reading)."""
    lines = ["## Confirmed designs: surrogate vs FE", ""]
    if not run.confirmations:
        return [*lines, "No design was confirmed by FE yet.", ""]
    scored = [targets.metric(m) if targets is not None else m for m in _SCORED]
    head = ["round", "trial", "chosen as", "FE status", "FE score"]
    lines += [
        "| " + " | ".join(head + [f"`{m}` error" for m in scored]) + " |",
        "|" + "---|" * (len(head) + len(scored)),
    ]
    for c in run.confirmations:
        cells = [
            str(c.candidate.round),
            str(c.candidate.trial),
            f"{c.candidate.reason} ({c.candidate.search})",
            c.status,
            _score_cell(c, targets),
        ]
        for m in scored:
            err, inside = c.rel_error.get(m), c.inside_90.get(m)
            mark = "" if inside is None else (" ✓" if inside else " ✗")
            cells.append("–" if err is None else f"{100 * err:+.1f} %{mark}")
        lines.append("| " + " | ".join(cells) + " |")
    reading = READING_WORDS.get(targets.reading, "") if targets is not None else ""
    lines += [
        "",
        "Error = (surrogate prediction − FE) / |FE|; ✓ / ✗: the FE value lies inside / outside "
        "the surrogate's 90 % interval; – : no FE value (the FE score says why)"
        + (f". Displacements read {reading}, as the targets are." if reading else "."),
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
        *_intro(run, targets),
        *_targets_section(targets, run.summary.get("tolerance"), run_options(run).dimension),
        *_validity_override_lines(run_options(run)),
        *_answers_section(run, targets),
        *_answers_3d_section(run, targets),
        *_rounds_section(run),
        *_confirmations_section(run, targets),
        *_notes_section(run),
        *_study_section(run_dir, run.config.get("storage")),
        *_figures_section(paths),
    ]
    path = run_dir / "report.md"
    text = "\n".join(lines).rstrip() + "\n"
    write_if_changed(path, text)  # the same: left alone
    return path
