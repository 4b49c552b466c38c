"""Design-space figures of a search run (the run-folder contract is in ``explore._run_folder``).

As in Optuna's visualization modules, every figure is made in two steps: a pure function
computes a small frozen "info" object from the run folder's data (numbers only, no
matplotlib; this is what the tests check), and a separate ``render_*`` function draws the info
on a matplotlib ``Figure`` (Agg canvas, no pyplot state). ``write_figures`` does both for every
figure and saves ``figures/<name>.png``.

Units: displacements and distances in mm, forces in N, hysteresis in N mm, time in s; the
score and the three objectives (compliance error, hysteresis error, wedge effort) are
dimensionless (``explore._objective``).
"""

from __future__ import annotations

import io
import itertools
import math
import warnings
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from matplotlib import colormaps
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.collections import LineCollection
from matplotlib.colors import ListedColormap, LogNorm, Normalize
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.ticker import FormatStrFormatter, LogLocator, NullFormatter

from sim.design import READINGS, Targets, load_targets, loading_curve
from sim.options import SimOptions
from sim.protocols import shown_hysteresis
from sim.provenance import write_if_changed

from ._objective import TAPPING, closeness, objectives, wedge_reference_N
from ._run_folder import (
    CONFIG,
    OBJECTIVE_NAMES,
    read_confirmations,
    read_json,
    read_studies,
    read_summary,
    read_trials,
)
from ._types import Confirmation

__all__ = [
    "ANSWER_NAMES",
    "FIGURES",
    "LOG_RATIO",
    "LOG_TICKS_PER_DECADE",
    "OBJECTIVE_NAMES",
    "Curve",
    "ImportanceInfo",
    "LogAxis",
    "LoopsInfo",
    "PairProjection",
    "ParallelInfo",
    "ParetoInfo",
    "ParityInfo",
    "ParityMetric",
    "ProjectionsInfo",
    "RunData",
    "WedgeInfo",
    "importance_info",
    "load_run",
    "log_axis",
    "log_ticks",
    "loops_info",
    "parallel_info",
    "pareto_front_indices",
    "pareto_info",
    "parity_info",
    "projections_info",
    "render_importance",
    "render_loops",
    "render_parallel",
    "render_pareto",
    "render_parity",
    "render_projections",
    "render_wedge",
    "run_options",
    "run_targets",
    "spread_labels",
    "wedge_info",
    "write_figures",
]

#: figure name (``figures/<name>.png``) -> one-line caption, in report order
FIGURES: dict[str, str] = {
    "loops": "Tapping loops (force against displacement) of the run's answers (best credible, "
    "gel, foam, buildable) and the paper's materials, against the human finger's loading curve.",
    "wedge": "Wedge indentation of the run's answers and the paper's materials: force over time, "
    "and the surface profiles after 1 s and 100 s.",
    "parity": "Surrogate prediction (median, 90 % interval) against the FE confirmation.",
    "pareto": "Trade-off between the three objectives over all trials; the non-dominated set "
    "is highlighted and the FE-confirmed designs are starred.",
    "importance": "Which design parameters matter most for the score (Optuna, continuous search).",
    "projections": "Pairwise projections of the most important parameters, coloured by score.",
    "parallel": "Parallel coordinates of the numeric parameters: every trial in grey, the best "
    "10 % on top, coloured by score.",
}
_DPI = 110
_UNITS = {
    "disp_at_1N_mm": "mm",
    "disp_at_4N_mm": "mm",
    "disp_at_1N_from_touch_mm": "mm",
    "disp_at_4N_from_touch_mm": "mm",
    "hysteresis_Nmm": "N mm",
    "wedge_peak_force_N": "N",
}


def _ro(values: Iterable[float] | np.ndarray) -> np.ndarray:
    """A read-only float array (the info objects are frozen, their arrays too)."""
    out = np.array(values, dtype=float)
    out.flags.writeable = False
    return out


# ---------------------------------------------------------------------------------------------
# Run-folder data
# ---------------------------------------------------------------------------------------------


@dataclass(frozen=True, eq=False)
class RunData:
    """Everything the figures read from a run folder (missing optional files: empty fields).

    ``trials``: the ``trials.csv`` columns, header order; numeric columns are float arrays
    (empty cell = inactive/missing -> NaN), the others arrays of str. ``params``: the
    design-space parameter columns (``explore._run_folder.parameter_columns``).
    ``records`` / ``references``: FE records (``curves``, ``metrics``) by confirmation key (the
    answers' records too, by the stem of their ``fe_record``) / by reference name (file stem).
    ``summary`` and ``config``: the parsed JSON ({} if absent); ``studies``: the rounds' Optuna
    studies (``explore._run_folder.read_studies``).
    """

    run_dir: Path
    trials: dict[str, np.ndarray] = field(default_factory=dict)
    params: tuple[str, ...] = ()
    confirmations: tuple[Confirmation, ...] = ()
    records: dict[str, dict[str, Any]] = field(default_factory=dict)
    references: dict[str, dict[str, Any]] = field(default_factory=dict)
    summary: dict[str, Any] = field(default_factory=dict)
    config: dict[str, Any] = field(default_factory=dict)
    studies: tuple[dict[str, Any], ...] = ()

    @property
    def n_trials(self) -> int:
        """Number of rows of trials.csv."""
        return len(next(iter(self.trials.values()))) if self.trials else 0

    @property
    def numeric_params(self) -> tuple[str, ...]:
        """The parameters whose every active value is a number (categoricals left out)."""
        return tuple(p for p in self.params if self.trials[p].dtype.kind == "f")

    def column(self, name: str) -> np.ndarray:
        """A numeric column of trials.csv (all NaN when absent or not numeric)."""
        col = self.trials.get(name)
        if col is None or col.dtype.kind != "f":
            return np.full(self.n_trials, np.nan)
        return col


def _read_folder(folder: Path) -> dict[str, dict[str, Any]]:
    if not folder.is_dir():
        return {}
    return {p.stem: read_json(p) for p in sorted(folder.glob("*.json"))}


def load_run(run_dir: str | Path) -> RunData:
    """Read a run folder: trials.csv, confirmations.json, the FE records of the confirmations,
    the references, summary.json, config.json and studies.json. Any of them may be missing."""
    run_dir = Path(run_dir)
    trials, params = read_trials(run_dir)
    confirmations = read_confirmations(run_dir)
    records = {}
    for c in confirmations:
        path = run_dir / "fe" / "records" / f"{c.key}.json"
        if path.is_file():
            records[c.key] = read_json(path)
    summary = read_summary(run_dir)
    for answer in (summary.get("answers") or {}).values():
        key = _answer_key(answer)  # an answer of the FE-only screen is no confirmation
        path = run_dir / "fe" / "records" / f"{key}.json"
        if key is not None and key not in records and path.is_file():
            records[key] = read_json(path)
    config_path = run_dir / CONFIG
    return RunData(
        run_dir=run_dir,
        trials=trials,
        params=params,
        confirmations=confirmations,
        records=records,
        references=_read_folder(run_dir / "fe" / "references"),
        summary=summary,
        config=read_json(config_path) if config_path.is_file() else {},
        studies=tuple(read_studies(run_dir)),
    )


def _answer_key(answer: Any) -> str | None:
    """The FE record key of a summary answer (``fe_record`` "fe/records/<key>.json")."""
    ref = answer.get("fe_record") if isinstance(answer, Mapping) else None
    return Path(ref).stem if isinstance(ref, str) and ref.endswith(".json") else None


def run_targets(run: RunData) -> Targets | None:
    """The run's targets (``config["targets"]``, else ``summary["targets"]``); None if absent.

    A ``displacement_reading`` entry (in the targets, or beside them in config.json) selects the
    reading (default: from the undeformed top); ``max_sag_mm`` beside them, the sag limit."""
    raw = run.config.get("targets") or run.summary.get("targets") or {}
    values = {k: float(raw[k]) for k in TAPPING if isinstance(raw.get(k), int | float)}
    if len(values) < len(TAPPING):
        return None
    reading = raw.get("displacement_reading", run.config.get("displacement_reading"))
    reading = reading if reading in READINGS else "from_undeformed_top"
    sag = run.config.get("max_sag_mm")
    return Targets(
        values=values, reading=reading, max_sag_mm=sag if isinstance(sag, int | float) else None
    )


