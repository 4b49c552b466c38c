"""``fingertip optimize`` and ``fingertip run``: search -> FE confirmation -> active learning
-> summary and report, resumable in a run folder (layout: ``explore._types``).

One round: an Optuna study searches the surrogate over the design space ("continuous") and
another over catalogue materials only ("buildable"); the best distinct trusted designs, one or
more promising-but-uncertain ones and the best buildable design are simulated with full FE; the
round's surrogate-vs-FE errors decide whether to stop (all tapping metrics within
``tolerance`` on every confirmed design) or to retrain the surrogate, warm-started, on its
training data plus every FE result so far, and search again. The answer is always an FE result:
the best confirmed design and the best confirmed buildable design (``summary.json``).
"""

from __future__ import annotations

import csv
import dataclasses
import json
import math
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from sim import SOLVER_VERSION, SimOptions
from sim.errors import DesignError
from sim.provenance import provenance, write_json
from sim.space import load_space
from sim.targets import Targets, load_targets

from ._confirm import REFERENCES, confirm, reference_point, run_fe
from ._objective import TAPPING, closeness
from ._search import (
    OBJECTIVE_NAMES,
    SearchSettings,
    TrialRow,
    _finished,
    catalogue_only,
    check_subspace,
    create_study,
    run_study,
    select_candidates,
)
from ._types import Candidate, Confirmation, Summary

__all__ = ["DEFAULT_CHECKPOINT", "OptimizeConfig", "optimize"]

PRETRAINED = Path(__file__).resolve().parents[1] / "surrogate" / "pretrained" / "default"
DEFAULT_CHECKPOINT = PRETRAINED / "model.safetensors"
#: confirmed FE designs count this many times in a warm-started retraining (they are few, and
#: they sit where the search wants the surrogate to be right)
CONFIRMED_WEIGHT = 10


@dataclass(frozen=True)
class OptimizeConfig:
    """Everything a search run depends on (stored in the run folder's config.json).

    ``trials`` / ``buildable_trials``: surrogate evaluations per round of the continuous and
    the catalogue-only study; ``confirm``: best distinct designs sent to FE per round;
    ``uncertain``: promising designs the trust guard flagged, also sent to FE; ``rounds``: at
    most this many search/confirm/retrain rounds; ``tolerance``: agreement needed to stop
    (|surrogate - FE| / FE on the tapping metrics, together with an FE-confirmed design within
    it of every tapping target) and the closeness counted as "within" a target;
    ``max_disagreement``: the trust guard's limit on the ensemble's std/|mean|.
    """

    surrogate: str = str(DEFAULT_CHECKPOINT)
    space: str | None = None
    targets: str | None = None
    trials: int = 1000
    buildable_trials: int = 300
    confirm: int = 3
    uncertain: int = 1
    rounds: int = 3
    tolerance: float = 0.05
    mode: str = "single"
    max_disagreement: float = 0.10
    storage: str | None = None
    study: str = "fingertip"
    seed: int = 0
    workers: int = 2
    dataset: str | None = None
    retrain_epochs: int = 150

    def check(self) -> None:
        def at_least(name: str, value: int, low: int) -> None:
            if value < low:
                raise DesignError(f"--{name.replace('_', '-')}", f"must be >= {low}, got {value}")

        at_least("trials", self.trials, 1)
        at_least("buildable_trials", self.buildable_trials, 0)
        at_least("confirm", self.confirm, 1)
        at_least("uncertain", self.uncertain, 0)
        at_least("rounds", self.rounds, 1)
        at_least("workers", self.workers, 1)
        at_least("retrain_epochs", self.retrain_epochs, 1)
        if self.mode not in ("single", "multi"):
            raise DesignError("--mode", f"must be single or multi, got {self.mode!r}")
        for name in ("tolerance", "max_disagreement"):
            v = getattr(self, name)
            if not 0 < v < 1:
                raise DesignError(f"--{name.replace('_', '-')}", f"must be in (0, 1), got {v}")


