"""Optuna searches of a surrogate for designs close to the targets, and candidate selection.

A study proposes design points define-by-run over a ``DesignSpace`` (a layer's parameters are
suggested only when the design uses them, so the search space is conditional exactly like the
design space); the surrogate scores batches of asked trials at once (ask/tell). Every trial keeps
its prediction as user attributes, so the study alone (``optuna-dashboard``) shows what the
surrogate said. Single-objective mode minimises the closeness score, multi-objective mode the
triple (compliance error, hysteresis error, wedge effort) — see ``explore._objective``.

The trust guard: a trial is *flagged* when its design lies outside the surrogate's training
domain or when the ensemble disagrees (relative spread std/|mean| of a scored metric above
``max_disagreement``). Flagged designs are never reported as answers unless FE confirmed them;
a few promising flagged designs are sent to FE on purpose ("uncertain" candidates), which is how
active learning improves the surrogate where the search wants to go.
"""

from __future__ import annotations

import hashlib
import math
import warnings
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from sim.design import DesignSpace, Parameter, Targets, is_family
from sim.protocols import LAYER_STRAIN_OUTPUTS, TRUST_OUTPUTS
from sim.provenance import finite_or_none

from ._objective import OBJECTIVE_NAMES, closeness, infeasibility, objectives
from ._types import Candidate

__all__ = [
    "FAMILY_SEARCHES",
    "SCORED",
    "SearchSettings",
    "TrialRow",
    "catalogue_only",
    "check_subspace",
    "create_study",
    "design_family",
    "family_space",
    "point_from_params",
    "predict_rows",
    "rows_of",
    "run_study",
    "screen",
    "select_candidates",
    "suggest_point",
]

#: the metrics the closeness score reads (targets.metric maps the displacement reading)
SCORED = ("disp_at_1N_mm", "disp_at_4N_mm", "hysteresis_Nmm", "wedge_peak_force_N")
#: the predictions credibility is judged on (``infeasibility``); the yes/no ones by their mean
_JUDGED = (*TRUST_OUTPUTS, *LAYER_STRAIN_OUTPUTS, "sag_mm")
_YES_NO = ("reached_base", "folded")


def _judged(pred, cols: dict[str, int], bound: bool) -> dict[str, np.ndarray]:
    """The predictions credibility is judged on: base contact and folding by their mean (a
    probability), the FE failure by its median (as the search always judged it, on either
    rule), the rest by their median or, with ``bound``, by the side of their 90 %
    interval towards the limit: the upper end of a strain, a tapping residual or error and the
    sag (limits from above), the lower end of a volume ratio J (a limit from below). A median
    just within a limit is as likely beyond it, and the answers sit on the limits: a 3D search
    on the median sent 21 candidates to FE, 14 of which came back beyond a limit by a hair (in
    2D 4 of 18, on either rule: docs/search.md, "Credible at the interval's bound")."""
    out = {}
    for m in _JUDGED:
        if m not in cols:
            continue
        if m in _YES_NO:
            values = pred.mean
        elif not bound or m == "failed":
            values = pred.median
        else:
            values = pred.lower_90 if m.endswith("_min_J") else pred.upper_90
        out[m] = values[:, cols[m]]
    return out


@dataclass(frozen=True)
class SearchSettings:
    """How one study searches. ``mode``: "single" (closeness score) or "multi" (Pareto front of
    the three objectives); ``batch``: trials asked and scored together; ``max_disagreement``:
    the trust guard's limit on std/|mean| (fraction)."""

    trials: int = 1500
    mode: str = "single"
    seed: int = 0
    batch: int = 16
    max_disagreement: float = 0.10
    #: score designs the surrogate predicts not credible (beyond the validity limits,
    #: unsettled, sag over the targets' limit) like the others; they stay flagged
    allow_untrusted: bool = False
    #: judge credibility on the side of each prediction's 90 % interval towards its limit
    #: (``_judged``), not on the median: a design is then credible only where the surrogate is
    #: about 95 % sure of it
    trust_bound: bool = False
    #: the simulation options whose validity limits and tapping tolerances judge credibility
    options: Any = None
    #: designs of a scrambled Sobol sample the surrogate scores before the sampler starts
    #: (0: none), and how many of the best of them seed the study as its first trials
    screen: int = 0
    #: 64 = TPE's own n_startup_trials (``_sampler``): the seeds take the place of its random
    #: start-up trials, so the model is fitted from the first asked trial on
    screen_keep: int = 64