def run_options(run: RunData) -> SimOptions:
    """The simulation options the run's FE used (``config["sim_options"]``; default ones in a
    folder that does not record them)."""
    from sim.options import options_from_dict

    recorded = run.config.get("sim_options")
    return options_from_dict(recorded) if isinstance(recorded, Mapping) else SimOptions()


def _finite_score_mask(run: RunData) -> np.ndarray:
    return np.isfinite(run.column("score"))


#: a positive parameter spanning at least this ratio is shown on a log scale (mu0, tau)
LOG_RATIO = 20.0


def _log_scale(values: np.ndarray) -> bool:
    """True if the active values are positive and span >= ``LOG_RATIO`` (e.g. moduli)."""
    v = values[np.isfinite(values)]
    return bool(len(v) >= 2 and v.min() > 0 and v.max() >= LOG_RATIO * v.min())


#: labelled ticks per decade on a log axis, at most: 1, 2 and 5 x 10^k at the densest
LOG_TICKS_PER_DECADE = 3
#: labelled ticks on a log axis, at most (sparser mantissas, then every n-th decade, beyond)
_MAX_LOG_TICKS = 6
_MANTISSAS = ((1, 2, 5), (1, 3), (1,))


@dataclass(frozen=True)
class LogAxis:
    """A log-scaled axis as drawn: ``limits`` (the values' range widened by 5 % of its decades
    on each side), the labelled ``ticks`` inside them (``log_ticks``) and their ``labels``
    (plain numbers; powers of ten as 10^k outside 1e-4 to 1e5). Minor ticks carry no label."""

    limits: tuple[float, float]
    ticks: tuple[float, ...]
    labels: tuple[str, ...]


def _decimal(mantissa: int, exponent: int) -> float:
    """mantissa x 10^exponent as the float of its decimal text (2e-3 is 0.002 exactly)."""
    return float(f"{mantissa}e{exponent}")


def log_ticks(low: float, high: float, max_ticks: int = _MAX_LOG_TICKS) -> tuple[float, ...]:
    """Labelled tick values for a log axis over [``low``, ``high``] (both > 0): the densest of
    1-2-5, 1-3 and 1 x 10^k (then every 2nd, 3rd, ... decade) with at most ``max_ticks``
    values, so never more than ``LOG_TICKS_PER_DECADE`` in a decade. A range too narrow for two
    of them (less than a factor 2.5) gets up to three of 1..9 x 10^k, else its rounded middle."""
    lo_e, hi_e = math.floor(math.log10(low)), math.ceil(math.log10(high))

    def inside(mantissas: Iterable[int], step: int) -> list[float]:
        out = [_decimal(m, e) for e in range(lo_e, hi_e + 1) if e % step == 0 for m in mantissas]
        return [v for v in out if low <= v <= high]

    ticks: list[float] = []
    for step in (1, 2, 3, 5, 10, 20, 50, 100):
        for mantissas in _MANTISSAS if step == 1 else ((1,),):
            ticks = inside(mantissas, step)
            if len(ticks) <= max_ticks:
                break
        if len(ticks) <= max_ticks:
            break
    if len(ticks) < 2:
        fine = inside(range(1, 10), 1)
        ticks = fine[:: math.ceil(len(fine) / LOG_TICKS_PER_DECADE)] if len(fine) >= 2 else []
    if not ticks:
        ticks = [float(f"{math.sqrt(low * high):.2g}")]
    return tuple(ticks)


def _tick_labels(ticks: Sequence[float]) -> tuple[str, ...]:
    """Plain numbers when every tick is in [1e-4, 1e5), else all as m x 10^k (mathtext)."""
    if all(1e-4 <= t < 1e5 for t in ticks):
        return tuple(f"{t:g}" for t in ticks)
    out = []
    for t in ticks:
        exponent = math.floor(math.log10(t) + 1e-9)
        mantissa = t / 10.0**exponent
        head = "" if round(mantissa, 6) == 1 else f"{mantissa:.2g}\\times"
        out.append(f"${head}10^{{{exponent}}}$")
    return tuple(out)


def log_axis(values: Iterable[float] | np.ndarray, pad: float = 0.05) -> LogAxis | None:
    """The log axis of ``values`` (their positive finite ones; None if there are none): limits
    widened by ``pad`` x the decades spanned on each side (0.1 decade for a single value), and
    the ticks of ``log_ticks`` inside the limits."""
    v = np.asarray(values if isinstance(values, np.ndarray) else list(values), dtype=float)
    v = v[np.isfinite(v) & (v > 0)]
    if len(v) == 0:
        return None
    lo, hi = math.log10(float(v.min())), math.log10(float(v.max()))
    margin = pad * (hi - lo) if hi > lo else 0.1
    limits = (10.0 ** (lo - margin), 10.0 ** (hi + margin))
    ticks = log_ticks(*limits)
    return LogAxis(limits, ticks, _tick_labels(ticks))


# ---------------------------------------------------------------------------------------------
# 4. Importance (first: the projections use it)
# ---------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class ImportanceInfo:
    """Optuna parameter importances for the score (sum 1), most important first.

    Empty ``names`` when the study could not be loaded or has < 2 complete scored trials;
    ``message`` then says why."""

    names: tuple[str, ...]
    importances: tuple[float, ...]
    study_name: str = ""
    n_trials: int = 0
    message: str = ""

    @property
    def empty(self) -> bool:
        return not self.names


def _storage_urls(run: RunData) -> list[str]:
    """The configured storage, then the run folder's journal and its older study.db; files
    must exist (loading a missing one would create an empty storage)."""
    from ._storage import JOURNAL_NAME, storage_file

    urls = []
    configured = run.config.get("storage")
    if isinstance(configured, str):
        urls.append(configured)
    urls += [str(run.run_dir / JOURNAL_NAME), f"sqlite:///{run.run_dir / 'study.db'}"]
    out = []
    for url in urls:
        path = storage_file(url)
        if path is None or path.is_file():
            out.append(url)
    return out


def _continuous_study_name(run: RunData) -> str | None:
    for study in run.studies:
        if isinstance(study, Mapping) and study.get("search") == "continuous":
            return study.get("name")
    return None


def _load_study(run: RunData) -> Any | None:
    import optuna

    name = _continuous_study_name(run)
    if name is None:
        return None
    from ._storage import open_storage

    for url in _storage_urls(run):
        try:
            return optuna.load_study(study_name=name, storage=open_storage(url))
        except Exception:  # a missing or foreign storage just means "no study"
            continue
    return None


def _score_of(trial: Any) -> float:
    value = trial.user_attrs.get("score")
    return float(value) if isinstance(value, int | float) else math.inf


def _ranked(importances: Mapping[str, float]) -> list[tuple[str, float]]:
    """(name, importance), most important first; ties by name. Optuna returns tied parameters
    (those that never vary among the best trials) in an order that follows string hashing,
    which changes from one process to the next: a re-run would redraw the figure."""
    return sorted(importances.items(), key=lambda kv: (-kv[1], kv[0]))


def importance_info(run: RunData) -> ImportanceInfo:
    """Parameter importances of the score in the first continuous study (Optuna's default
    evaluator, PED-ANOVA, which draws nothing at random; target ``trial.user_attrs["score"]``;
    trials without a finite score ignored)."""
    import optuna

    study = _load_study(run)
    if study is None:
        return ImportanceInfo((), (), message="the study could not be loaded")
    complete = study.get_trials(deepcopy=False, states=(optuna.trial.TrialState.COMPLETE,))
    n = sum(math.isfinite(_score_of(t)) for t in complete)
    if n < 2:
        return ImportanceInfo((), (), study.study_name, n, "not enough trials")
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            imp = optuna.importance.get_param_importances(study, target=_score_of)
    except (ValueError, RuntimeError) as exc:  # e.g. no parameter varies
        return ImportanceInfo((), (), study.study_name, n, f"importance failed: {exc}")
    ordered = _ranked(imp)
    return ImportanceInfo(
        tuple(k for k, _ in ordered), tuple(float(v) for _, v in ordered), study.study_name, n
    )


