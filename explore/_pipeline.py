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

import dataclasses
import json
import math
import socket
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from sim.errors import DesignError
from sim.metrics import SOLVER_VERSION, same_metrics
from sim.options import SimOptions
from sim.provenance import (
    check_folder_kind,
    nan_if_none,
    provenance,
)
from sim.space import load_space, point_to_design
from sim.sweep import default_workers
from sim.targets import READINGS, Targets, load_targets

from ._buildable import (
    DEFAULT_FE_BUDGET,
    FE_SEARCH,
    fe_screen,
    material_notes,
    predictable_materials,
    screen_summary,
)
from ._confirm import REFERENCES, confirm, reference_point, run_fe
from ._objective import TAPPING, closeness
from ._run_folder import (
    add_study,
    read_candidates,
    read_config,
    write_candidates,
    write_config,
    write_confirmations,
    write_summary,
    write_trials,
)
from ._search import (
    FAMILY_SEARCHES,
    SearchSettings,
    TrialRow,
    _finished,
    catalogue_only,
    check_subspace,
    create_study,
    design_family,
    family_space,
    run_study,
    select_candidates,
)
from ._sensitivity import sensitivity_notes
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
    ``max_disagreement``: the trust guard's limit on the ensemble's std/|mean|; ``workers``: FE
    processes (``sim.sweep.default_workers``: one per usable core), which never change the
    answer, so a run may be resumed with another number of them; ``catalogues``: the user's
    ``--catalogue`` files (recorded with their sha256; a resume with others is refused);
    ``buildable_fe``: buildable stacks of the merged catalogue simulated by FE only, for the
    materials the surrogate cannot predict (``explore._buildable``); ``family_trials``:
    surrogate evaluations per round of each family's own study (gel only, foam core:
    ``explore._search.family_space``), whose best design is confirmed too; ``allow_untrusted``:
    let designs that are not credible (an FE result beyond the validity limits or unsettled,
    or a sag over the targets' limit) compete for the answers, flagged as such; ``screen``:
    designs of a quasi-random sample the surrogate scores at the start of every study, whose
    best (``SearchSettings.screen_keep``) seed the sampler (``explore._search.screen``), so
    ``trials`` counts the sampler's trials after them.
    """

    surrogate: str = str(DEFAULT_CHECKPOINT)
    space: str | None = None
    targets: str | None = None
    # after the screen's 64 seeds: 128 TPE trials found a better design than 1000 TPE trials
    # alone, in a tenth of the time (benchmarks/bench_search.py, README "Search"); families
    # and the buildable search, smaller spaces, take half
    trials: int = 128
    buildable_trials: int = 64
    confirm: int = 3
    uncertain: int = 1
    rounds: int = 3
    tolerance: float = 0.05
    mode: str = "single"
    max_disagreement: float = 0.10
    storage: str | None = None
    study: str = "fingertip"
    seed: int = 0
    workers: int = field(default_factory=default_workers)
    dataset: str | None = None
    retrain_epochs: int = 150
    catalogues: tuple[str, ...] = ()
    buildable_fe: int = DEFAULT_FE_BUDGET
    family_trials: int = 64
    allow_untrusted: bool = False
    # 2^16 designs: ~2-3 s per study at the surrogate's ~65 000 designs/s on one thread
    # (benchmarks/bench_predict.py), so a round of four studies stays within 30 s (issue 15)
    screen: int = 65536

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
        at_least("buildable_fe", self.buildable_fe, 0)
        at_least("family_trials", self.family_trials, 0)
        at_least("screen", self.screen, 0)
        if self.mode not in ("single", "multi"):
            raise DesignError("--mode", f"must be single or multi, got {self.mode!r}")
        for name in ("tolerance", "max_disagreement"):
            v = getattr(self, name)
            if not 0 < v < 1:
                raise DesignError(f"--{name.replace('_', '-')}", f"must be in (0, 1), got {v}")


# ----------------------------------------------------------------------------- run folder
#: configuration entries that never change the answer: a run may be resumed with others
_FREE = ("workers", "studies")


def _record(config: OptimizeConfig, out: Path, targets: Targets, options: SimOptions) -> dict:
    """What config.json holds (without the studies, added as they start)."""
    record = {
        **dataclasses.asdict(config),
        "sim_options": dataclasses.asdict(options),
        "storage": _storage_url(config, out),
        "targets": dict(targets.values),
        "displacement_reading": targets.reading,
        "max_sag_mm": targets.max_sag_mm,
    }
    return json.loads(json.dumps(record))  # as config.json holds it (lists, not tuples)


def _storage_url(config: OptimizeConfig, out: Path) -> str:
    return config.storage or f"sqlite:///{(out / 'study.db').resolve()}"


def _check_resume(out: Path, record: dict) -> None:
    """A run folder is resumed only with the configuration it was made with (``_FREE`` aside)."""
    old = read_config(out)
    if old is None:
        return
    keys = sorted((set(old) | set(record)) - set(_FREE))
    diff = [k for k in keys if old.get(k) != record.get(k)]
    if diff:
        raise DesignError(
            "--out",
            f"{out} holds a run with another configuration ({', '.join(diff)}); "
            "use another --out or the same options to resume",
        )


def _prepare(config: OptimizeConfig, out: Path, record: dict) -> str:
    """Create the run folder (a resumed one is left as it is); returns the storage URL."""
    if not (out / "config.json").exists():
        write_config(out, record, provenance(record, config.seed, kind="optimize"))
    return record["storage"]


def check_storage(url: str) -> None:
    """Open the Optuna storage ``url`` once (creating its tables if needed), or refuse it in one
    line naming ``--storage``: checked before any FE work or folder is made. Workers starting
    together on a new database race to create its tables: the losers try again."""
    import optuna
    from sqlalchemy.engine import make_url
    from sqlalchemy.exc import ArgumentError, IntegrityError, ProgrammingError, SQLAlchemyError

    example = "e.g. sqlite:///path/study.db or postgresql+psycopg://user:password@host/database"
    try:
        make_url(url)
    except ArgumentError:
        raise DesignError("--storage", f"{url!r} is not a database URL ({example})") from None
    optuna.logging.set_verbosity(optuna.logging.WARNING)
    for attempt in range(5):
        try:
            storage = optuna.storages.RDBStorage(url)
            break
        except (IntegrityError, ProgrammingError) as exc:  # another worker's table or type
            if attempt == 4:
                raise DesignError("--storage", f"cannot open {url}: {_first_line(exc)}") from None
            time.sleep(0.2 * (attempt + 1))
        except (SQLAlchemyError, ImportError, ValueError, OSError, RuntimeError) as exc:
            raise DesignError("--storage", f"cannot open {url}: {_first_line(exc)}") from None
    storage.remove_session()
    storage.engine.dispose()


def _first_line(exc: BaseException) -> str:
    return (str(exc).strip().splitlines() or [type(exc).__name__])[0]


def check_inputs(config: OptimizeConfig, out: str | Path) -> Targets:
    """Everything a search can check without its surrogate, before any work: the options, the
    run folder (absent, empty or a search run's), the targets file, the ``--catalogue`` files
    and the space file (the storage URL: ``check_storage``). Returns the targets.
    ``fingertip run --from-scratch`` calls it before its sweep; ``optimize`` calls it first."""
    config.check()
    out = Path(out)
    check_folder_kind(out, "optimize")
    read_config(out)
    targets = load_targets(config.targets)
    from sim.materials import load_user_catalogues

    catalogue = load_user_catalogues(config.catalogues)[1]  # the --catalogue files, checked
    if config.space:
        load_space(config.space, catalogue)
    return targets


# ----------------------------------------------------------------------------- active learning
def _find_dataset(config: OptimizeConfig, surrogate) -> Path | None:
    """The surrogate's training sweep: --dataset, the checkpoint's folder (a shipped checkpoint
    carries its table.csv), or the sweep named in its header, whichever holds the table whose
    sha256 the header records."""
    from sim import _sweep_folder as sweep_folder
    from surrogate._io import sha256_file

    want = surrogate.header.get("training_data", {}).get("table_sha256")
    places = [config.dataset, str(Path(config.surrogate).parent),
              surrogate.header.get("training_data", {}).get("sweep")]  # fmt: skip
    for p in places:
        if not p:
            continue
        table = Path(p) / sweep_folder.TABLE
        if table.exists() and (Path(p) / sweep_folder.CONFIG).exists():
            if config.dataset or sha256_file(table) == want:
                return Path(p)
    return None


def _sim_options(dataset: Path | None) -> SimOptions:
    """The FE options of the surrogate's training sweep (so FE confirms like with like), else
    the defaults."""
    from sim._sweep_folder import read_config as read_sweep_config
    from sim.options import options_from_dict

    if dataset is None:
        return SimOptions()
    cfg = read_sweep_config(dataset)
    return options_from_dict(cfg["options"]) if "options" in cfg else SimOptions()


def retrain(
    surrogate,
    dataset: Path,
    confirmed: list[Confirmation],
    epochs: int,
    seed: int,
    progress: Callable[[int], None] | None = None,
):
    """Warm-started retraining on the training sweep plus the FE-confirmed designs;
    ``progress`` is called with the number of epochs done since its last call."""
    from sim.trust import TRUST_OUTPUTS, trust_values
    from surrogate import read_sweep
    from surrogate._train import Split, TrainConfig, fit

    data = read_sweep(dataset)
    names = list(data.metric_names)
    # an unsettled or invalid result teaches no metric, but it does teach what made it so
    # (the trust outputs, when the surrogate learns them), as in ``read_sweep``
    learns_trust = set(TRUST_OUTPUTS) <= set(names)
    ok = [c for c in confirmed if c.trusted or (learns_trust and c.status == "ok")]

    def target_row(c: Confirmation) -> list[float]:
        trust = trust_values({**c.diagnostics, "status": c.status})
        return [
            trust[m] if m in trust else nan_if_none(c.fe_metrics.get(m)) if c.trusted else math.nan
            for m in names
        ]

    new_points = [c.candidate.point for c in ok for _ in range(CONFIRMED_WEIGHT)]
    new_targets = np.array([target_row(c) for c in ok for _ in range(CONFIRMED_WEIGHT)]).reshape(
        -1, len(names)
    )
    base = len(data.points)
    aug = dataclasses.replace(  # the sweep's own fields (its space, solver, tap frequency...)
        data,
        points=[*data.points, *new_points],
        targets=np.vstack([data.targets, new_targets]),
        index=np.concatenate([data.index, -1 - np.arange(len(new_points))]),
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
    result = fit(aug, config, progress=progress or False, split=Split(train, val, test),
                 init=surrogate)  # fmt: skip
    result.surrogate.header["active_learning"] = {
        "confirmed_designs": len(ok),
        "weight": CONFIRMED_WEIGHT,
        "warm_start_from": surrogate.header.get("sha256", ""),
    }
    return result.surrogate


# ----------------------------------------------------------------------------- the loop
@dataclass(frozen=True)
class _Setup:
    """The checked inputs of a search (``_setup``)."""

    surrogate: Any
    space: Any
    build_space: Any
    build_note: str | None
    targets: Targets
    dataset: Path | None
    options: SimOptions
    record: dict
    catalogue: dict = field(default_factory=dict)  # shipped + user materials, by name


def _setup(config: OptimizeConfig, out: Path) -> _Setup:
    """Check every input before any work and before the run folder is made: the options, the
    folder, the targets, the space (inside the surrogate's), the configuration of a resumed
    run, the storage URL."""
    from surrogate import load_checkpoint

    targets = check_inputs(config, out)
    # a surrogate trained on FE results of another solver version still searches (the shipped
    # one until it is re-made), with a warning: every answer is confirmed by this solver's FE
    surrogate = load_checkpoint(config.surrogate, allow_solver_mismatch=True)
    user, catalogue = _catalogues(config, surrogate.space)
    space = load_space(config.space, catalogue) if config.space else surrogate.space
    try:
        check_subspace(space, surrogate.space)
    except ValueError as exc:
        name, _, msg = str(exc).partition(": ")
        raise DesignError(f"space {name}", msg) from None
    build_space, build_note = None, None
    if config.buildable_trials:
        try:
            build_space = catalogue_only(space)
        except ValueError as exc:  # e.g. a core that must be "param"
            build_note = f"no buildable search: {exc}"
    dataset = _find_dataset(config, surrogate)
    options = _sim_options(dataset)
    record = _record(config, out, targets, options)
    record.pop("catalogues")  # the files by content, and only when given (older runs: none)
    if user:
        record["catalogues"] = [c.record() for c in user]
    _check_resume(out, record)
    if config.storage is not None:
        check_storage(config.storage)
    return _Setup(
        surrogate, space, build_space, build_note, targets, dataset, options, record, catalogue
    )


def _catalogues(config: OptimizeConfig, trained) -> tuple[tuple, dict]:
    """The ``--catalogue`` files and the merged catalogue: shipped, the user materials the
    surrogate's space holds (it was trained on them) and the files' (a name must mean one
    material)."""
    from sim.materials import load_user_catalogues

    user, catalogue = load_user_catalogues(config.catalogues)
    for mat in trained.materials:
        name = str(mat.name)
        if name in catalogue and catalogue[name] != mat:
            raise DesignError(
                "--catalogue",
                f"material {name!r} differs from the one the surrogate was trained on; rename it",
            )
        catalogue[name] = mat
    return user, catalogue


def optimize(config: OptimizeConfig, out: str | Path, *, progress: bool = True) -> Summary:
    """Run (or resume) a search in ``out``; returns the summary (also written to disk).

    Resumable at any point, with the same answer as an uninterrupted run: what each round has
    done is read from its own files (its studies, ``rounds/round-<r>-candidates.json``, the FE
    records, ``surrogates/round-<r+1>.safetensors``), and each round decides from the
    confirmations of the rounds up to it only. A finished run re-run computes and rewrites
    nothing (``summary.json`` keeps the first run's ``wall_time_s``)."""
    from tqdm import tqdm

    from surrogate import load_checkpoint, save_checkpoint

    out = Path(out)
    s = _setup(config, out)
    trained_on = s.surrogate.header.get("solver_version")
    if not same_metrics(trained_on):
        print(
            f"warning: the surrogate {config.surrogate} was trained on FE results of solver "
            f"{trained_on}, this is solver {SOLVER_VERSION}: its predictions may be off; the "
            "answers are confirmed with this solver",
            file=sys.stderr,
        )
    resumed = (out / "config.json").exists()
    storage = _prepare(config, out, s.record)
    # a shared storage: this worker is its run folder (resumed, it finds its trials again)
    worker = None if config.storage is None else f"{socket.gethostname()}:{out.resolve()}"
    targets, space, options, dataset = s.targets, s.space, s.options, s.dataset
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
    confirmations: list[Confirmation] = []  # those of the rounds so far, in order
    all_rows: list[TrialRow] = []
    rounds: list[dict[str, Any]] = []
    surrogate = s.surrogate
    metric_names = list(surrogate.metric_names)
    for r in range(config.rounds):
        if r > 0:  # the surrogate retrained after round r - 1, as stored (resumed or not)
            ckpt = out / "surrogates" / f"round-{r}.safetensors"
            surrogate = load_checkpoint(ckpt, allow_solver_mismatch=True)
        settings = SearchSettings(
            trials=config.trials,
            mode=config.mode,
            seed=config.seed + r,
            max_disagreement=config.max_disagreement,
            allow_untrusted=config.allow_untrusted,
            options=options,
            screen=config.screen,
        )
        searches = [("continuous", space, config.trials)]
        for fam in FAMILY_SEARCHES if config.family_trials else ():
            sub = family_space(space, fam)
            if sub is not None:
                searches.append((fam, sub, config.family_trials))
        if s.build_space is not None:
            searches.append(("buildable", s.build_space, config.buildable_trials))
        round_rows: dict[str, list[TrialRow]] = {}
        for search, sp, n in searches:
            name = f"{config.study}-r{r}-{search}"
            add_study(out, name, search, r, config.mode)
            study = create_study(storage, name, dataclasses.replace(settings, trials=n), worker)
            total = n + (settings.screen_keep if settings.screen else 0)  # seeds + sampled
            bar = tqdm(total=total, desc=f"round {r + 1}: search {search}", unit="trial",
                       disable=not progress)  # fmt: skip
            bar.update(min(total, _finished(study)))
            tic = time.perf_counter()
            round_rows[search] = run_study(
                study, surrogate, sp, targets, dataclasses.replace(settings, trials=n),
                round_=r, search=search, progress=bar.update, shared=worker is not None,
                worker=worker,
            )  # fmt: skip
            bar.close()
            timings["search_s"] += time.perf_counter() - tic
            all_rows += round_rows[search]
        chosen = read_candidates(out, r)
        if chosen is None:  # not chosen yet (a resumed run keeps its earlier choice)
            chosen = _choose(round_rows, surrogate, config, confirmations)
            write_candidates(out, r, chosen)
        tic = time.perf_counter()
        new = confirm(
            chosen, out, targets, options, workers=config.workers, progress=progress,
            materials=_user_tables(s.catalogue), catalogue=s.catalogue,
        )  # fmt: skip
        timings["fe_s"] += time.perf_counter() - tic
        known = {c.key for c in confirmations}
        confirmations += [c for c in new if c.key not in known]
        write_confirmations(out, confirmations, final=False)
        info = _round_info(r, new, targets, config.tolerance)
        rounds.append(info)
        write_trials(out, all_rows, space.names, metric_names, final=False)
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
            tic = time.perf_counter()
            label = f"round {r + 2}: retrain on {len(confirmations)} FE designs"
            bar = tqdm(total=config.retrain_epochs, desc=label, unit="epoch",
                       disable=not progress)  # fmt: skip
            try:
                model = retrain(surrogate, dataset, confirmations, config.retrain_epochs,
                                config.seed, progress=bar.update)  # fmt: skip
            finally:
                bar.close()
            timings["retrain_s"] += time.perf_counter() - tic
            nxt.parent.mkdir(parents=True, exist_ok=True)
            save_checkpoint(model, nxt)  # atomic: a kill never leaves half a checkpoint
    write_confirmations(out, confirmations, final=True)
    write_trials(out, all_rows, space.names, metric_names, final=True)
    screen = []
    fe_only = set(s.catalogue) - predictable_materials(s.surrogate.space)
    if config.buildable_trials and config.buildable_fe and fe_only:  # unpredictable stacks
        trusted = [c for c in confirmations if credible(c, targets, config.allow_untrusted)]
        tic = time.perf_counter()
        screen = fe_screen(
            out, min(trusted, key=lambda c: c.fe_score, default=None), space, s.catalogue,
            targets, options, budget=config.buildable_fe, seed=config.seed,
            workers=config.workers, progress=progress,
        )  # fmt: skip
        timings["fe_s"] += time.perf_counter() - tic
    summary = summarise(
        confirmations + screen, targets, config.tolerance, rounds, all_rows, space,
        catalogue=s.catalogue, allow_untrusted=config.allow_untrusted, surrogate=surrogate,
    )  # fmt: skip
    if screen:
        summary.notes.append(screen_summary(screen, len(s.catalogue)))
    if s.build_note:
        summary.notes.append(s.build_note)
    write_summary(out, summary, time.perf_counter() - t0, timings, resumed)
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
    for search in (*FAMILY_SEARCHES, "buildable"):  # the best of each family's own search
        if search not in round_rows:
            continue
        best = select_candidates(
            round_rows[search], features, best=1, uncertain=0,
            exclude=done + [c.point for c in chosen], reason_best=search,
        )  # fmt: skip
        if not best:  # every design of the family flagged: FE decides anyway
            flagged = sorted(
                (x for x in round_rows[search] if math.isfinite(x.score)),
                key=lambda x: x.score,
            )
            best = [flagged[0].candidate(search)] if flagged else []
        chosen += best
    return chosen


def _target_errors(c: Confirmation, targets: Targets) -> dict[str, float]:
    """FE relative error of a confirmed design against each tapping target."""
    cl = closeness(c.fe_metrics, targets)
    return {m: float(cl.errors[m]) for m in TAPPING}


def _target_met(confirmations: list[Confirmation], targets: Targets, tol: float) -> bool:
    """Whether some credible FE-confirmed design is within ``tol`` of every tapping target."""
    return any(
        credible(c, targets) and all(abs(e) <= tol for e in _target_errors(c, targets).values())
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
def _answer(
    c: Confirmation | None, targets: Targets, tol: float, space, catalogue=None
) -> dict | None:
    if c is None:
        return None
    errors = _target_errors(c, targets)
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


#: the answers of a run, in report order: kind -> what the design must be (``design_family``)
ANSWER_KINDS = {"best": None, "gel": "gel", "foam": "foam", "buildable": "catalogue"}


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


def _user_tables(catalogue: dict) -> dict | None:
    """The user materials of a merged catalogue as tables, for the FE worker processes."""
    from sim.materials import material_tables, user_materials

    return material_tables(user_materials(catalogue)) or None


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