@dataclass(frozen=True)
class TrialRow:
    """One scored trial: its point, prediction and closeness (the trials.csv row)."""

    round: int
    trial: int
    search: str
    point: dict[str, Any]
    score: float
    objectives: tuple[float, float, float]
    predicted: dict[str, dict[str, float | None]]
    in_domain: bool
    disagreement: float
    flags: tuple[str, ...]

    def candidate(self, reason: str) -> Candidate:
        return Candidate(
            point=self.point,
            reason=reason,
            round=self.round,
            trial=self.trial,
            search=self.search,
            score=self.score,
            predicted=self.predicted,
            in_domain=self.in_domain,
            disagreement=self.disagreement,
            flags=self.flags,
        )


# ----------------------------------------------------------------------------- spaces
def _restricted(p: Parameter, keep) -> Parameter:
    """Choice parameter ``p`` with only the choices of ``keep`` (in ``p``'s order), each keeping
    its weight."""
    w = dict(zip(p.choices, p.weights or [1.0] * len(p.choices), strict=True))
    choices = tuple(c for c in p.choices if c in keep)
    return Parameter(p.name, "choice", choices=choices,
                     weights=tuple(w[c] for c in choices) if p.weights else ())  # fmt: skip


def catalogue_only(space: DesignSpace) -> DesignSpace:
    """The space restricted to catalogue materials (no family): what can be bought today."""
    params = []
    for p in space.parameters:
        if p.name.endswith(".material") and p.kind == "choice":
            p = _restricted(p, {c for c in p.choices if not is_family(c)})
            if not p.choices:
                raise ValueError(f"{p.name}: the space has no catalogue material")
        params.append(p)
    return DesignSpace(tuple(params), space.materials)


#: the families a run searches and answers for besides the best design (``family_space``)
FAMILY_SEARCHES = ("gel", "foam")


def family_space(space: DesignSpace, family: str) -> DesignSpace | None:
    """The space restricted to one family's designs, None when the space has none: "gel",
    every layer a gel; "foam", a foam core under any other layers the space allows (no foam
    outside the core). A layer that cannot be of the family is left out by restricting the
    layer counts to those without it (a space whose skin is a catalogue material has one-layer
    gel designs)."""
    from sim.design import active_roles

    allowed: dict[str, tuple] = {}
    for p in space.parameters:
        if p.name.endswith(".material"):
            role = p.name.split(".")[0]
            choices = p.choices if p.kind == "choice" else (p.value,)
            if family == "gel" or (family == "foam" and role == "core"):
                keep = {family}
            else:
                keep = {c for c in choices if c != "foam"}
            allowed[role] = tuple(c for c in choices if c in keep)
    count = space["layers.count"]
    counts = count.choices if count.kind == "choice" else (count.value,)
    counts = tuple(c for c in counts if all(allowed.get(r) for r in active_roles(c)))
    if not counts:
        return None
    params = []
    for p in space.parameters:
        if p.name == "layers.count" and p.kind == "choice":
            p = _restricted(p, counts)
        elif p.name.endswith(".material") and p.kind == "choice":
            # a layer no design of the family uses keeps its choices
            p = _restricted(p, allowed[p.name.split(".")[0]] or p.choices)
        params.append(p)
    return DesignSpace(tuple(params), space.materials)


def design_family(point: dict[str, Any]) -> str:
    """The family a design belongs to: "gel" (every layer a gel), "foam" (a foam core),
    "catalogue" (catalogue materials only) or "mixed"."""
    from sim.design import active_roles

    mats = [point.get(f"{r}.material") for r in active_roles(point["layers.count"])]
    if all(m == "gel" for m in mats):
        return "gel"
    if mats[-1] == "foam" and "foam" not in mats[:-1]:
        return "foam"
    if not any(is_family(m) for m in mats):
        return "catalogue"
    return "mixed"