# ---------------------------------------------------------------------------------------------
# 1. Pairwise projections
# ---------------------------------------------------------------------------------------------


@dataclass(frozen=True, eq=False)
class PairProjection:
    """One projection: trials with both parameters active and a finite score (``x``, ``y`` in
    the parameters' units, ``score`` for the colour), and the coordinates of the confirmed
    designs with FE status ok (NaN where inactive); ``x_log``/``y_log``: the axis spans
    decades (log scale), drawn as ``x_axis``/``y_axis`` (limits and labelled ticks; None on a
    linear axis)."""

    x_name: str
    y_name: str
    x: np.ndarray
    y: np.ndarray
    score: np.ndarray
    confirmed_x: np.ndarray
    confirmed_y: np.ndarray
    x_log: bool = False
    y_log: bool = False
    x_axis: LogAxis | None = None
    y_axis: LogAxis | None = None


@dataclass(frozen=True)
class ProjectionsInfo:
    """Pairwise projections of ``params`` (most important first); ``pairs`` holds every pair
    (i < j) in order; ``ranked_by`` is "importance" or "variation"; ``score_axis``: the (log)
    colour scale of the score, from the lowest score to the median one (``_score_range``),
    with its labelled ticks (None: no positive score)."""

    params: tuple[str, ...]
    pairs: tuple[PairProjection, ...]
    ranked_by: str = "importance"
    score_axis: LogAxis | None = None

    @property
    def score_norm(self) -> Normalize:
        """The colour scale of the score: log over ``score_axis.limits`` (the lowest score to
        the median; worse trials get the end colour)."""
        if self.score_axis is None:
            return Normalize(0.0, 1.0)
        return LogNorm(*self.score_axis.limits)

    @property
    def empty(self) -> bool:
        return not self.pairs


def _variation(values: np.ndarray) -> float:
    """Spread of a column: std of its min-max normalised active values x active fraction."""
    v = values[np.isfinite(values)]
    if len(v) < 2 or v.max() == v.min():
        return 0.0
    return float(np.std((v - v.min()) / (v.max() - v.min())) * len(v) / len(values))


def _top_params(
    run: RunData, top: int, importance: ImportanceInfo | None
) -> tuple[tuple[str, ...], str]:
    ok = _finite_score_mask(run)
    usable = [p for p in run.numeric_params if np.isfinite(run.trials[p][ok]).sum() >= 2]
    chosen = [n for n in (importance.names if importance else ()) if n in usable][:top]
    ranked_by = "importance" if chosen else "variation"
    rest = sorted(
        (p for p in usable if p not in chosen), key=lambda p: -_variation(run.trials[p][ok])
    )
    return tuple((chosen + rest)[:top]), ranked_by


def _confirmed_coordinate(run: RunData, name: str) -> np.ndarray:
    """Parameter ``name`` of the confirmed designs with FE status ok (NaN if inactive)."""
    out = []
    for c in run.confirmations:
        if c.status != "ok":
            continue
        v = c.candidate.point.get(name)
        out.append(float(v) if isinstance(v, int | float) and not isinstance(v, bool) else np.nan)
    return _ro(out)


def projections_info(
    run: RunData, top: int = 5, importance: ImportanceInfo | None = None
) -> ProjectionsInfo:
    """Pairwise projections of the ``top`` numeric parameters with the largest importance
    (``importance``, computed when None; topped up by the most varied parameters), points
    coloured by score (trials with an infinite score left out), confirmed designs marked."""
    if importance is None:
        importance = importance_info(run)
    params, ranked_by = _top_params(run, top, importance)
    ok = _finite_score_mask(run)
    score = run.column("score")
    pairs = []
    for a, b in itertools.combinations(params, 2):
        x, y = run.trials[a], run.trials[b]
        sel = ok & np.isfinite(x) & np.isfinite(y)
        cx, cy = _confirmed_coordinate(run, a), _confirmed_coordinate(run, b)
        x_log, y_log = _log_scale(x[ok]), _log_scale(y[ok])
        pairs.append(
            PairProjection(
                a,
                b,
                _ro(x[sel]),
                _ro(y[sel]),
                _ro(score[sel]),
                cx,
                cy,
                x_log,
                y_log,
                log_axis(np.concatenate([x[sel], cx])) if x_log else None,
                log_axis(np.concatenate([y[sel], cy])) if y_log else None,
            )
        )
    limits = _score_range(score[ok])
    score_axis = log_axis(limits, pad=0.0) if limits and params else None
    return ProjectionsInfo(params, tuple(pairs), ranked_by, score_axis)


# ---------------------------------------------------------------------------------------------
# 2. Pareto front
# ---------------------------------------------------------------------------------------------


def pareto_front_indices(points: np.ndarray, chunk: int = 1024) -> np.ndarray:
    """Indices (ascending) of the non-dominated rows of ``points`` (n, k), all minimised.

    Row j dominates row i if it is <= in every column and < in at least one; equal rows do
    not dominate each other. Memory is bounded by ``chunk`` x n x k booleans."""
    p = np.asarray(points, dtype=float)
    if p.ndim != 2 or len(p) == 0:
        return np.zeros(0, dtype=int)
    dominated = np.zeros(len(p), dtype=bool)
    for start in range(0, len(p), chunk):
        block = p[start : start + chunk]  # candidates i
        le = np.all(p[:, None, :] <= block[None, :, :], axis=-1)  # [j, i]: p_j <= p_i
        lt = np.any(p[:, None, :] < block[None, :, :], axis=-1)
        dominated[start : start + len(block)] = np.any(le & lt, axis=0)
    return np.flatnonzero(~dominated)


@dataclass(frozen=True, eq=False)
class ParetoInfo:
    """The objectives (``OBJECTIVE_NAMES``, dimensionless) of every trial with three finite
    values: ``points`` (n, 3) with their trials.csv row ``rows``; ``front``: indices into
    ``points`` of the non-dominated set (all minimised); ``confirmed``: the FE objectives
    (m, 3) of the confirmed designs (status ok, finite), labelled by ``confirmed_labels``;
    ``x_axis``/``y_axis``: the log axes of the first two objectives (limits, labelled ticks),
    None (linear axes) unless every point's two are positive."""

    points: np.ndarray
    rows: np.ndarray
    front: np.ndarray
    confirmed: np.ndarray
    confirmed_labels: tuple[str, ...]
    x_axis: LogAxis | None = None
    y_axis: LogAxis | None = None

    @property
    def empty(self) -> bool:
        return len(self.points) == 0 and len(self.confirmed) == 0


def _label(c: Confirmation) -> str:
    return f"{c.candidate.reason} r{c.candidate.round}/t{c.candidate.trial}"


def _confirmed_objectives(run: RunData) -> tuple[np.ndarray, tuple[str, ...]]:
    targets = run_targets(run)
    rows: list[np.ndarray] = []
    labels: list[str] = []
    if targets is not None:
        reference = wedge_reference_N(run_options(run).dimension)
        for c in run.confirmations:
            if c.status != "ok":
                continue
            obj = objectives(closeness(c.fe_metrics, targets, wedge_reference_N=reference))
            if np.all(np.isfinite(obj)):
                rows.append(obj)
                labels.append(_label(c))
    return (np.array(rows, dtype=float) if rows else np.zeros((0, 3))), tuple(labels)


