"""The answer of a search (``Summary``): the best credible FE-confirmed design and the best of
each family (gel only, foam core, buildable), how each meets the targets, and notes on what is
missed and why (by the surrogate's view of the searched designs, and the sensitivities around
the best design: ``explore._sensitivity``).

An FE result can be an answer only when it is credible (:func:`credible`): it ran, settled,
stayed within the validity limits and recovers between taps.
"""

from __future__ import annotations

import math
import textwrap
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

from sim.design import (
    FAMILIES,
    READINGS,
    Targets,
    active_roles,
    design_to_toml,
    is_family,
    point_to_design,
)
from sim.provenance import nan_if_none

from ._buildable import FE_SEARCH, material_notes
from ._objective import TAPPING, closeness
from ._search import FAMILY_SEARCHES, TrialRow, design_family
from ._sensitivity import sensitivity_notes
from ._types import Confirmation, Summary

__all__ = [
    "ANSWER_KINDS",
    "ANSWER_WORDS",
    "LayerMaterial",
    "answer_file_text",
    "credible",
    "layer_materials",
    "summarise",
    "target_errors",
    "target_met",
]

#: the answers of a run, in report order: kind -> what the design must be (``design_family``)
ANSWER_KINDS = {"best": None, "gel": "gel", "foam": "foam", "buildable": "catalogue"}
#: each answer in words (the report's headings, the answer files' headers)
ANSWER_WORDS = {
    "best": "Best credible design (closest to the targets, confirmed by FE)",
    "gel": "Best gel-only design (every layer of the gel family, confirmed by FE)",
    "foam": "Best foam-core design (a core of the foam family, confirmed by FE)",
    "buildable": "Best buildable design (catalogue materials only, confirmed by FE)",
}


def target_errors(c: Confirmation, targets: Targets) -> dict[str, float]:
    """FE relative error of a confirmed design against each tapping target."""
    cl = closeness(c.fe_metrics, targets)
    return {m: float(cl.errors[m]) for m in TAPPING}


def target_met(confirmations: list[Confirmation], targets: Targets, tol: float) -> bool:
    """Whether some credible FE-confirmed design is within ``tol`` of every tapping target."""
    return any(
        credible(c, targets) and all(abs(e) <= tol for e in target_errors(c, targets).values())
        for c in confirmations
    )


def _answer(
    c: Confirmation | None, targets: Targets, tol: float, space, catalogue=None
) -> dict | None:
    if c is None:
        return None
    errors = target_errors(c, targets)
    fe = c.to_json()["fe_metrics"]
    return {
        "design": point_to_design(c.candidate.point, catalogue or space.catalogue).to_dict(),
        "point": c.to_json()["candidate"]["point"],
        "family": design_family(c.candidate.point),
        "search": c.candidate.search,
        "reason": c.candidate.reason,
        "round": c.candidate.round,
        "trusted_by_surrogate": c.candidate.trusted,
        "flags": list(c.candidate.flags),
        "predicted": c.candidate.predicted,
        "predicted_score": c.to_json()["candidate"]["score"],  # None: no prediction
        "fe_metrics": fe,
        "fe_score": c.fe_score,
        "readings": _readings(fe),
        "errors_vs_targets": errors,
        "within_tolerance": {m: abs(e) <= tol for m, e in errors.items()},
        "credible": credible(c, targets),  # False only when --allow-untrusted let it in
        "diagnostics": c.diagnostics,
        "fe_record": f"fe/records/{c.key}.json",
    }


def _readings(fe: dict[str, float | None]) -> dict[str, Any]:
    """The tapping displacements in both readings, and the sag between them (mm)."""
    return {
        reading: {t: fe.get(m) for t, m in names.items()} for reading, names in READINGS.items()
    } | {"sag_mm": fe.get("sag_mm")}