def complete_subspace(space: DesignSpace, trained: DesignSpace) -> DesignSpace:
    """``space`` with the parameters of ``trained`` that no design of it uses put back, in
    ``trained``'s order: a space file whose core is of the gel family only has no ``core.nu``
    (``sim.design.space`` keeps a family parameter only where a material choice uses it), but
    the surrogate's designs have it, inactive (NaN) where unused. Any other missing parameter is
    left missing, for :func:`check_subspace` to refuse."""
    from sim.design import PARAM_MATERIAL_KEYS, family_uses

    if set(space.names) == set(trained.names) or not set(space.names) <= set(trained.names):
        return space

    def unused(name: str) -> bool:
        role, _, key = name.partition(".")
        material = f"{role}.material"
        if key not in PARAM_MATERIAL_KEYS or material not in space.names:
            return False
        p = space[material]
        choices = p.choices if p.kind == "choice" else (p.value,)
        return not any(family_uses(c, key) for c in choices)

    names = set(space.names)
    params = [
        space[t.name] if t.name in names else t
        for t in trained.parameters
        if t.name in names or unused(t.name)
    ]
    return DesignSpace(tuple(params), space.materials)


def check_subspace(space: DesignSpace, trained: DesignSpace) -> None:
    """A search space must lie inside the surrogate's training space (same parameters, bounds
    within, choices a subset): a ``ValueError`` naming the first parameter that does not."""
    if space.names != trained.names:
        extra = sorted(set(space.names) ^ set(trained.names))
        raise ValueError(f"{extra[0]}: the surrogate was trained on other parameters")
    for p in space.parameters:
        t = trained[p.name]
        values = [p.value] if p.kind == "fixed" else list(p.choices) if p.kind == "choice" else []
        if values:
            pool = [t.value] if t.kind == "fixed" else list(t.choices) if t.kind == "choice" else []
            if t.kind == "float":
                ok = all(isinstance(v, int | float) and t.low <= v <= t.high for v in values)
            else:
                ok = all(v in pool for v in values)
        else:
            ok = t.kind == "float" and t.low <= p.low and p.high <= t.high
        if not ok:
            raise ValueError(f"{p.name}: outside the surrogate's training space {t.to_dict()}")


def suggest_point(trial, space: DesignSpace) -> dict[str, Any]:
    """A design point proposed by an Optuna trial, define-by-run: fixed parameters take their
    value, a layer's parameters are suggested only when the design uses them."""
    point: dict[str, Any] = {}
    for p in space.parameters:  # space order: the count and a layer's material come first
        if not space.is_active(p.name, point):
            continue
        if not p.sampled:
            point[p.name] = p.from_unit(0.0)
        elif p.kind == "choice":
            point[p.name] = trial.suggest_categorical(p.name, list(p.choices))
        else:
            point[p.name] = trial.suggest_float(p.name, p.low, p.high, log=p.log)
    return point_from_params(space, point)


# ----------------------------------------------------------------------------- scoring
def _scores(
    pred,
    targets: Targets,
    options=None,
    allow_untrusted: bool = False,
    points=None,
    space=None,
    trust_bound: bool = False,
):
    """(score, objectives, why-not-credible) of a surrogate ``Prediction``, vectorised: the
    closeness of the median prediction, plus the credibility penalty unless
    ``allow_untrusted`` (``explore._objective.infeasibility``, judged with the validity limits
    and tapping tolerances of ``options``, a ``SimOptions``, default the defaults; the largest
    strain of each layer of the predicted design ``points`` held to its material's limit, named
    in ``space``'s catalogue: ``explore._objective.point_layer_limits``; the design's largest
    strain to the largest of them where the surrogate does not predict the layers' own; with
    ``trust_bound`` on the interval's side towards each limit: ``_judged``)."""
    from sim.options import SimOptions

    from ._objective import point_layer_limits, wedge_reference_N

    options = SimOptions() if options is None else options
    catalogue = getattr(space, "catalogue", None)
    layer_limits = point_layer_limits(points or [], catalogue, options.validity)
    names = list(pred.metric_names)
    cols = {m: names.index(m) for m in names}
    point = pred.median
    metrics = {targets.metric(m): point[:, cols[targets.metric(m)]] for m in SCORED}
    metrics["wedge_peak_force_N"] = point[:, cols["wedge_peak_force_N"]]
    c = closeness(metrics, targets, wedge_reference_N=wedge_reference_N(options.dimension))
    obj = objectives(c)
    judged = _judged(pred, cols, trust_bound)
    penalty, why = infeasibility(
        judged, targets, options.validity, options.tapping, layer_limits=layer_limits
    )
    if allow_untrusted:
        return c.score, obj, why
    return c.score + penalty, obj + penalty[:, None], why