def pareto_info(run: RunData) -> ParetoInfo:
    """The non-dominated set of (compliance error, hysteresis error, wedge effort) over all
    trials with finite values, and the confirmed designs' FE objectives (recomputed with
    ``explore._objective`` from their FE metrics and the run's targets)."""
    if run.n_trials:
        table = np.column_stack([run.column(n) for n in OBJECTIVE_NAMES])
    else:
        table = np.zeros((0, 3))
    rows = np.flatnonzero(np.all(np.isfinite(table), axis=1))
    points = table[rows]
    confirmed, labels = _confirmed_objectives(run)
    front = pareto_front_indices(points)
    rows.flags.writeable = front.flags.writeable = False
    every = np.vstack([points, confirmed])
    x_axis = y_axis = None
    if len(every) and np.all(every[:, :2] > 0):
        x_axis, y_axis = log_axis(every[:, 0]), log_axis(every[:, 1])
    return ParetoInfo(_ro(points), rows, front, _ro(confirmed), labels, x_axis, y_axis)


# ---------------------------------------------------------------------------------------------
# 3. Parallel coordinates
# ---------------------------------------------------------------------------------------------


@dataclass(frozen=True, eq=False)
class ParallelInfo:
    """Parallel coordinates of the trials with a finite score: ``values`` (n, p) is each
    numeric parameter min-max normalised to [0, 1] over those trials (0.5 if constant, NaN if
    inactive); ``low``/``high`` the observed range (parameter units); ``log``: the parameter
    spans decades and is normalised as log(x / low) / log(high / low); ``score`` of each
    trial; ``best`` marks the best ``best_fraction`` (at least one) by score, the trials drawn
    on top in a colour ramp of their score (the others grey, behind)."""

    params: tuple[str, ...]
    values: np.ndarray
    low: np.ndarray
    high: np.ndarray
    log: np.ndarray
    score: np.ndarray
    best: np.ndarray
    best_fraction: float = 0.1

    @property
    def empty(self) -> bool:
        return len(self.params) == 0 or len(self.score) == 0

    @property
    def best_order(self) -> np.ndarray:
        """Rows of the best trials, worst of them first (the drawing order: the best on top)."""
        rows = np.flatnonzero(self.best)
        return rows[np.argsort(-self.score[rows], kind="stable")]


def _normalise(column: np.ndarray, log: bool) -> tuple[np.ndarray, float, float]:
    """Min-max normalised column (of log10 values if ``log``), its min and max (own units)."""
    finite = column[np.isfinite(column)]
    if len(finite) == 0:
        return np.full(len(column), np.nan), np.nan, np.nan
    lo, hi = float(finite.min()), float(finite.max())
    if hi == lo:
        return np.where(np.isfinite(column), 0.5, np.nan), lo, hi
    if log:
        return np.log(column / lo) / np.log(hi / lo), lo, hi
    return (column - lo) / (hi - lo), lo, hi


def parallel_info(run: RunData, best_fraction: float = 0.1) -> ParallelInfo:
    """Parallel coordinates of every numeric parameter over the trials with a finite score,
    coloured by score, the best ``best_fraction`` highlighted."""
    ok = _finite_score_mask(run)
    score = run.column("score")[ok]
    params = run.numeric_params
    cols, lows, highs, logs = [], [], [], []
    for p in params:
        logs.append(_log_scale(run.trials[p][ok]))
        v, lo, hi = _normalise(run.trials[p][ok], logs[-1])
        cols.append(v)
        lows.append(lo)
        highs.append(hi)
    values = np.column_stack(cols) if cols else np.zeros((len(score), 0))
    best = np.zeros(len(score), dtype=bool)
    if len(score):
        n_best = max(1, math.ceil(best_fraction * len(score)))
        best[np.argsort(score, kind="stable")[:n_best]] = True
    best.flags.writeable = False
    log = np.array(logs, dtype=bool)
    log.flags.writeable = False
    return ParallelInfo(
        params, _ro(values), _ro(lows), _ro(highs), log, _ro(score), best, best_fraction
    )


# ---------------------------------------------------------------------------------------------
# 5./6. Curves of the run's answers, the references and the human finger
# ---------------------------------------------------------------------------------------------

#: the answers of a run (summary.json ``answers``, ``explore._summary.ANSWER_KINDS``), in report
#: order, as the figures name them
ANSWER_NAMES: dict[str, str] = {
    "best": "best credible",
    "gel": "gel",
    "foam": "foam",
    "buildable": "buildable",
}


@dataclass(frozen=True, eq=False)
class Curve:
    """One curve of an FE record: ``x``/``y`` (units of the figure's axes), ``role`` "answer",
    "reference" or "human", and ``value``: the figure's headline metric of that record
    (hysteresis in N mm for tapping loops, peak force in N for the wedge; None if unknown).
    ``answers``: the summary answers (``ANSWER_NAMES`` keys) this record is, in report order
    (two when one design is both, e.g. the best credible and the best gel design)."""

    label: str
    role: str
    x: np.ndarray
    y: np.ndarray
    value: float | None = None
    answers: tuple[str, ...] = ()


def _report_order(kinds: Iterable[str]) -> tuple[str, ...]:
    """Answer kinds in ``ANSWER_NAMES`` order, unknown ones after it by name."""
    order = list(ANSWER_NAMES)
    return tuple(sorted(kinds, key=lambda k: (order.index(k) if k in order else len(order), k)))


def _answer_records(
    run: RunData,
) -> tuple[list[tuple[tuple[str, ...], Mapping[str, Any], dict[str, Any]]], tuple[str, ...]]:
    """(answer kinds, first answer, FE record) of every answer in summary.json with a record,
    one entry per record, in ``ANSWER_NAMES`` order (unknown kinds after); and the kinds
    without a curve (no answer, i.e. null, or its record missing)."""
    answers = run.summary.get("answers") or {}
    kinds = _report_order(answers)
    by_key: dict[str, list[str]] = {}
    missing = []
    for kind in kinds:
        key = _answer_key(answers[kind])
        if key is None or key not in run.records:
            missing.append(kind)
        else:
            by_key.setdefault(key, []).append(kind)
    out = [(tuple(ks), answers[ks[0]], run.records[key]) for key, ks in by_key.items()]
    return out, tuple(missing)


def _answer_label(kinds: Sequence[str], answer: Mapping[str, Any]) -> str:
    names = " = ".join(ANSWER_NAMES.get(k, k) for k in kinds)
    score = answer.get("fe_score")
    return f"{names} (FE score {score:.3g})" if isinstance(score, int | float) else names


#: (label, role, answer kinds, the answer's design or {}, FE record) of one drawn record
_Selected = tuple[str, str, tuple[str, ...], Mapping[str, Any], dict[str, Any]]


def _selected_records(run: RunData) -> tuple[list[_Selected], tuple[str, ...]]:
    """(label, role, answer kinds, design of the answer or {}, record) of the answers, then of
    the references (by name); and the answer kinds without a curve."""
    answered, missing = _answer_records(run)
    out = [
        (_answer_label(kinds, answer), "answer", kinds, answer.get("design") or {}, rec)
        for kinds, answer, rec in answered
    ]
    out += [(name, "reference", (), {}, rec) for name, rec in sorted(run.references.items())]
    return out, missing


def _metric(record: Mapping[str, Any], name: str) -> float | None:
    v = (record.get("metrics") or {}).get(name)
    return float(v) if isinstance(v, int | float) and math.isfinite(v) else None


def _curve(
    label: str,
    role: str,
    record: Mapping[str, Any],
    protocol: str,
    xy: tuple[str, str],
    value: float | None = None,
    transform: Callable[[np.ndarray, np.ndarray], np.ndarray] | None = None,
    answers: tuple[str, ...] = (),
) -> Curve | None:
    data = (record.get("curves") or {}).get(protocol) or {}
    if xy[0] not in data or xy[1] not in data or not len(data[xy[0]]):
        return None
    x = np.asarray(data[xy[0]], dtype=float)
    y = np.asarray(data[xy[1]], dtype=float)
    if transform is not None:
        x = transform(x, y)
    return Curve(label, role, _ro(x), _ro(y), value, answers)


