"""Buildable stacks the surrogate cannot predict, and the material a missed target would need.

The surrogate predicts the materials it was trained on only: a catalogue material enters it as
one of its space's choices (one-hot), so a material outside them (the fitted catalogue entries,
a user's ``--catalogue``) has no prediction at all, and none is made up for it (no proxy, no
"nearest known material"). The buildable search over such materials is therefore FE only: after
the rounds, :func:`fe_screen` simulates ``budget`` buildable stacks of the merged catalogue

1. ``"nearest"``: the best FE-confirmed design of the search with each layer's material replaced
   by the catalogue materials closest to it (:func:`material_distance`: long-term shear modulus
   and the fraction relaxed within 0.1 s and 1 s), its geometry and thicknesses kept: what can be
   built closest to the optimum (up to half the budget, the closest first);
2. ``"screen"``: seeded random stacks of the whole catalogue inside the space's geometry and
   thickness bounds (the rest of the budget): a screen, not a search.

Every one is an FE result (``rounds/buildable-fe-candidates.json``, ``buildable_fe.json``,
records in ``fe/records``), so it can be the buildable answer; none is used to retrain the
surrogate (it cannot encode them). :func:`material_notes` then says, per tapping target the
buildable answer misses, what a new material would need, from the materials of the best
FE-confirmed design and the catalogue's properties.
"""

from __future__ import annotations

import itertools
import json
import math
from collections.abc import Iterator, Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from sim.design import (
    LAYER_ROLES,
    DesignSpace,
    Parameter,
    Targets,
    active_roles,
    is_family,
    mask_inactive,
)
from sim.materials import CATALOGUE, Material, material_tables
from sim.metrics import METRICS
from sim.options import SimOptions
from sim.provenance import atomic_write, json_text, write_if_changed

from ._confirm import confirm, record_path
from ._types import Candidate, Confirmation

__all__ = [
    "DEFAULT_FE_BUDGET",
    "FE_SEARCH",
    "RELAXATION_TIMES_S",
    "fe_screen",
    "material_distance",
    "material_notes",
    "material_properties",
    "predictable_materials",
    "screen_jobs",
    "screen_space",
]

#: the ``search`` of the FE-only screen's candidates
FE_SEARCH = "buildable-fe"
#: FE designs of the screen by default: a handful (each one is a full FE run)
DEFAULT_FE_BUDGET = 8
#: the relaxation a material is described by: the fraction relaxed within these times (s); a
#: tap of the human targets loads for 1 s (0.5 Hz) and the paper's materials relax over
#: 0.025-25 s, so 0.1 s and 1 s say how much of the relaxation acts within a tap
RELAXATION_TIMES_S = (0.1, 1.0)
_NO_PREDICTION = {"median": None, "mean": None, "std": None, "lower_90": None, "upper_90": None}


# ----------------------------------------------------------------------------- materials
def material_properties(mat: Material) -> dict[str, float]:
    """``mu_MPa``: long-term small-strain shear modulus; ``relaxed_<t>s``: the fraction of the
    shear modulus relaxed within each of ``RELAXATION_TIMES_S`` (``1 - g(t)``)."""
    out = {"mu_MPa": float(mat.long_term.initial_shear_modulus_MPa)}
    for t in RELAXATION_TIMES_S:
        out[f"relaxed_{t:g}s"] = float(1.0 - mat.prony.relaxation(t)) if mat.prony.g else 0.0
    return out


def material_distance(a: Material, b: Material) -> float:
    """``|log10(mu_a / mu_b)| + sum_t |relaxed_a(t) - relaxed_b(t)|``: a decade of stiffness
    counts as much as relaxing everything or nothing within a tap."""
    pa, pb = material_properties(a), material_properties(b)
    d = abs(math.log10(pa["mu_MPa"] / pb["mu_MPa"]))
    return d + sum(abs(pa[f"relaxed_{t:g}s"] - pb[f"relaxed_{t:g}s"]) for t in RELAXATION_TIMES_S)