# ----------------------------------------------------------------------------- run folder
def _prepare(config: OptimizeConfig, out: Path, targets: Targets, options: SimOptions) -> str:
    """Create or resume the run folder; returns the storage URL."""
    storage = config.storage or f"sqlite:///{(out / 'study.db').resolve()}"
    record = {
        **dataclasses.asdict(config),
        "sim_options": dataclasses.asdict(options),
        "storage": storage,
        "targets": dict(targets.values),
        "displacement_reading": targets.reading,
    }
    record = json.loads(json.dumps(record))  # as config.json holds it (lists, not tuples)
    path = out / "config.json"
    if path.exists():
        old = json.loads(path.read_text())
        if {k: v for k, v in old.items() if k != "studies"} != record:
            diff = next(k for k in record if record[k] != old.get(k))
            raise DesignError(
                "--out",
                f"{out} holds a run with another configuration ({diff}); "
                "use another --out or the same options to resume",
            )
        return storage
    out.mkdir(parents=True, exist_ok=True)
    write_json(path, {**record, "studies": []})
    write_json(out / "meta.json", provenance(record, config.seed))
    return storage


def _add_study(out: Path, name: str, search: str, round_: int, mode: str) -> None:
    path = out / "config.json"
    cfg = json.loads(path.read_text())
    if not any(s["name"] == name for s in cfg["studies"]):
        directions = ["minimize"] * (3 if mode == "multi" else 1)
        cfg["studies"].append(
            {"name": name, "search": search, "round": round_, "directions": directions}
        )
        write_json(path, cfg)


def _load_confirmations(out: Path) -> list[Confirmation]:
    path = out / "confirmations.json"
    if not path.exists():
        return []
    return [Confirmation.from_json(d) for d in json.loads(path.read_text())]


def _save_confirmations(out: Path, items: list[Confirmation]) -> None:
    tmp = out / ".confirmations.json.tmp"
    tmp.write_text(json.dumps([c.to_json() for c in items], indent=1, allow_nan=False))
    tmp.replace(out / "confirmations.json")