def predict_rows(
    surrogate,
    points: Sequence[dict[str, Any]],
    targets: Targets,
    *,
    round_: int = 0,
    trials: Sequence[int] | None = None,
    search: str = "continuous",
    max_disagreement: float = 0.10,
    options=None,
    allow_untrusted: bool = False,
    trust_bound: bool = False,
) -> list[TrialRow]:
    """Score design points with the surrogate: prediction, closeness and trust-guard flags.

    A design the surrogate predicts not credible (``explore._objective.infeasibility`` with the
    validity limits and tapping tolerances of ``options``, a ``SimOptions``, default the
    defaults) is flagged with the reason, and its score and objectives carry the penalty
    unless ``allow_untrusted``."""
    pred = surrogate.predict(list(points))
    names = list(pred.metric_names)
    cols = {m: names.index(m) for m in names}
    point = pred.median  # the robust point prediction (see surrogate.Prediction)
    space = getattr(surrogate, "space", None)
    scores, obj, why = _scores(
        pred, targets, options, allow_untrusted, list(points), space, trust_bound
    )
    scored = [targets.metric(m) for m in SCORED]
    with np.errstate(divide="ignore", invalid="ignore"):
        spread = np.stack(
            [pred.std[:, cols[m]] / np.abs(point[:, cols[m]]) for m in scored], axis=1
        )
    rows = []
    for i, point in enumerate(points):
        dis = float(np.nanmax(spread[i])) if np.isfinite(spread[i]).any() else math.inf
        flags = []
        if not pred.in_domain[i]:
            flags.append(f"out of domain: {pred.reasons[i]}")
        if not dis <= max_disagreement:
            flags.append(f"high disagreement {dis:.3f} > {max_disagreement:g}")
        if why[i]:
            flags.append(f"predicted not credible: {why[i]}")
        predicted = {
            m: {
                **{
                    k: finite_or_none(getattr(pred, k)[i, j])
                    for k in ("median", "mean", "std", "lower_90", "upper_90")
                },
                "by_rule": bool(pred.by_rule[i, j]),  # exact by physics, not learnt
            }
            for j, m in enumerate(names)
        }
        rows.append(
            TrialRow(
                round=round_,
                trial=-1 if trials is None else int(trials[i]),
                search=search,
                point=dict(point),
                score=float(scores[i]),
                objectives=tuple(float(v) for v in obj[i]),
                predicted=predicted,
                in_domain=bool(pred.in_domain[i]),
                disagreement=dis,
                flags=tuple(flags),
            )
        )
    return rows


# ----------------------------------------------------------------------------- studies
def point_from_params(space: DesignSpace, params: dict[str, Any]) -> dict[str, Any]:
    """The design point of a trial's parameters (fixed values filled, unused ones masked:
    ``DesignSpace.complete``)."""
    return space.complete(params)