def predictable_materials(trained: DesignSpace) -> set[str]:
    """The catalogue materials a surrogate trained on ``trained`` can predict (its choices)."""
    out: set[str] = set()
    for role in LAYER_ROLES:
        name = f"{role}.material"
        if name in trained.names:
            p = trained[name]
            out |= set(p.choices if p.kind == "choice" else (p.value,))
    return {m for m in out if not is_family(m)}


def screen_space(space: DesignSpace, catalogue: Mapping[str, Material]) -> DesignSpace:
    """``space`` with every layer's material any material of ``catalogue`` (no "param"): its
    geometry, layer counts and thickness bounds are kept."""
    names = tuple(sorted(catalogue))
    params = [
        Parameter(p.name, "choice", choices=names) if p.name.endswith(".material") else p
        for p in space.parameters
    ]
    user = tuple(m for n, m in sorted(catalogue.items()) if CATALOGUE.get(n) != m)
    return DesignSpace(tuple(params), user)


# ----------------------------------------------------------------------------- the screen
def _nearest_points(
    best: Confirmation | None, space: DesignSpace, catalogue: Mapping[str, Material], k: int = 2
) -> list[dict[str, Any]]:
    """The best design with its layers' materials replaced by the ``k`` closest catalogue
    materials each, the closest stacks first."""
    if best is None:
        return []
    point = dict(best.candidate.point)
    design = space.design(point)
    roles = active_roles(point["layers.count"])
    ranked = []
    for layer in design.layers:
        dist = sorted((material_distance(layer.material, m), n) for n, m in catalogue.items())
        ranked.append(dist[:k])
    stacks = sorted(itertools.product(*ranked), key=lambda combo: sum(d for d, _ in combo))
    out = []
    for combo in stacks:
        p = dict(point)
        for role, (_, name) in zip(roles, combo, strict=True):
            p[f"{role}.material"] = name
        out.append(mask_inactive(p))
    return out