def credible(c: Confirmation, targets: Targets, allow_untrusted: bool = False) -> bool:
    """Whether an FE-confirmed design can be an answer: it ran, its taps settled, it stayed
    within the validity limits (``Confirmation.trusted``) and it recovers between taps (its
    ``sag_mm`` within ``targets.max_sag_mm``). ``allow_untrusted``: any design that ran."""
    if c.status != "ok" or not math.isfinite(c.fe_score):
        return False
    if allow_untrusted:
        return True
    return c.trusted and bool(targets.sag_ok(nan_if_none(c.fe_metrics.get("sag_mm"))))


def summarise(
    confirmations: list[Confirmation],
    targets: Targets,
    tol: float,
    rounds: list[dict[str, Any]],
    rows: list[TrialRow],
    space,
    catalogue: dict | None = None,
    allow_untrusted: bool = False,
    surrogate=None,
) -> Summary:
    """The answers and the notes. "best": the best credible FE result of the searches;
    "gel", "foam", "buildable": the best credible FE result of that family (every layer a gel;
    a foam core; catalogue materials only, the FE-only screen included, which competes for this
    answer only), whichever search proposed it. ``catalogue``: the merged catalogue the designs'
    material names come from (default: the space's); ``surrogate``: for the sensitivities of a
    missed target around the best design (``explore._sensitivity``)."""
    ok = [c for c in confirmations if credible(c, targets, allow_untrusted)]
    answers: dict[str, dict | None] = {}
    for kind, family in ANSWER_KINDS.items():
        pool = [
            c
            for c in ok
            if (family is None and c.candidate.search != FE_SEARCH)
            or (family is not None and design_family(c.candidate.point) == family)
        ]
        best = min(pool, key=lambda c: c.fe_score, default=None)
        answers[kind] = _answer(best, targets, tol, space, catalogue)
    notes = _notes(answers, targets, tol, rows)
    if answers["best"] is None:
        notes = [_no_answer(confirmations, targets)]
    elif surrogate is not None and not all(answers["best"]["within_tolerance"].values()):
        notes += sensitivity_notes(surrogate, answers["best"]["point"], targets, tol)
    notes += material_notes(answers, catalogue or space.catalogue, tol)
    return Summary(answers, dict(targets.values), tol, rounds, notes)


def _no_answer(confirmations: list[Confirmation], targets: Targets) -> str:
    """Why there is no best design: the FE failed, or no FE result was credible."""
    ran = [c for c in confirmations if c.status == "ok" and c.candidate.search != FE_SEARCH]
    if not ran:
        return "no design was confirmed by FE (every confirmation failed)"
    unsettled = sum(c.diagnostics.get("settled") is False for c in ran)
    invalid = sum(c.diagnostics.get("valid") is False for c in ran)
    sagging = sum(
        c.trusted and not targets.sag_ok(nan_if_none(c.fe_metrics.get("sag_mm"))) for c in ran
    )
    return (
        f"no credible answer: of {len(ran)} FE-confirmed designs, {invalid} went beyond the "
        f"validity limits, {unsettled} did not reach their periodic state and {sagging} sagged "
        f"more than {targets.max_sag_mm} mm between taps (see confirmations.json, "
        "`diagnostics`; `--set validity.*` widens the limits, `--allow-untrusted` lets such "
        "designs compete, flagged)"
    )