def run_study(
    study,
    surrogate,
    space: DesignSpace,
    targets: Targets,
    settings: SearchSettings,
    *,
    round_: int,
    search: str,
    shared: bool = False,
    worker: str | None = None,
    progress: Callable[[int], None] | None = None,
    flush: int = 128,
) -> list[TrialRow]:
    """Run ``study`` (new or resumed) until it holds ``settings.trials`` finished trials besides
    its seeds and return its complete trials as ``TrialRow``s.

    The surrogate scores a batch of asked trials at once. By default (``shared=False``, the
    run folder's SQLite file, one writer) the sampler works on an in-memory twin of the study
    that starts from every stored trial, and finished trials are written to ``study`` every
    ``flush`` trials: the same sampling at a fraction of the cost of a database transaction
    per call; a kill loses at most the unwritten batch. ``shared=True`` (a database several
    workers share) asks and tells on ``study`` itself, so the workers see each other's trials,
    and each batch is sized by the trials the study still lacks, whoever made the others (the
    workers together overshoot by less than a batch per extra worker). ``worker`` names this
    worker in a shared study (its run folder: the same name when it is resumed): each trial it
    asks carries it (user attribute ``worker``), its sampler is seeded by (``settings.seed``,
    ``worker``) so that workers do not propose the same designs, the trials a kill left running
    are failed when it starts again (``abandoned``, not counted), and it seeds the study if it
    created it (``create_study``).

    Reproducible through kills (``shared=False``): each batch of ``settings.batch`` trials is
    asked from a sampler seeded by (``settings.seed``, number of trials before the batch), so
    the trials depend only on the trials before them, never on how many invocations made them.
    A resumed study restarts at the last whole batch it holds: the stored trials of a batch cut
    by a kill (Optuna writes trials one by one) are asked again, identical, and not stored
    twice. A resumed search therefore holds exactly the trials of an uninterrupted one.

    With ``settings.screen``, the study's first trials are the best designs of a quasi-random
    screen (``screen``), and ``settings.trials`` sampled trials follow them (``_seed``; in a
    shared study only the worker that created it adds them, so they are added once).
    ``progress`` is told of every trial this call adds to the study, the seeds included.
    """
    import optuna

    multi = settings.mode == "multi"
    states = (optuna.trial.TrialState.COMPLETE, optuna.trial.TrialState.FAIL)
    if shared and worker is not None:
        _abandon(study, worker)
        # a sampler of its own: workers seeded alike would propose the same designs
        study.sampler = _sampler(settings, _worker_seed(settings.seed, worker))
    stored = sorted(study.get_trials(deepcopy=False, states=states), key=lambda t: t.number)
    seeder = shared and worker is not None and study.user_attrs.get("seeder") == worker
    n_seeds = _seed(study, stored, surrogate, space, targets, settings, round_, search,
                    shared=shared, seeder=seeder)  # fmt: skip
    added = n_seeds - sum(_is_seed(t) for t in stored)
    if added > 0:  # seeds were added: read them back, and count them as work done
        stored = sorted(study.get_trials(deepcopy=False, states=states), key=lambda t: t.number)
        if progress is not None:
            progress(added)
    total = n_seeds + settings.trials
    if shared:
        target, done, n_stored = study, len(stored), None
    else:
        n_stored = len(stored)
        sampled = n_stored - n_seeds
        done = n_seeds + min(sampled - sampled % settings.batch, settings.trials)
        target = _twin(study, settings, stored[:done])
    pending: list = []
    while True:
        # a shared study: what it still lacks, counting the other workers' trials
        left = settings.trials - _sampled(study) if shared else total - done
        if left <= 0:
            break
        if not shared:  # a fresh sampler per batch, seeded by the trials before it
            target.sampler = _sampler(settings, _batch_seed(settings.seed, done))
        ask = target.ask if not shared or worker is None else lambda: _ask(study, worker)
        batch = [ask() for _ in range(min(settings.batch, left))]
        points = [suggest_point(t, space) for t in batch]
        rows = predict_rows(
            surrogate, points, targets, round_=round_, trials=[t.number for t in batch],
            search=search, max_disagreement=settings.max_disagreement,
            options=settings.options, allow_untrusted=settings.allow_untrusted,
            trust_bound=settings.trust_bound,
        )  # fmt: skip
        new = 0
        for t, row in zip(batch, rows, strict=True):
            values = list(row.objectives) if multi else [row.score]
            _store(t, row)
            if all(math.isfinite(v) for v in values):
                frozen = target.tell(t, values if multi else values[0])
            else:
                frozen = target.tell(t, state=optuna.trial.TrialState.FAIL)
            if n_stored is None or frozen.number >= n_stored:  # stored before a kill: kept
                pending.append(frozen)
                new += 1
        done += len(batch)
        if not shared and pending and (len(pending) >= flush or done >= total):
            study.add_trials(pending)
            pending = []
        if progress is not None and new:
            progress(new)
    return rows_of(study, surrogate, space, targets, round_=round_, search=search,
                   max_disagreement=settings.max_disagreement, options=settings.options,
                   allow_untrusted=settings.allow_untrusted,
                   trust_bound=settings.trust_bound)  # fmt: skip