def write_trials(out: Path, rows: list[TrialRow], names: list[str], metrics: list[str]) -> None:
    """trials.csv: one row per scored trial of every round (see explore._types)."""
    header = [
        "round", "trial", "search", *names, "score", *OBJECTIVE_NAMES,
        *[f"pred.{m}" for m in metrics], *[f"std.{m}" for m in metrics],
        "in_domain", "disagreement", "trusted",
    ]  # fmt: skip
    tmp = out / ".trials.csv.tmp"
    with tmp.open("w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(header)
        for r in rows:
            cells = [r.round, r.trial, r.search]
            for n in names:
                v = r.point.get(n, "")
                cells.append("" if isinstance(v, float) and math.isnan(v) else v)
            cells.append(_cell(r.score))
            cells += [_cell(v) for v in r.objectives]
            cells += [_cell(r.predicted.get(m, {}).get("median")) for m in metrics]
            cells += [_cell(r.predicted.get(m, {}).get("std")) for m in metrics]
            cells += [int(r.in_domain), _cell(r.disagreement), int(not r.flags)]
            w.writerow(cells)
    tmp.replace(out / "trials.csv")


def _cell(v: Any) -> Any:
    if v is None:
        return ""
    v = float(v)
    return repr(v) if math.isfinite(v) else ""


# ----------------------------------------------------------------------------- active learning
def _find_dataset(config: OptimizeConfig, surrogate) -> Path | None:
    """The surrogate's training sweep: --dataset, the checkpoint's folder (a shipped checkpoint
    carries its table.csv), or the sweep named in its header, whichever holds the table whose
    sha256 the header records."""
    from surrogate._io import sha256_file

    want = surrogate.header.get("training_data", {}).get("table_sha256")
    places = [config.dataset, str(Path(config.surrogate).parent),
              surrogate.header.get("training_data", {}).get("sweep")]  # fmt: skip
    for p in places:
        if not p:
            continue
        table = Path(p) / "table.csv"
        if table.exists() and (Path(p) / "config.json").exists():
            if config.dataset or sha256_file(table) == want:
                return Path(p)
    return None


def _sim_options(dataset: Path | None) -> SimOptions:
    """The FE options of the surrogate's training sweep (so FE confirms like with like), else
    the defaults."""
    from sim.sweep import options_from_dict

    if dataset is None:
        return SimOptions()
    cfg = json.loads((dataset / "config.json").read_text())
    return options_from_dict(cfg["options"]) if "options" in cfg else SimOptions()


def retrain(surrogate, dataset: Path, confirmed: list[Confirmation], epochs: int, seed: int):
    """Warm-started retraining on the training sweep plus the FE-confirmed designs."""
    from surrogate import SweepData, read_sweep
    from surrogate._train import Split, TrainConfig, fit

    data = read_sweep(dataset)
    ok = [c for c in confirmed if c.trusted]  # an unsettled or invalid result teaches nothing
    names = list(data.metric_names)
    new_points = [c.candidate.point for c in ok for _ in range(CONFIRMED_WEIGHT)]
    new_targets = np.array(
        [[_nan(c.fe_metrics.get(m)) for m in names] for c in ok for _ in range(CONFIRMED_WEIGHT)]
    ).reshape(-1, len(names))
    base = len(data.points)
    aug = SweepData(
        folder=data.folder,
        space=data.space,
        solver_version=data.solver_version,
        points=[*data.points, *new_points],
        targets=np.vstack([data.targets, new_targets]),
        index=np.concatenate([data.index, -1 - np.arange(len(new_points))]),
        metric_names=data.metric_names,
        table_sha256=data.table_sha256,
        n_rows=data.n_rows + len(new_points),
    )
    split_idx = surrogate.header.get("training_data", {}).get("split_table_index", {})
    row_of = {int(i): r for r, i in enumerate(data.index)}

    def rows(key: str) -> np.ndarray:
        return np.array([row_of[i] for i in split_idx.get(key, []) if i in row_of], dtype=int)

    train, val, test = rows("train"), rows("val"), rows("test")
    if len(train) == 0 or len(val) == 0:
        raise ValueError("the checkpoint does not record its training split")
    train = np.concatenate([train, base + np.arange(len(new_points))])
    fields = {f.name for f in dataclasses.fields(TrainConfig)}
    old = {k: v for k, v in surrogate.header.get("training", {}).items() if k in fields}
    old = {k: tuple(v) if isinstance(v, list) else v for k, v in old.items()}
    config = TrainConfig(**{**old, "seed": seed, "max_epochs": epochs, "patience": epochs})
    result = fit(aug, config, progress=False, split=Split(train, val, test), init=surrogate)
    result.surrogate.header["active_learning"] = {
        "confirmed_designs": len(ok),
        "weight": CONFIRMED_WEIGHT,
        "warm_start_from": surrogate.header.get("sha256", ""),
    }
    return result.surrogate


def _nan(v: Any) -> float:
    return math.nan if v is None else float(v)


# ----------------------------------------------------------------------------- the loop
def optimize(config: OptimizeConfig, out: str | Path, *, progress: bool = True) -> Summary:
    """Run (or resume) a search in ``out``; returns the summary (also written to disk)."""
    from tqdm import tqdm

    from surrogate import load_checkpoint, save_checkpoint

    config.check()
    out = Path(out)
    # a surrogate trained on FE results of another solver version still searches (the shipped
    # one until it is re-made), with a warning: every answer is confirmed by this solver's FE
    surrogate = load_checkpoint(config.surrogate, allow_solver_mismatch=True)
    trained_on = surrogate.header.get("solver_version")
    if trained_on != SOLVER_VERSION:
        print(
            f"warning: the surrogate {config.surrogate} was trained on FE results of solver "
            f"{trained_on}, this is solver {SOLVER_VERSION}: its predictions may be off; the "
            "answers are confirmed with this solver",
            file=sys.stderr,
        )
    space = load_space(config.space) if config.space else surrogate.space
    try:
        check_subspace(space, surrogate.space)
    except ValueError as exc:
        field, _, msg = str(exc).partition(": ")
        raise DesignError(f"space {field}", msg) from None
    build_space, build_note = None, None
    if config.buildable_trials:
        try:
            build_space = catalogue_only(space)
        except ValueError as exc:  # e.g. a core that must be "param"
            build_note = f"no buildable search: {exc}"
    targets = load_targets(config.targets)
    dataset = _find_dataset(config, surrogate)
    options = _sim_options(dataset)
    storage = _prepare(config, out, targets, options)
    t0 = time.perf_counter()
    timings = {"fe_s": 0.0, "search_s": 0.0, "retrain_s": 0.0}

    tic = time.perf_counter()
    run_fe(
        [(out / "fe" / "references" / f"{m}.json", reference_point(m)) for m in REFERENCES],
        options,
        workers=config.workers,
        progress=progress,
        desc="FE references",
    )
    timings["fe_s"] += time.perf_counter() - tic
    confirmations = _load_confirmations(out)
    all_rows: list[TrialRow] = []
    rounds: list[dict[str, Any]] = []
    metric_names = list(surrogate.metric_names)
    for r in range(config.rounds):
        ckpt = out / "surrogates" / f"round-{r}.safetensors"
        if r > 0 and ckpt.exists():
            surrogate = load_checkpoint(ckpt, allow_solver_mismatch=True)
        settings = SearchSettings(
            trials=config.trials,
            mode=config.mode,
            seed=config.seed + r,
            max_disagreement=config.max_disagreement,
        )
        searches = [("continuous", space, config.trials)]
        if build_space is not None:
            searches.append(("buildable", build_space, config.buildable_trials))
        round_rows: dict[str, list[TrialRow]] = {}
        for search, sp, n in searches:
            name = f"{config.study}-r{r}-{search}"
            _add_study(out, name, search, r, config.mode)
            study = create_study(storage, name, dataclasses.replace(settings, trials=n))
            bar = tqdm(total=n, desc=f"round {r + 1}: search {search}", unit="trial",
                       disable=not progress)  # fmt: skip
            bar.update(min(n, _finished(study)))
            tic = time.perf_counter()
            round_rows[search] = run_study(
                study, surrogate, sp, targets, dataclasses.replace(settings, trials=n),
                round_=r, search=search, progress=bar.update, shared=config.storage is not None,
            )  # fmt: skip
            bar.close()
            timings["search_s"] += time.perf_counter() - tic
            all_rows += round_rows[search]
        chosen = _load_candidates(out, r)
        if chosen is None:  # not chosen yet (a resumed run keeps its earlier choice)
            chosen = _choose(round_rows, surrogate, config, confirmations)
            _save_candidates(out, r, chosen)
        tic = time.perf_counter()
        new = confirm(chosen, out, targets, options, workers=config.workers, progress=progress)
        timings["fe_s"] += time.perf_counter() - tic
        known = {c.key for c in confirmations}
        confirmations += [c for c in new if c.key not in known]
        _save_confirmations(out, confirmations)
        info = _round_info(r, new, targets, config.tolerance)
        rounds.append(info)
        write_trials(out, all_rows, space.names, metric_names)
        info["target_met"] = _target_met(confirmations, targets, config.tolerance)
        # done when the surrogate can be trusted AND an FE-confirmed design meets every tapping
        # target; a trusted surrogate whose best design misses searches again (new seed)
        if (info["agreed"] and info["target_met"]) or r == config.rounds - 1:
            break
        if dataset is None:
            rounds[-1]["note"] = "no training data found beside the checkpoint: not retrained"
            break
        nxt = out / "surrogates" / f"round-{r + 1}.safetensors"
        if not nxt.exists():
            if progress:
                print(f"round {r + 1}: retraining the surrogate on {len(confirmations)} FE designs")
            tic = time.perf_counter()
            model = retrain(surrogate, dataset, confirmations, config.retrain_epochs, config.seed)
            timings["retrain_s"] += time.perf_counter() - tic
            nxt.parent.mkdir(parents=True, exist_ok=True)
            save_checkpoint(model, nxt)
    summary = summarise(confirmations, targets, config.tolerance, rounds, all_rows, space)
    if build_note:
        summary.notes.append(build_note)
    summary_json = summary.to_json()
    summary_json["wall_time_s"] = time.perf_counter() - t0  # this invocation (resumes: less)
    summary_json["timings"] = timings
    write_json(out / "summary.json", summary_json)
    return summary


def _choose(
    round_rows: dict[str, list[TrialRow]],
    surrogate,
    config: OptimizeConfig,
    confirmations: list[Confirmation],
) -> list[Candidate]:
    """This round's FE candidates: the best distinct trusted designs, promising flagged ones,
    and the best buildable design; none that earlier rounds confirmed."""
    done = [c.candidate.point for c in confirmations]
    encoder = surrogate.encoder

    def features(pts: list[dict[str, Any]]) -> np.ndarray:
        return encoder.encode(pts).features  # unit-scaled columns + active flags

    chosen = select_candidates(
        round_rows["continuous"], features, best=config.confirm,
        uncertain=config.uncertain, exclude=done,
    )  # fmt: skip
    if "buildable" in round_rows:
        build = select_candidates(
            round_rows["buildable"], features, best=1, uncertain=0,
            exclude=done + [c.point for c in chosen], reason_best="buildable",
        )  # fmt: skip
        if not build:  # every buildable design flagged: FE decides anyway
            flagged = sorted(
                (x for x in round_rows["buildable"] if math.isfinite(x.score)),
                key=lambda x: x.score,
            )
            build = [flagged[0].candidate("buildable")] if flagged else []
        chosen += build
    return chosen


def _candidates_path(out: Path, r: int) -> Path:
    return out / "rounds" / f"round-{r}-candidates.json"


def _load_candidates(out: Path, r: int) -> list[Candidate] | None:
    path = _candidates_path(out, r)
    if not path.exists():
        return None
    return [Candidate.from_json(d) for d in json.loads(path.read_text())]


def _save_candidates(out: Path, r: int, chosen: list[Candidate]) -> None:
    path = _candidates_path(out, r)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_suffix(".tmp")
    tmp.write_text(json.dumps([c.to_json() for c in chosen], indent=1, allow_nan=False))
    tmp.replace(path)


def _target_errors(c: Confirmation, targets: Targets) -> dict[str, float]:
    """FE relative error of a confirmed design against each tapping target."""
    cl = closeness(c.fe_metrics, targets)
    return {m: float(cl.errors[m]) for m in TAPPING}


def _target_met(confirmations: list[Confirmation], targets: Targets, tol: float) -> bool:
    """Whether some trusted FE-confirmed design is within ``tol`` of every tapping target."""
    return any(
        c.trusted and all(abs(e) <= tol for e in _target_errors(c, targets).values())
        for c in confirmations
    )


def _round_info(r: int, new: list[Confirmation], targets: Targets, tol: float) -> dict[str, Any]:
    errs = [
        abs(c.rel_error[targets.metric(m)])
        for c in new
        if c.status == "ok"
        for m in TAPPING
        if c.rel_error.get(targets.metric(m)) is not None
    ]
    ok = [c for c in new if c.status == "ok"]
    return {
        "round": r,
        "n_confirmed": len(new),
        "n_failed": len(new) - len(ok),
        "max_rel_error": max(errs) if errs else None,
        "median_rel_error": float(np.median(errs)) if errs else None,
        "agreed": bool(errs) and max(errs) <= tol,
        "best_fe_score": min((c.fe_score for c in ok), default=None),
    }


# ----------------------------------------------------------------------------- summary
def _answer(c: Confirmation | None, targets: Targets, tol: float, space) -> dict | None:
    if c is None:
        return None
    errors = _target_errors(c, targets)
    return {
        "design": space.design(c.candidate.point).to_dict(),
        "point": c.to_json()["candidate"]["point"],
        "reason": c.candidate.reason,
        "round": c.candidate.round,
        "trusted_by_surrogate": c.candidate.trusted,
        "flags": list(c.candidate.flags),
        "predicted": c.candidate.predicted,
        "predicted_score": c.candidate.score,
        "fe_metrics": c.to_json()["fe_metrics"],
        "fe_score": c.fe_score,
        "errors_vs_targets": errors,
        "within_tolerance": {m: abs(e) <= tol for m, e in errors.items()},
        "diagnostics": c.diagnostics,
        "fe_record": f"fe/records/{c.key}.json",
    }


def summarise(
    confirmations: list[Confirmation],
    targets: Targets,
    tol: float,
    rounds: list[dict[str, Any]],
    rows: list[TrialRow],
    space,
) -> Summary:
    # an unsettled or invalid FE result is never an answer
    ok = [c for c in confirmations if c.trusted and math.isfinite(c.fe_score)]
    best = min(ok, key=lambda c: c.fe_score, default=None)
    buildable = min(
        (c for c in ok if c.candidate.search == "buildable"),
        key=lambda c: c.fe_score,
        default=None,
    )
    answers = {
        "best": _answer(best, targets, tol, space),
        "buildable": _answer(buildable, targets, tol, space),
    }
    notes = _notes(answers, targets, tol, rows)
    return Summary(answers, dict(targets.values), tol, rounds, notes)


def _notes(
    answers: dict[str, dict | None], targets: Targets, tol: float, rows: list[TrialRow]
) -> list[str]:
    """Which target each answer misses, by how much, and what the search says why."""
    if answers.get("best") is None:
        return ["no design was confirmed by FE (every confirmation failed)"]
    notes = []
    for kind, search in (("best", "continuous"), ("buildable", "buildable")):
        answer = answers.get(kind)
        if answer is None:
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