def _notes(
    answers: dict[str, dict | None], targets: Targets, tol: float, rows: list[TrialRow]
) -> list[str]:
    """Which target each answer misses, by how much, and what the search says why."""
    if answers.get("best") is None:
        return ["no design was confirmed by FE (every confirmation failed)"]
    notes = []
    for kind, search in (("best", "continuous"), *((f, f) for f in FAMILY_SEARCHES),
                         ("buildable", "buildable")):  # fmt: skip
        answer = answers.get(kind)
        if answer is None:
            continue
        if answer.get("search") == FE_SEARCH:  # no surrogate view of these materials
            notes += [
                f"{kind}: {m} is missed: FE {answer['fe_metrics'][targets.metric(m)]:.3g} vs "
                f"target {targets.values[m]:.3g} ({100 * e:+.1f} %, tolerance ±{100 * tol:.0f} "
                "%); this stack comes from the FE-only screen of the catalogue"
                for m, e in answer["errors_vs_targets"].items()
                if abs(e) > tol
            ]
            continue
        searched = [r for r in rows if r.search == search and math.isfinite(r.score)]
        last = max((r.round for r in searched), default=0)
        missed = [
            _why(kind, m, e, answer, targets, tol, [r for r in searched if r.round == last])
            for m, e in answer["errors_vs_targets"].items()
            if abs(e) > tol
        ]
        if not missed:
            missed = [f"{kind}: the FE-confirmed design is within ±{100 * tol:.0f} % of every "
                      "target"]  # fmt: skip
        notes += missed
    return notes


def _why(
    kind: str, m: str, e: float, answer: dict, targets: Targets, tol: float, rows: list[TrialRow]
) -> str:
    """One missed target: by how much, and the surrogate's view of whether the space (or the
    catalogue) can reach it while meeting the other two targets."""
    text = (
        f"{kind}: {m} is missed: FE {answer['fe_metrics'][targets.metric(m)]:.3g} vs target "
        f"{targets.values[m]:.3g} ({100 * e:+.1f} %, tolerance ±{100 * tol:.0f} %)."
    )
    where = "searched catalogue-only design" if kind == "buildable" else "searched design"
    errs = [
        {o: _rel(r.predicted[targets.metric(o)]["median"], targets.values[o]) for o in TAPPING}
        for r in rows
    ]
    alone = min((abs(x[m]) for x in errs), default=math.inf)
    others = [o for o in TAPPING if o != m]
    feasible = [abs(x[m]) for x in errs if all(abs(x[o]) <= tol for o in others)]
    if alone > tol:
        return text + (
            f" No {where} is predicted within ±{100 * tol:.0f} % of it even alone (best "
            f"{100 * alone:.0f} % by the surrogate): out of reach of this space."
        )
    if not feasible:
        return text + (
            f" Some {where}s are predicted to meet it, but none together with the other two "
            "targets: a trade-off inside the space, by the surrogate."
        )
    if min(feasible) > tol:
        return text + (
            f" Among the {where}s predicted to meet the other two targets, the best error on "
            f"this one is {100 * min(feasible):.1f} % (surrogate): the space trades it against "
            "the others."
        )
    return text + (
        " The surrogate predicts designs that meet all three; FE disagrees with it here, so "
        "more FE data near the optimum (more --rounds) should close the gap."
    )


def _rel(v: float | None, target: float) -> float:
    return math.inf if v is None else (v - target) / target


# ---------------------------------------------------------------------------------------------
# An answer's materials, and its design file
# ---------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class LayerMaterial:
    """Where the material of an answer's layer comes from: ``role`` ("skin", "middle",
    "core"); ``family``: the design-space family the search drew it from ("gel", "foam", ...,
    ``sim.design.families``), None for a catalogue material; ``name``: its catalogue name (None for
    a family member); ``parameters``: the family parameters it was drawn with (``mu0_MPa``,
    ``alpha``, ``nu``, ``g_total``, ``tau_s``: those the family uses), from the answer's point."""

    role: str
    family: str | None
    name: str | None
    parameters: tuple[tuple[str, float], ...] = ()

    def words(self) -> str:
        """``platsil_gel_10_marechal (catalogue)`` or ``gel family (mu0_MPa 0.0105, alpha 3.8,
        g_total 0.555, tau_s 0.0408)``."""
        if self.family is None:
            return f"{self.name or 'an inline material'} (catalogue)"
        values = ", ".join(f"{k} {v:.3g}" for k, v in self.parameters)
        return f"{self.family} family" + (f" ({values})" if values else "")

    @property
    def description(self) -> str:
        """What the family is (``sim.design.families.Family.description``; "" for a catalogue
        material)."""
        fam = FAMILIES.get(self.family) if self.family is not None else None
        return fam.description if fam is not None else ""