def screen(
    surrogate, space: DesignSpace, targets: Targets, settings: SearchSettings, chunk: int = 16384
) -> list[dict[str, Any]]:
    """The ``settings.screen_keep`` best-scored points (``_scores``, lowest first) of a scrambled
    Sobol sample of ``settings.screen`` designs of ``space`` (seeded by ``settings.seed``),
    scored by the surrogate in batches of ``chunk``: what a sampler would need tens of thousands
    of trials to find, at the surrogate's own speed."""
    from scipy.stats import qmc

    d, n = len(space.sampled), settings.screen
    if n <= 0 or d == 0 or settings.screen_keep <= 0:
        return []
    unit = qmc.Sobol(d, scramble=True, seed=settings.seed).random_base2(math.ceil(math.log2(n)))
    unit = unit[:n]
    keep_scores: list[float] = []
    keep_points: list[dict[str, Any]] = []
    for start in range(0, n, chunk):
        points = space.points(unit[start : start + chunk])
        score, _, _ = _scores(surrogate.predict(points), targets, settings.options,
                              settings.allow_untrusted, points, space,
                              settings.trust_bound)  # fmt: skip
        score = np.where(np.isfinite(score), score, np.inf)
        best = np.argsort(score, kind="stable")[: settings.screen_keep]
        keep_scores += score[best].tolist()
        keep_points += [points[i] for i in best]
    order = np.argsort(keep_scores, kind="stable")[: settings.screen_keep]
    return [keep_points[i] for i in order if math.isfinite(keep_scores[i])]


def _is_seed(trial) -> bool:
    return trial.user_attrs.get("source") == "screen"


def _seed(
    study, stored, surrogate, space, targets, settings, round_, search, *, shared=False,
    seeder=False,
) -> int:  # fmt: skip
    """Seed ``study`` with the screen's best designs (``_seed_trials``) unless it holds sampled
    trials already, and return how many seeds it holds. The seeds are its first trials; a kill
    may have cut them, and the screen is deterministic, so the missing ones are added. A
    resumed study past its seeds is never screened again (the screen is the costly part).

    A shared study is seeded by its ``seeder`` alone (the worker that created it: one worker,
    so each seed is added once), whatever the other workers added meanwhile; the study records
    when its seeds are complete (user attribute ``seeds``)."""
    n_seeds = sum(_is_seed(t) for t in stored)
    keep = settings.screen_keep if settings.screen > 0 else 0
    if shared:
        if not seeder or keep == 0 or "seeds" in study.user_attrs:
            return n_seeds
        seeds = _seed_trials(surrogate, space, targets, settings, round_, search)
        study.add_trials(seeds[n_seeds:])  # the stored ones are the first (one writer)
        study.set_user_attr("seeds", len(seeds))
        return len(seeds)
    if n_seeds < len(stored) or n_seeds >= keep:
        return n_seeds
    seeds = _seed_trials(surrogate, space, targets, settings, round_, search)
    study.add_trials(seeds[n_seeds:])
    return len(seeds)


def _seed_trials(
    surrogate,
    space: DesignSpace,
    targets: Targets,
    settings: SearchSettings,
    round_: int,
    search: str,
) -> list:
    """The screen's best designs (``screen``) as finished Optuna trials, in score order, with
    the distributions ``suggest_point`` gives the same parameters (so the sampler learns from
    them) and the user attributes every trial carries, plus ``source = "screen"``."""
    import optuna

    points = screen(surrogate, space, targets, settings)
    if not points:
        return []
    rows = predict_rows(
        surrogate, points, targets, round_=round_, search=search,
        max_disagreement=settings.max_disagreement, options=settings.options,
        allow_untrusted=settings.allow_untrusted, trust_bound=settings.trust_bound,
    )  # fmt: skip
    trials = []
    for row in rows:
        params, dists = {}, {}
        for p in space.sampled:
            v = row.point[p.name]
            if v == "" or (isinstance(v, float) and math.isnan(v)):
                continue  # unused by this design: never suggested either
            params[p.name] = v
            dists[p.name] = (
                optuna.distributions.CategoricalDistribution(list(p.choices))
                if p.kind == "choice"
                else optuna.distributions.FloatDistribution(p.low, p.high, log=p.log)
            )
        trial = optuna.trial.create_trial(
            params=params,
            distributions=dists,
            values=list(row.objectives) if settings.mode == "multi" else [row.score],
            user_attrs={"source": "screen"},
        )
        _store(trial, row)
        trials.append(trial)
    return trials