def _from_touch(displacement: np.ndarray, force: np.ndarray) -> np.ndarray:
    """Displacement from the first touch: minus the displacement where the force leaves 0."""
    loaded = np.flatnonzero(force > 0)
    touch = max(int(loaded[0]) - 1, 0) if len(loaded) else 0
    return displacement - displacement[touch]


@dataclass(frozen=True)
class LoopsInfo:
    """Tapping loops (x: displacement in mm, read as the targets are; y: force in N) of the
    run's answers (role "answer", in ``ANSWER_NAMES`` order) and the references, each curve's
    hysteresis (N mm) in ``Curve.value``; ``missing``: the answer kinds without a loop (no
    answer, or no record). The human target points ((disp_at_1N_mm, 1 N), (disp_at_4N_mm,
    4 N)) and hysteresis (None: no targets); ``human``: the loading curve through the points
    (``sim.design.targets.loading_curve``, derived, not a published fit), from 0 to the tap's peak
    force, with ``human_fit`` = (B in N, k in 1/mm) of F = B (exp(k d) - 1); ``human_is_finger``:
    the targets are the shipped human ones (else a user's own)."""

    curves: tuple[Curve, ...]
    target_points: tuple[tuple[float, float], ...]
    target_hysteresis_Nmm: float | None
    reading: str = "from_undeformed_top"
    human: Curve | None = None
    human_fit: tuple[float, float] | None = None
    human_is_finger: bool = False
    missing: tuple[str, ...] = ()

    @property
    def empty(self) -> bool:
        return not self.curves and not self.target_points

    @property
    def answers(self) -> tuple[str, ...]:
        """Every answer kind with a loop, in the order drawn."""
        return tuple(k for c in self.curves for k in c.answers)


def _human_curve(
    targets: Targets, peak_force_N: float, n: int = 101
) -> tuple[Curve | None, tuple[float, float] | None, bool]:
    """The loading curve through the targets' 1 N and 4 N points, up to ``peak_force_N``."""
    curve = loading_curve(targets)
    if curve is None:
        return None, None, False
    finger = targets.values == load_targets().values
    who = "human finger, Serina et al. 1997" if finger else "targets"
    d = np.linspace(0.0, float(curve.displacement(max(peak_force_N, 4.0))), n)
    label = (
        f"{who}: loading curve, exponential through the 1 N and 4 N points (derived, not a "
        "published fit)"
    )
    value = targets.values.get("hysteresis_Nmm")
    fit = (curve.B_N, curve.k_per_mm)
    return Curve(label, "human", _ro(d), _ro(curve.force(d)), value), fit, finger


def loops_info(run: RunData) -> LoopsInfo:
    """Tapping loops of the run's answers (summary.json ``answers``: best credible, gel, foam,
    buildable; their ``fe_record``) and of every reference, with the human target points and
    hysteresis and the human loading curve through the points."""
    targets = run_targets(run)
    reading = targets.reading if targets else "from_undeformed_top"
    transform = _from_touch if reading == "from_first_touch" else None
    curves = []
    options = run_options(run)
    selected, missing = _selected_records(run)
    for label, role, kinds, design, rec in selected:
        # 0 below what the solver's tolerances resolve (a reference names no design: the
        # resolution's indenter term alone)
        hyst = shown_hysteresis(rec.get("metrics") or {}, design or None, options)
        xy = ("displacement_mm", "force_N")
        c = _curve(label, role, rec, "tapping", xy, hyst, transform, kinds)
        if c is not None:
            curves.append(c)
        elif role == "answer":
            missing += kinds
    points: tuple[tuple[float, float], ...] = ()
    hysteresis = None
    human, fit, finger = None, None, False
    if targets is not None:
        v = targets.values
        points = ((v["disp_at_1N_mm"], 1.0), (v["disp_at_4N_mm"], 4.0))
        hysteresis = v["hysteresis_Nmm"]
        human, fit, finger = _human_curve(targets, options.tapping.peak_force_N)
    missing = _report_order(missing)
    return LoopsInfo(tuple(curves), points, hysteresis, reading, human, fit, finger, missing)


@dataclass(frozen=True)
class WedgeInfo:
    """Wedge force (N) over time (s), peak force (N) in ``Curve.value``; surface deflection
    (mm) against distance from the wedge (mm) after 1 s and 100 s; the same answers and
    references as the loops (``missing``: answer kinds without a wedge curve)."""

    force: tuple[Curve, ...]
    profile_1s: tuple[Curve, ...]
    profile_100s: tuple[Curve, ...]
    missing: tuple[str, ...] = ()

    @property
    def empty(self) -> bool:
        return not (self.force or self.profile_1s or self.profile_100s)

    @property
    def answers(self) -> tuple[str, ...]:
        """Every answer kind with a wedge force curve, in the order drawn."""
        return tuple(k for c in self.force for k in c.answers)


def wedge_info(run: RunData) -> WedgeInfo:
    """Wedge force-time curves and the 1 s / 100 s surface profiles of the run's answers and
    of every reference."""
    force, p1, p100 = [], [], []
    profile_xy = ("distance_mm", "deflection_mm")
    selected, missing = _selected_records(run)
    for label, role, kinds, _design, rec in selected:
        peak = _metric(rec, "wedge_peak_force_N")
        for out, curve in (
            (force, _curve(label, role, rec, "wedge", ("time_s", "force_N"), peak, None, kinds)),
            (p1, _curve(label, role, rec, "profile_1s", profile_xy, None, None, kinds)),
            (p100, _curve(label, role, rec, "profile_100s", profile_xy, None, None, kinds)),
        ):
            if curve is not None:
                out.append(curve)
    drawn = {k for c in force for k in c.answers}
    lost = [k for label, role, kinds, _d, _r in selected for k in kinds if k not in drawn]
    return WedgeInfo(tuple(force), tuple(p1), tuple(p100), _report_order((*missing, *lost)))


# ---------------------------------------------------------------------------------------------
# 7. Parity: surrogate vs FE on the confirmations
# ---------------------------------------------------------------------------------------------


@dataclass(frozen=True, eq=False)
class ParityMetric:
    """One scored metric over the confirmations (status ok, finite FE value and prediction):
    FE value, surrogate mean and 90 % interval (metric unit); ``inside_fraction``: share of the
    designs with an interval whose FE value lies in it (NaN if none); ``median_abs_rel_error``:
    median |mean - FE| / |FE| (NaN if none)."""

    name: str
    unit: str
    fe: np.ndarray
    mean: np.ndarray
    lower: np.ndarray
    upper: np.ndarray
    labels: tuple[str, ...]
    inside_fraction: float
    median_abs_rel_error: float


@dataclass(frozen=True)
class ParityInfo:
    """Parity of every scored metric (the tapping targets' metrics and the wedge peak force)."""

    metrics: tuple[ParityMetric, ...]

    @property
    def empty(self) -> bool:
        return all(len(m.fe) == 0 for m in self.metrics)


def _scored_metrics(targets: Targets | None) -> tuple[str, ...]:
    t = targets or Targets(values={})
    return (*(t.metric(n) for n in TAPPING), "wedge_peak_force_N")


def _num(x: Any) -> float:
    return float(x) if isinstance(x, int | float) and not isinstance(x, bool) else np.nan


def _parity_metric(run: RunData, name: str) -> ParityMetric:
    fe, mean, lower, upper, labels = [], [], [], [], []
    for c in run.confirmations:
        pred = c.candidate.predicted.get(name) or {}
        f, m = _num(c.fe_metrics.get(name)), _num(pred.get("median", pred.get("mean")))
        if c.status != "ok" or not (math.isfinite(f) and math.isfinite(m)):
            continue
        fe.append(f)
        mean.append(m)
        lower.append(_num(pred.get("lower_90")))
        upper.append(_num(pred.get("upper_90")))
        labels.append(_label(c))
    fe_a, mean_a, lo, hi = (np.array(v, dtype=float) for v in (fe, mean, lower, upper))
    has = np.isfinite(lo) & np.isfinite(hi)
    inside = (
        float(np.mean((lo[has] <= fe_a[has]) & (fe_a[has] <= hi[has]))) if has.any() else np.nan
    )
    with np.errstate(divide="ignore", invalid="ignore"):
        rel = np.abs(mean_a - fe_a) / np.abs(fe_a)
    rel = rel[np.isfinite(rel)]
    median = float(np.median(rel)) if len(rel) else np.nan
    unit = _UNITS.get(name, "")
    return ParityMetric(
        name, unit, _ro(fe_a), _ro(mean_a), _ro(lo), _ro(hi), tuple(labels), inside, median
    )