def _choose(
    best: Confirmation | None,
    space: DesignSpace,
    screen: DesignSpace,
    catalogue: Mapping[str, Material],
    budget: int,
    seed: int,
) -> list[Candidate]:
    chosen: list[tuple[str, dict[str, Any]]] = []
    seen: set[str] = set()

    def add(reason: str, point: dict[str, Any]) -> None:
        key = _stack_key(screen, point)
        if key not in seen and len(chosen) < budget:
            seen.add(key)
            chosen.append((reason, point))

    for point in _nearest_points(best, space, catalogue)[: max(1, budget // 2)]:
        add("nearest", point)
    for point in _screen_draws(screen, budget, seed):
        if len(chosen) >= budget:
            break
        add("screen", point)
    predicted = {m: dict(_NO_PREDICTION, by_rule=False) for m in METRICS}
    return [
        Candidate(
            point=point,
            reason=reason,
            round=-1,
            trial=i,
            search=FE_SEARCH,
            score=math.nan,
            predicted=predicted,
            in_domain=False,
            disagreement=math.nan,
            flags=("no surrogate prediction: FE only",),
        )
        for i, (reason, point) in enumerate(chosen)
    ]


def _stack_key(screen: DesignSpace, point: dict[str, Any]) -> str:
    """What tells two stacks apart: the design they make."""
    return json.dumps(screen.design(point).to_dict(), sort_keys=True)


def _screen_draws(screen: DesignSpace, budget: int, seed: int) -> Iterator[dict[str, Any]]:
    """The screen's seeded random stacks, in order, each once (a sample of a few catalogue
    materials repeats itself: up to ``50 budget`` draws)."""
    rng = np.random.default_rng(seed)
    seen: set[str] = set()
    for _ in range(50 * budget):
        point = screen.point(rng.random(len(screen.sampled)))
        key = _stack_key(screen, point)
        if key not in seen:
            seen.add(key)
            yield point


def screen_jobs(
    out: Path,
    space: DesignSpace,
    catalogue: Mapping[str, Material],
    options: SimOptions,
    *,
    budget: int,
    seed: int,
) -> tuple[list[tuple[Path, dict[str, Any]]], dict[str, dict[str, Any]] | None]:
    """The FE jobs (record path, point) of the random stacks :func:`fe_screen` takes whatever
    the search finds (the first ``budget - budget // 2``: the "nearest" stacks take at most
    ``budget // 2``), and the user materials' tables they need. Run ahead (beside the rounds'
    searches), their records are there when :func:`fe_screen` wants them: the same records,
    only their timing moves."""
    if budget <= 0:
        return [], None
    screen = screen_space(space, catalogue)
    points = itertools.islice(_screen_draws(screen, budget, seed), budget - budget // 2)
    jobs = [(record_path(out, p, options, screen.catalogue), p) for p in points]
    user = {str(m.name): m for m in screen.materials}
    return jobs, material_tables(user) or None


def fe_screen(
    out: Path,
    best: Confirmation | None,
    space: DesignSpace,
    catalogue: Mapping[str, Material],
    targets: Targets,
    options: SimOptions,
    *,
    budget: int,
    seed: int,
    workers: int,
    progress: bool,
) -> list[Confirmation]:
    """Simulate ``budget`` buildable stacks of ``catalogue`` (see the module docstring); a
    resumed run keeps its choice (``rounds/buildable-fe-candidates.json``) and its FE records."""
    if budget <= 0:
        return []
    screen = screen_space(space, catalogue)
    path = out / "rounds" / "buildable-fe-candidates.json"
    if path.exists():
        chosen = [Candidate.from_json(d) for d in json.loads(path.read_text())]
    else:
        chosen = _choose(best, space, screen, catalogue, budget, seed)
        path.parent.mkdir(parents=True, exist_ok=True)
        atomic_write(path, json_text([c.to_json() for c in chosen], indent=1))
    user = {str(m.name): m for m in screen.materials}
    done = confirm(
        chosen, out, targets, options, workers=workers, progress=progress,
        materials=material_tables(user) or None, catalogue=screen.catalogue,
    )  # fmt: skip
    text = json_text([c.to_json() for c in done], indent=1)
    write_if_changed(out / "buildable_fe.json", text)
    return done


# ----------------------------------------------------------------------------- notes
def _layers(answer: Mapping[str, Any], catalogue: Mapping[str, Material]) -> list[Material]:
    from sim.design import design_from_dict

    return design_from_dict(answer["design"], catalogue).materials


def material_notes(
    answers: Mapping[str, Mapping[str, Any] | None],
    catalogue: Mapping[str, Material],
    tol: float,
) -> list[str]:
    """Per tapping target the buildable answer misses: the property a new material would
    need, read from the best FE-confirmed design's layers (stiffness for a displacement,
    relaxation within a tap for the hysteresis) and set against the catalogue's materials."""
    build, best = answers.get("buildable"), answers.get("best")
    if build is None:
        return []
    props = {n: material_properties(m) for n, m in catalogue.items()}
    if best is None:
        return _catalogue_only_notes(build, props, tol)
    notes = []
    best_layers = _layers(best, catalogue)
    for m, e in build["errors_vs_targets"].items():
        if abs(e) <= tol:
            continue
        e_best = best["errors_vs_targets"][m]
        if abs(e_best) >= abs(e):
            notes.append(
                f"buildable: {m}: the best credible design does no better "
                f"({100 * e_best:+.1f} % against {100 * e:+.1f} %), so it names no material "
                "property for it"
            )
            continue
        if m.startswith("hysteresis"):
            t = RELAXATION_TIMES_S[0]
            key = f"relaxed_{t:g}s"
            layer = max(range(len(best_layers)), key=lambda i: _relaxed(best_layers[i], t))
            need = _relaxed(best_layers[layer], t)
            mu = _mu(best_layers[layer])
            close = [n for n, p in props.items() if p[key] >= 0.5 * need and _within(p, mu, 3)]
            most = max(props, key=lambda n: props[n][key])
            what = (
                f"a {_role(best, layer)} relaxing by >= {100 * need:.0f} % within {t:g} s, with "
                f"a long-term shear modulus near {1e3 * mu:.3g} kPa"
            )
            have = (
                f"the most relaxing, {most}, relaxes by {100 * props[most][key]:.0f} % within "
                f"{t:g} s"
            )
        else:
            layer = min(range(len(best_layers)), key=lambda i: _mu(best_layers[i]))
            mu = _mu(best_layers[layer])
            close = [n for n, p in props.items() if _within(p, mu, 1.5)]
            softest = min(props, key=lambda n: props[n]["mu_MPa"])
            what = f"a {_role(best, layer)} with a long-term shear modulus near {1e3 * mu:.3g} kPa"
            have = f"the softest, {softest}, has {1e3 * props[softest]['mu_MPa']:.3g} kPa"
        head = (
            f"buildable: {m} is missed by {100 * e:+.1f} %; the best FE-confirmed design "
            f"({100 * e_best:+.1f} % on it) has {what}"
        )
        if close:
            notes.append(
                f"{head}, and the catalogue has materials like it ({', '.join(sorted(close)[:3])}"
                "): the miss comes from the stack, more --buildable-fe designs may find it"
            )
        else:
            notes.append(
                f"{head}; no catalogue material comes close ({have}): a new material would "
                f"need to be {what}"
            )
    return notes


def _catalogue_only_notes(
    build: Mapping[str, Any], props: Mapping[str, Mapping[str, float]], tol: float
) -> list[str]:
    """Without a trusted design of the search no property can be named: what the catalogue
    offers for each missed target instead."""
    t = RELAXATION_TIMES_S[0]
    key = f"relaxed_{t:g}s"
    relaxing = [n for n, p in props.items() if p[key] > 0]
    most = max(props, key=lambda n: props[n][key])
    softest = min(props, key=lambda n: props[n]["mu_MPa"])
    notes = []
    for m, e in build["errors_vs_targets"].items():
        if abs(e) <= tol:
            continue
        fact = (
            f"{len(relaxing)} of the {len(props)} catalogue materials relax at all, the most "
            f"within {t:g} s {most} ({100 * props[most][key]:.0f} %)"
            if m.startswith("hysteresis")
            else f"the catalogue's softest material is {softest} "
            f"({1e3 * props[softest]['mu_MPa']:.3g} kPa)"
        )
        notes.append(
            f"buildable: {m} is missed by {100 * e:+.1f} %; no trusted FE design of the search "
            f"says what material would reach it; {fact}"
        )
    return notes


def _mu(mat: Material) -> float:
    return material_properties(mat)["mu_MPa"]


def _relaxed(mat: Material, t: float) -> float:
    return material_properties(mat)[f"relaxed_{t:g}s"]


def _within(props: Mapping[str, float], mu: float, factor: float) -> bool:
    return mu / factor <= props["mu_MPa"] <= mu * factor


def _role(answer: Mapping[str, Any], index: int) -> str:
    n = len(answer["design"]["layers"])
    return active_roles(n)[index] + (" layer" if n > 1 else " (one-layer skin)")


def screen_summary(screen: Sequence[Confirmation], n_materials: int) -> str:
    """One line on what the FE-only screen did."""
    ok = sum(c.trusted for c in screen)
    return (
        f"buildable: {len(screen)} stacks of the {n_materials}-material catalogue were "
        f"simulated by FE only ({ok} trusted results): the surrogate was trained on a few of "
        "these materials only and cannot predict the others"
    )