def _batch_seed(seed: int, done: int) -> int:
    """The sampler seed of the batch that starts after ``done`` trials (``seed`` itself for the
    first batch)."""
    if done == 0:
        return seed
    return int(np.random.SeedSequence([seed, done]).generate_state(1)[0])


def _worker_seed(seed: int, worker: str) -> int:
    """The sampler seed of ``worker`` in a shared study (``seed`` and the worker's name)."""
    name = int.from_bytes(hashlib.sha256(worker.encode()).digest()[:8], "little")
    return int(np.random.SeedSequence([seed, name]).generate_state(1)[0])


def _twin(study, settings: SearchSettings, trials: Sequence | None = None):
    """An in-memory study with the same sampler and directions, holding ``trials`` (default:
    every finished trial of ``study``)."""
    import optuna

    twin = create_study(None, study.study_name, settings)
    if trials is None:
        finished = (optuna.trial.TrialState.COMPLETE, optuna.trial.TrialState.FAIL)
        trials = study.get_trials(deepcopy=False, states=finished)
    twin.add_trials(trials)
    return twin


def _finished(study) -> int:
    import optuna

    states = (optuna.trial.TrialState.COMPLETE, optuna.trial.TrialState.FAIL)
    return len(study.get_trials(deepcopy=False, states=states))


def _ask(study, worker: str):
    """``study.ask()``, the new trial carrying ``worker`` (user attribute) from its creation: one
    transaction, so a kill never leaves a running trial without its worker's name."""
    import optuna

    template = optuna.trial.create_trial(
        state=optuna.trial.TrialState.RUNNING, user_attrs={"worker": worker}
    )
    study._thread_local.cached_all_trials = None  # as Study.ask: the sampler reads every trial
    return optuna.Trial(study, study._storage.create_new_trial(study._study_id, template))


def _sampled(study) -> int:
    """Finished trials of ``study`` besides its seeds and the abandoned ones (``_abandon``)."""
    import optuna

    states = (optuna.trial.TrialState.COMPLETE, optuna.trial.TrialState.FAIL)
    trials = study.get_trials(deepcopy=False, states=states)
    return sum(not _is_seed(t) and not t.user_attrs.get("abandoned") for t in trials)


def _abandon(study, worker: str) -> int:
    """Fail the trials ``worker`` left running in ``study`` (a kill cut its batch), marked
    ``abandoned``; returns how many."""
    import optuna

    running = study.get_trials(deepcopy=False, states=(optuna.trial.TrialState.RUNNING,))
    mine = [t for t in running if t.user_attrs.get("worker") == worker]
    for t in mine:
        optuna.trial.Trial(study, t._trial_id).set_user_attr("abandoned", True)
        study.tell(t.number, state=optuna.trial.TrialState.FAIL)
    return len(mine)


def _store(trial, row: TrialRow) -> None:
    """What the dashboard shows beside the parameters (the full prediction is reproducible
    from the checkpoint and is re-computed by ``rows_of``)."""
    trial.set_user_attr("score", row.score if math.isfinite(row.score) else None)
    trial.set_user_attr("trusted", not row.flags)
    for name, v in zip(OBJECTIVE_NAMES, row.objectives, strict=True):
        trial.set_user_attr(name, v if math.isfinite(v) else None)


def rows_of(
    study,
    surrogate,
    space: DesignSpace,
    targets: Targets,
    *,
    round_: int,
    search: str,
    max_disagreement: float = 0.10,
    options=None,
    allow_untrusted: bool = False,
    trust_bound: bool = False,
) -> list[TrialRow]:
    """The complete trials of ``study`` as ``TrialRow``s, re-scored by ``surrogate``."""
    import optuna

    trials = study.get_trials(deepcopy=False, states=(optuna.trial.TrialState.COMPLETE,))
    if not trials:
        return []
    points = [point_from_params(space, t.params) for t in trials]
    return predict_rows(
        surrogate, points, targets, round_=round_, trials=[t.number for t in trials],
        search=search, max_disagreement=max_disagreement, options=options,
        allow_untrusted=allow_untrusted, trust_bound=trust_bound,
    )  # fmt: skip