def parity_info(run: RunData) -> ParityInfo:
    """FE against surrogate (mean, 90 % interval) per scored metric, over the confirmations
    with status ok, with the fraction inside the interval and the median |relative error|."""
    return ParityInfo(tuple(_parity_metric(run, n) for n in _scored_metrics(run_targets(run))))


# ---------------------------------------------------------------------------------------------
# Rendering
# ---------------------------------------------------------------------------------------------


def _figure(width: float, height: float) -> Figure:
    fig = Figure(figsize=(width, height), layout="constrained")
    FigureCanvasAgg(fig)
    return fig


def _no_data(title: str, message: str = "no data") -> Figure:
    fig = _figure(5.0, 3.0)
    ax = fig.add_subplot()
    ax.set_axis_off()
    ax.set_title(title)
    ax.text(0.5, 0.5, message, ha="center", va="center", fontsize=12, transform=ax.transAxes)
    return fig


def _score_range(scores: np.ndarray) -> tuple[float, float] | None:
    """The score's colour range: the lowest positive finite score to the median of them (the
    worse half all in the palest colour: a few poor trials would otherwise squeeze the good
    ones into one colour); to the highest if the median is the lowest. None: no such score."""
    pos = scores[np.isfinite(scores) & (scores > 0)]
    if len(pos) == 0:
        return None
    lo, mid, hi = float(pos.min()), float(np.median(pos)), float(pos.max())
    return (lo, mid if mid > lo else (hi if hi > lo else 10.0 * lo))


def _clip(values: np.ndarray, norm: Normalize) -> np.ndarray:
    return np.clip(values, norm.vmin, None) if isinstance(norm, LogNorm) else values


def _set_log_axis(axis: Any, log: LogAxis) -> None:
    """Draw ``axis`` (an Axes' xaxis or yaxis, or a colour bar's) as the log axis ``log``: its
    limits, its labelled ticks, unlabelled minor ticks (matplotlib labels the minor ticks of an
    axis spanning few decades, and those labels run into each other)."""
    axis.set_ticks(log.ticks, labels=log.labels)
    axis.set_minor_locator(LogLocator(base=10.0, subs=tuple(range(2, 10))))
    axis.set_minor_formatter(NullFormatter())


def _log_axes(ax: Any, x: LogAxis | None, y: LogAxis | None) -> None:
    """Log scale, limits and ticks on the axes given (the others stay linear)."""
    for log, scale, limits, axis in (
        (x, ax.set_xscale, ax.set_xlim, ax.xaxis),
        (y, ax.set_yscale, ax.set_ylim, ax.yaxis),
    ):
        if log is not None:
            scale("log")
            limits(*log.limits)
            _set_log_axis(axis, log)


#: the score's colour ramp: dark is good (the best drawn last, on top), the pale yellow end of
#: viridis left out (it vanishes on white)
_SCORE_CMAP = ListedColormap(colormaps["viridis"](np.linspace(0.0, 0.85, 256)))


def render_projections(info: ProjectionsInfo) -> Figure:
    """Lower-triangle matrix of pairwise scatter plots, log colour scale of the score."""
    title = f"Pairwise projections (top parameters by {info.ranked_by})"
    if info.empty:
        return _no_data(title, "not enough numeric parameters")
    n = len(info.params) - 1
    fig = _figure(2.6 * n + 1.2, 2.4 * n + 0.6)
    axes = fig.subplots(n, n, squeeze=False)
    norm = info.score_norm
    index = {p: k for k, p in enumerate(info.params)}
    mappable = None
    for ax in axes.flat:
        ax.set_visible(False)
    for pair in info.pairs:
        ax = axes[index[pair.y_name] - 1, index[pair.x_name]]
        ax.set_visible(True)
        order = np.argsort(-pair.score, kind="stable")  # the best drawn last, on top
        mappable = ax.scatter(
            pair.x[order],
            pair.y[order],
            c=_clip(pair.score[order], norm),
            norm=norm,
            cmap=_SCORE_CMAP,
            s=8,
            lw=0,
        )
        ax.scatter(pair.confirmed_x, pair.confirmed_y, marker="*", s=90, c="none", ec="red")
        _log_axes(ax, pair.x_axis, pair.y_axis)
        ax.set_xlabel(pair.x_name, fontsize=7)
        ax.set_ylabel(pair.y_name, fontsize=7)
        ax.tick_params(which="both", labelsize=6)
    if mappable is not None:
        label = "score (lower is better; the worse half of the trials: the end colour)"
        bar = fig.colorbar(mappable, ax=axes, label=label, shrink=0.6, extend="max")
        if info.score_axis is not None:
            _set_log_axis(bar.ax.yaxis, info.score_axis)
    fig.suptitle(f"{title}; the best drawn on top; red stars: FE-confirmed designs", fontsize=9)
    return fig


def render_pareto(info: ParetoInfo) -> Figure:
    """Compliance error against hysteresis error coloured by wedge effort, the non-dominated
    set highlighted, the confirmed designs (FE) starred."""
    title = "Objectives of all trials (minimise all three)"
    if info.empty:
        return _no_data(title)
    fig = _figure(6.0, 4.6)
    ax = fig.add_subplot()
    every = np.vstack([info.points, info.confirmed])
    norm = Normalize(float(every[:, 2].min()), float(every[:, 2].max()) or 1.0)
    sc = ax.scatter(
        info.points[:, 0], info.points[:, 1], c=info.points[:, 2], norm=norm, s=10, lw=0
    )
    if len(info.front):
        f = info.points[info.front]
        label = f"non-dominated ({len(f)})"
        ax.scatter(f[:, 0], f[:, 1], c=f[:, 2], norm=norm, s=36, ec="red", lw=1.0, label=label)
    if len(info.confirmed):
        cx, cy, cz = info.confirmed.T
        ax.scatter(cx, cy, c=cz, norm=norm, marker="*", s=160, ec="black", label="FE-confirmed")
    _log_axes(ax, info.x_axis, info.y_axis)
    if len(info.confirmed):
        _callouts(fig, ax, info.confirmed[:, :2], info.confirmed_labels)
    fig.colorbar(sc, ax=ax, label="wedge effort F / F_ref")
    ax.set_xlabel("compliance error (rms relative, 1 N and 4 N)")
    ax.set_ylabel("hysteresis error (|relative|)")
    ax.set_title(title, fontsize=9)
    if ax.get_legend_handles_labels()[0]:
        ax.legend(fontsize=7)
    return fig


def spread_labels(
    wanted: np.ndarray, gap: float, low: float = 0.0, high: float = 1.0
) -> np.ndarray:
    """Positions of labels along one axis, each as near its ``wanted`` position as the others
    allow, at least ``gap`` apart and inside [``low``, ``high``] (if they fit: ``gap`` x count
    <= ``high`` - ``low``). Order is kept: label i ends below label j if it wanted to."""
    wanted = np.asarray(wanted, dtype=float)
    order = np.argsort(wanted, kind="stable")
    y = np.clip(wanted[order], low, high)
    for k in range(1, len(y)):  # push up the ones that crowd the one below
        y[k] = max(y[k], y[k - 1] + gap)
    if len(y) and y[-1] > high:  # then down from the top, as little as needed
        y[-1] = high
        for k in range(len(y) - 2, -1, -1):
            y[k] = min(y[k], y[k + 1] - gap)
    out = np.empty_like(y)
    out[order] = y
    return out