def layer_materials(answer: Mapping[str, Any]) -> list[LayerMaterial]:
    """The materials of an answer's layers, outermost first: a catalogue name, or the family
    (and its parameters) the search used (the ``point``'s ``<role>.material``)."""
    layers = (answer.get("design") or {}).get("layers") or []
    point = answer.get("point") or {}
    out = []
    for role, layer in zip(active_roles(len(layers)), layers, strict=False):
        chosen = point.get(f"{role}.material")
        if is_family(chosen):
            keys = FAMILIES[chosen].keys
            params = tuple(
                (k, float(point[f"{role}.{k}"]))
                for k in keys
                if isinstance(point.get(f"{role}.{k}"), int | float)
            )
            out.append(LayerMaterial(role, chosen, None, params))
            continue
        material = layer.get("material")
        name = material if isinstance(material, str) else None
        if isinstance(material, Mapping):
            name = material.get("name") or (chosen if isinstance(chosen, str) else None)
        out.append(LayerMaterial(role, None, name))
    return out


def answer_file_text(
    kind: str,
    answer: Mapping[str, Any],
    *,
    run_name: str,
    made_by: str | None,
    reading: str,
    tolerance: float | None,
    option_overrides: Sequence[str] = (),
) -> str:
    """The design file of answer ``kind`` (``answers/<kind>.toml``): the design, as
    ``fingertip simulate`` and ``fingertip predict`` read it, under a comment header naming the
    answer, its FE score and errors, the command and run that made it (``made_by``: the run's
    command, ``run_name``: its folder) and how to check it (``option_overrides``: the
    ``--set`` options under which the run's FE ran, when not the defaults); a comment on each
    layer says which catalogue material or family it is."""
    errors = answer.get("errors_vs_targets") or {}
    score = answer.get("fe_score")
    record = answer.get("fe_record")
    tol = f" (tolerance ±{100 * tolerance:.0f} %)" if isinstance(tolerance, int | float) else ""
    words = ANSWER_WORDS.get(kind, kind)
    header = [
        f'fingertip answer "{kind}" of the search run "{run_name}":',
        f"  {words[0].lower()}{words[1:]}",
        f"made by: {made_by or 'a command meta.json does not record'}",
        f"  (round {answer.get('round')}, {answer.get('search')} search"
        + (f"; FE record {record})" if record else ")"),
    ]
    if isinstance(score, int | float):
        header.append(f"FE score {score:.3g} (0 = every target met, lower is better)")
    if errors:
        header += [
            f"error vs the targets, displacements read {READING_WORDS.get(reading, reading)}{tol}:",
            "  " + ", ".join(f"{m} {100 * e:+.1f} %" for m, e in errors.items()),
        ]
    if answer.get("credible") is False:
        header.append("NOT CREDIBLE: let in by --allow-untrusted (its diagnostics: summary.json)")
    sets = "".join(f" --set {o}" for o in option_overrides)
    header += [
        f"check it: fingertip simulate THIS_FILE{sets}",
        "          fingertip predict CHECKPOINT THIS_FILE",
    ]
    if not sets:
        header.append("(the run's FE ran with the default options)")
    notes = {}
    for k, m in enumerate(layer_materials(answer)):
        text = f"{m.role}: {m.words()}" + (f": {m.description}" if m.description else "")
        notes[f"layers[{k}]"] = textwrap.wrap(text, 96, break_on_hyphens=False)
    return design_to_toml(answer["design"], header, notes)


#: how a targets file's displacement reading is said in words
READING_WORDS = {
    "from_first_touch": "from the first touch of each tap",
    "from_undeformed_top": "from the undeformed top of the fingertip",
}