def _sampler(settings: SearchSettings, seed: int):
    """The seeded sampler of a study: TPE (multivariate, grouped for the conditional space) for
    one objective, NSGA-II for three."""
    import optuna

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", optuna.exceptions.ExperimentalWarning)
        if settings.mode == "multi":
            return optuna.samplers.NSGAIISampler(seed=seed)
        return optuna.samplers.TPESampler(
            seed=seed, multivariate=True, group=True, n_startup_trials=64
        )


def create_study(storage, name: str, settings: SearchSettings, worker: str | None = None):
    """A new or resumed study with a seeded sampler (``_sampler``). Resuming an existing study
    writes nothing to its storage (a finished run re-run leaves its files as they are).

    ``worker`` (a shared storage): when this call creates the study, it records ``worker`` as
    the one that seeds it (user attribute ``seeder``, read by ``run_study``). The database's
    unique study name makes creation atomic: of workers starting together, one creates the
    study, the others load it."""
    import optuna

    optuna.logging.set_verbosity(optuna.logging.WARNING)
    sampler = _sampler(settings, settings.seed)
    directions = ["minimize"] * (3 if settings.mode == "multi" else 1)
    study = None
    if storage is not None:
        try:
            study = optuna.load_study(study_name=name, storage=storage, sampler=sampler)
        except KeyError:  # no such study yet
            study = None
    if study is None:
        try:
            study = optuna.create_study(
                storage=storage, study_name=name, sampler=sampler, directions=directions
            )
        except optuna.exceptions.DuplicatedStudyError:  # another worker has just made it
            study = optuna.load_study(study_name=name, storage=storage, sampler=sampler)
        else:
            if worker is not None:
                study.set_user_attr("seeder", worker)
    if settings.mode == "multi" and study.metric_names != list(OBJECTIVE_NAMES):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", optuna.exceptions.ExperimentalWarning)
            study.set_metric_names(list(OBJECTIVE_NAMES))
    return study


# ----------------------------------------------------------------------------- selection
def select_candidates(
    rows: Sequence[TrialRow],
    features: Callable[[list[dict[str, Any]]], np.ndarray],
    *,
    best: int,
    uncertain: int,
    exclude: Sequence[dict[str, Any]] = (),
    min_distance: float = 0.05,
    reason_best: str = "best",
) -> list[Candidate]:
    """The ``best`` trusted designs with the lowest predicted score that are distinct (encoded
    distance per feature >= ``min_distance`` from each other and from ``exclude``, designs
    already confirmed), then ``uncertain`` flagged-but-promising ones (within the best 10 % of
    scores, the most disagreeing first). When fewer than ``best`` designs are trusted, the
    best-scored flagged designs take the free slots (as "uncertain")."""
    finite = [r for r in rows if math.isfinite(r.score)]
    if not finite:
        return []
    order = sorted(finite, key=lambda r: r.score)
    chosen: list[Candidate] = []
    taken = [features([p])[0] for p in exclude]

    def distinct(r: TrialRow) -> bool:
        x = features([r.point])[0]
        if all(np.linalg.norm(x - y) / math.sqrt(len(x)) >= min_distance for y in taken):
            taken.append(x)
            return True
        return False

    for r in order:
        if len(chosen) >= best:
            break
        if not r.flags and distinct(r):
            chosen.append(r.candidate(reason_best))
    # the guard flagged the rest: promising ones go to FE on purpose (FE decides), and they
    # also fill the best slots no trusted design could take
    n_unc = uncertain + best - len(chosen)
    cutoff = np.quantile([r.score for r in finite], 0.10)
    flagged = [r for r in order if r.flags]
    promising = sorted((r for r in flagged if r.score <= cutoff), key=lambda r: -r.disagreement)
    if best > len(chosen):  # no trusted design to fill them: the best flagged ones first
        promising = flagged
    taken_unc = 0
    for r in promising:
        if taken_unc >= n_unc:
            break
        if distinct(r):
            chosen.append(r.candidate("uncertain"))
            taken_unc += 1
    return chosen