def _callouts(fig: Figure, ax: Any, points: np.ndarray, labels: Sequence[str]) -> None:
    """Label ``points`` (data coordinates) in a column right of the axes, each at the height of
    its point where the others allow (``spread_labels``), joined to it by a thin line: labels
    never overlap, however close the points."""
    ax.autoscale_view()
    to_axes = ax.transData + ax.transAxes.inverted()
    wanted = to_axes.transform(points)[:, 1]
    size = 6.0
    axes_height_pt = 0.75 * fig.get_figheight() * 72.0  # constrained layout leaves ~3/4
    gap = 1.5 * size / axes_height_pt
    if gap * len(labels) > 1.0:  # too many for the column: smaller type, tighter
        size = max(3.0, size / (gap * len(labels)))
        gap = 1.0 / len(labels)
    slots = spread_labels(wanted, gap, 0.5 * gap, 1.0 - 0.5 * gap)
    for (x, y), slot, label in zip(points, slots, labels, strict=True):
        ax.annotate(label, (x, y), xytext=(1.02, slot), textcoords="axes fraction",
                    fontsize=size, va="center", ha="left", annotation_clip=False,
                    arrowprops={"arrowstyle": "-", "lw": 0.4, "color": "0.6",
                                "shrinkA": 0, "shrinkB": 4})  # fmt: skip


def _segments(values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Line segments between neighbouring axes where both ends are active, and their rows."""
    p = values.shape[1]
    segs, rows = [], []
    for k in range(p - 1):
        both = np.isfinite(values[:, k]) & np.isfinite(values[:, k + 1])
        r = np.flatnonzero(both)
        seg = np.zeros((len(r), 2, 2))
        seg[:, 0, 0], seg[:, 1, 0] = k, k + 1
        seg[:, 0, 1], seg[:, 1, 1] = values[r, k], values[r, k + 1]
        segs.append(seg)
        rows.append(r)
    if not segs:
        return np.zeros((0, 2, 2)), np.zeros(0, dtype=int)
    return np.concatenate(segs), np.concatenate(rows)


def render_parallel(info: ParallelInfo) -> Figure:
    """Parallel coordinates: every trial a thin grey line behind, the best ones on top in a
    colour ramp of their score (linear over the best; the very best drawn thickest, last)."""
    title = "Parallel coordinates (each axis: observed min to max)"
    if info.empty:
        return _no_data(title)
    p = len(info.params)
    fig = _figure(max(6.0, 1.1 * p + 2.0), 4.6)
    ax = fig.add_subplot()
    segs, rows = _segments(info.values)
    order = info.best_order  # worst of the best first
    best_scores = info.score[order]
    norm = Normalize(float(best_scores.min()), float(best_scores.max()))
    if norm.vmax <= norm.vmin:
        norm = Normalize(norm.vmin - 0.5, norm.vmin + 0.5)
    rest = ~info.best[rows]
    ax.add_collection(LineCollection(segs[rest], colors="0.6", linewidths=0.4, alpha=0.25))
    rank = np.empty(len(info.score), dtype=int)
    rank[order] = np.arange(len(order))  # the drawing order of the best rows
    top = np.flatnonzero(info.best[rows])
    top = top[np.argsort(rank[rows[top]], kind="stable")]
    lc = LineCollection(segs[top], cmap=_SCORE_CMAP, norm=norm, linewidths=1.0, alpha=0.9)
    lc.set_array(info.score[rows[top]])
    ax.add_collection(lc)
    winner = top[rows[top] == order[-1]]
    ax.add_collection(LineCollection(segs[winner], colors="black", linewidths=2.2))
    if p == 1:  # one axis, no segments: mark the values
        others = info.values[~info.best, 0]
        ax.scatter(np.zeros(len(others)), others, c="0.6", s=6)
        ax.scatter(np.zeros(len(order)), info.values[order, 0], c=best_scores, norm=norm,
                   cmap=_SCORE_CMAP, s=10)  # fmt: skip
    for k in range(p):
        ax.axvline(k, color="0.3", lw=0.8)
        ax.text(k, -0.06, f"{info.low[k]:.3g}", ha="center", va="top", fontsize=7)
        ax.text(k, 1.04, f"{info.high[k]:.3g}", ha="center", va="bottom", fontsize=7)
    ax.set_xlim(-0.3, p - 0.7)
    ax.set_ylim(-0.15, 1.12)
    names = [f"{n} (log)" if log else n for n, log in zip(info.params, info.log, strict=True)]
    ax.set_xticks(range(p), names, rotation=30, ha="right", fontsize=7)
    ax.set_yticks([])
    n, n_best = len(info.score), len(order)
    share = f"{100 * info.best_fraction:.3g} %"
    bar = fig.colorbar(lc, ax=ax, pad=0.01)
    bar.set_label(f"score of the best {share} (lower is better)", fontsize=8)
    handles = [
        Line2D([], [], color="0.6", lw=1.0, label=f"other trials ({n - n_best})"),
        Line2D([], [], color=_SCORE_CMAP(0.5), lw=1.0,
               label=f"best {share} ({n_best} trials), coloured by score"),
        Line2D([], [], color="black", lw=2.2,
               label=f"best trial (score {info.score[order[-1]]:.3g})"),
    ]  # fmt: skip
    fig.legend(handles=handles, fontsize=7, loc="outside lower center", ncols=3, frameon=False)
    ax.set_title(f"{title}: the best {share} of {n} trials on top of the others", fontsize=9)
    return fig


def render_importance(info: ImportanceInfo) -> Figure:
    """Horizontal bars of the importances, the most important at the top."""
    title = "Parameter importance for the score"
    if info.empty:
        reason = "" if info.message in ("", "not enough trials") else f" ({info.message})"
        return _no_data(title, f"not enough trials{reason}")
    fig = _figure(6.0, 0.3 * len(info.names) + 1.4)
    ax = fig.add_subplot()
    y = np.arange(len(info.names))[::-1]
    ax.barh(y, info.importances, color="C0")
    ax.set_yticks(y, info.names, fontsize=7)
    for yy, v in zip(y, info.importances, strict=True):
        ax.text(v, yy, f" {v:.2f}", va="center", fontsize=6)
    ax.set_xlabel("importance (normalised, sum 1)")
    # two lines: a study name of any length never runs off the figure
    ax.set_title(f"{title}\n(study {info.study_name}, {info.n_trials} trials)", fontsize=9)
    return fig


#: the colour of each answer in the loops and wedge figures (the same in both)
_ANSWER_COLOURS = {"best": "C0", "gel": "C1", "foam": "C2", "buildable": "C3"}


def _draw_curves(ax: Any, curves: Iterable[Curve], value: str = "") -> None:
    """The answers in their colours (``_ANSWER_COLOURS``), the references grey and dashed;
    ``value`` formats ``Curve.value`` into the legend ("{:.3g} N", say)."""
    styles = itertools.cycle(["--", ":", "-."])
    extra = itertools.count(4)
    for c in curves:
        label = c.label if c.role == "answer" else f"{c.label} (paper's material)"
        if c.value is not None and value:
            label += f"; {value.format(c.value)}"
        if c.role == "answer":
            colour = _ANSWER_COLOURS.get(c.answers[0] if c.answers else "", None)
            ax.plot(c.x, c.y, "-", color=colour or f"C{next(extra)}", lw=1.6, label=label)
        else:
            ax.plot(c.x, c.y, next(styles), color="0.5", lw=1.1, label=label)


def _missing_note(missing: Sequence[str]) -> str:
    names = ", ".join(ANSWER_NAMES.get(k, k) for k in missing)
    return f"\nno curve for: {names} (no such answer in summary.json, or no FE record)"


def render_loops(info: LoopsInfo) -> Figure:
    """Force against displacement of each tap of the answers and the references, against the
    human loading curve (solid between the two measured points, dotted beyond) and points."""
    title = "Tapping loops"
    if info.empty:
        return _no_data(title)
    fig = _figure(10.0, 5.0)
    ax = fig.add_subplot()
    _draw_curves(ax, info.curves, "hysteresis {:.3g} N mm")
    who = "human finger" if info.human_is_finger else "targets"
    if info.human is not None:
        h = info.human
        forces = [f for _, f in info.target_points] or [1.0, 4.0]
        inside = (h.y >= min(forces)) & (h.y <= max(forces))
        ax.plot(h.x[inside], h.y[inside], "-", color="black", lw=2.4, zorder=5,
                label=h.label.replace(": ", ":\n", 1))  # fmt: skip
        for part in (h.y <= min(forces), h.y >= max(forces)):
            ax.plot(h.x[part], h.y[part], ":", color="black", lw=1.6, zorder=5)
        ax.plot([], [], ":", color="black", lw=1.6,
                label=f"{who}: the curve extrapolated below 1 N and above 4 N")  # fmt: skip
    if info.target_points:
        x, y = zip(*info.target_points, strict=True)
        source = " (Serina et al. 1997, via Cabibihan et al.)" if info.human_is_finger else ""
        hyst = f", hysteresis {info.target_hysteresis_Nmm:.3g} N mm"
        ax.plot(x, y, "o", color="black", ms=8, mfc="white", mew=2, zorder=6,
                label=f"{who}: measured points{source}{hyst}")  # fmt: skip
    reading = "from first touch" if info.reading == "from_first_touch" else "from undeformed top"
    ax.set_xlabel(f"displacement ({reading}) [mm]")
    ax.set_ylabel("force [N]")
    ax.set_xlim(left=0.0 if info.reading == "from_first_touch" else None)
    ax.set_ylim(bottom=0.0)
    note = _missing_note(info.missing) if info.missing else ""
    ax.set_title(f"{title} of the run's answers against the {who}{note}", fontsize=9)
    ax.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0), frameon=False)
    return fig


def render_wedge(info: WedgeInfo) -> Figure:
    """Three panels: wedge force over time (symlog time), the 1 s and the 100 s profiles; one
    legend for the three, below them."""
    title = "Wedge indentation"
    if info.empty:
        return _no_data(title)
    fig = _figure(13.0, 4.8)
    axes = fig.subplots(1, 3)
    _draw_curves(axes[0], info.force, "peak {:.3g} N")
    axes[0].set_xscale("symlog", linthresh=1.0)
    axes[0].xaxis.set_major_formatter(FormatStrFormatter("%g"))
    axes[0].set_xlabel("time [s]")
    axes[0].set_ylabel("wedge force [N]")
    axes[0].set_title("force (lower is better: a human finger needs almost none)", fontsize=8)
    profiles = ((axes[1], info.profile_1s, "1 s"), (axes[2], info.profile_100s, "100 s"))
    for ax, curves, when in profiles:
        _draw_curves(ax, curves)
        ax.set_xlabel("distance from the wedge [mm]")
        ax.set_ylabel("surface deflection, downward [mm]")
        ax.set_title(f"surface profile after {when}", fontsize=8)
        # the surface drawn as it goes: deflection downward, as in `fingertip simulate --out`'s
        # figure (sim.output.result) and the paper's profiles
        ax.invert_yaxis()
        if not curves:
            ax.text(0.5, 0.5, f"not reached (a wedge hold shorter than {when})", ha="center",
                    va="center", fontsize=8, transform=ax.transAxes)  # fmt: skip
    handles, labels = axes[0].get_legend_handles_labels()
    if not handles:
        handles, labels = axes[1].get_legend_handles_labels()
    if handles:
        fig.legend(handles, labels, loc="outside lower center", ncols=3, fontsize=7,
                   frameon=False)  # fmt: skip
    note = _missing_note(info.missing) if info.missing else ""
    fig.suptitle(f"{title} of the run's answers{note}", fontsize=9)
    return fig


def _parity_panel(ax: Any, m: ParityMetric) -> None:
    unit = f" [{m.unit}]" if m.unit else ""
    ax.set_xlabel(f"FE{unit}", fontsize=7)
    ax.set_ylabel(f"surrogate{unit}", fontsize=7)
    if len(m.fe) == 0:
        ax.set_title(f"{m.name}: no confirmed designs", fontsize=8)
        return
    err = np.nan_to_num(np.vstack([m.mean - m.lower, m.upper - m.mean]), nan=0.0).clip(min=0)
    ax.errorbar(m.fe, m.mean, yerr=err, fmt="o", ms=4, elinewidth=0.8, capsize=2)
    lo = float(min(m.fe.min(), m.mean.min()))
    hi = float(max(m.fe.max(), m.mean.max()))
    pad = 0.05 * (hi - lo or abs(hi) or 1.0)
    ax.plot([lo - pad, hi + pad], [lo - pad, hi + pad], "k--", lw=0.8)
    inside = "–" if math.isnan(m.inside_fraction) else f"{100 * m.inside_fraction:.0f} %"
    med = "–" if math.isnan(m.median_abs_rel_error) else f"{100 * m.median_abs_rel_error:.1f} %"
    ax.set_title(
        f"{m.name} (n = {len(m.fe)})\n{inside} inside 90 % interval, median |rel. err.| {med}",
        fontsize=8,
    )


def render_parity(info: ParityInfo) -> Figure:
    """One panel per scored metric: surrogate mean with its 90 % interval against FE."""
    title = "Surrogate vs FE on the confirmed designs"
    if info.empty:
        return _no_data(title, "no confirmed designs")
    n = len(info.metrics)
    cols = 2 if n > 1 else 1
    rows = math.ceil(n / cols)
    fig = _figure(4.2 * cols, 3.8 * rows)
    axes = np.atleast_1d(fig.subplots(rows, cols, squeeze=False)).ravel()
    for ax, m in zip(axes, info.metrics, strict=False):
        _parity_panel(ax, m)
    for ax in axes[n:]:
        ax.set_visible(False)
    fig.suptitle(f"{title} (dashed: perfect agreement)", fontsize=9)
    return fig


# ---------------------------------------------------------------------------------------------
# All figures
# ---------------------------------------------------------------------------------------------


def _drawings(run: RunData) -> dict[str, tuple[Callable[[Any], Figure], Any]]:
    """Every figure as (render function, its info), computed from the run."""
    importance = importance_info(run)
    return {
        "loops": (render_loops, loops_info(run)),
        "wedge": (render_wedge, wedge_info(run)),
        "parity": (render_parity, parity_info(run)),
        "pareto": (render_pareto, pareto_info(run)),
        "importance": (render_importance, importance),
        "projections": (render_projections, projections_info(run, importance=importance)),
        "parallel": (render_parallel, parallel_info(run)),
    }


def _png(render: Callable[[Any], Figure], info: Any) -> bytes:
    """The PNG bytes of ``render(info)`` (no date in them: the same figure, the same bytes)."""
    figure = render(info)
    buffer = io.BytesIO()
    figure.savefig(buffer, dpi=_DPI, format="png")
    figure.clear()
    return buffer.getvalue()


def write_figures(run_dir: str | Path, workers: int = 1) -> dict[str, Path]:
    """Compute, render and save every figure as ``run_dir/figures/<name>.png`` (dpi 110);
    returns name -> path in the order of ``FIGURES``. Empty data gives a "no data" figure.

    ``workers`` > 1 renders in that many processes (drawing, not the data, is what takes the
    time: several seconds for the seven figures); the bytes are the same either way."""
    run = load_run(run_dir)
    folder = Path(run_dir) / "figures"
    folder.mkdir(parents=True, exist_ok=True)
    drawings = _drawings(run)
    names = list(FIGURES)
    jobs = [drawings[name] for name in names]
    if workers > 1:
        from sim.pool import process_pool

        with process_pool(min(workers, len(jobs))) as pool:
            pngs = list(pool.map(_png, *zip(*jobs, strict=True)))
    else:
        pngs = [_png(render, info) for render, info in jobs]
    paths = {}
    for name, data in zip(names, pngs, strict=True):
        path = folder / f"{name}.png"
        write_if_changed(path, data)  # the same figure: left as it is
        paths[name] = path
    return paths
