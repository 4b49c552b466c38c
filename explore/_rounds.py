"""The rounds of a search: each searches the surrogate (one Optuna study per search: the
continuous one, each family's, the catalogue-only one), sends the best distinct trusted designs,
promising flagged ones and the best of each other search to FE, and then stops (the surrogate
agrees with FE and an FE-confirmed design meets every tapping target, or the last round) or
retrains the surrogate on every FE result so far (``explore._retrain``) and searches again.

Resumable: each round's work is read back from its own files (its studies, its candidates, the
FE records, the retrained checkpoint), and each round decides from the confirmations of the
rounds up to it only.
"""

from __future__ import annotations

import dataclasses
import math
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager, nullcontext
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from sim.design import Targets

from ._buildable import fe_screen, predictable_materials, screen_jobs
from ._config import OptimizeConfig, Setup
from ._confirm import REFERENCES, confirm, reference_point, run_fe
from ._objective import TAPPING
from ._retrain import retrain, retrain_epochs
from ._run_folder import (
    add_study,
    read_candidates,
    surrogate_path,
    write_candidates,
    write_confirmations,
    write_time_part,
    write_trials,
)
from ._search import (
    FAMILY_SEARCHES,
    SearchSettings,
    TrialRow,
    _finished,
    create_study,
    family_space,
    run_study,
    select_candidates,
)
from ._summary import credible, target_met
from ._types import Candidate, Confirmation

__all__ = ["Search", "choose", "fe_alongside", "fe_only_screen", "run_rounds", "user_tables"]


@dataclass(eq=False)
class Search:
    """A search in progress: its configuration, run folder and checked inputs, and what its
    rounds have made so far (in order): the confirmations, the scored trials, the rounds' log
    (``Summary.rounds``) and the time spent searching, in FE and retraining (``timings``, of
    this invocation; ``time_part``: its entry of the run folder's time.json, which each stage
    updates as it ends, None for one that records nothing: a finished run re-run; ``started``:
    when it started, ``time.perf_counter``)."""

    config: OptimizeConfig
    out: Path
    setup: Setup
    storage: Any  # an Optuna storage (explore._storage.open_storage) or a database URL
    worker: str | None  # a shared storage: this worker's name (its run folder)
    progress: bool = True
    confirmations: list[Confirmation] = field(default_factory=list)
    rows: list[TrialRow] = field(default_factory=list)
    rounds: list[dict[str, Any]] = field(default_factory=list)
    timings: dict[str, float] = field(
        default_factory=lambda: {"fe_s": 0.0, "search_s": 0.0, "retrain_s": 0.0}
    )
    time_part: int | None = None
    started: float = field(default_factory=time.perf_counter)

    @contextmanager
    def timed(self, what: str) -> Iterator[None]:
        """Count the time of the block in ``timings[what]`` and record it in the run folder
        (:meth:`record_time`), also when the block is interrupted."""
        tic = time.perf_counter()
        try:
            yield
        finally:
            self.timings[what] = self.timings.get(what, 0.0) + time.perf_counter() - tic
            self.record_time()

    def record_time(self) -> None:
        """This invocation's time so far, in its entry of time.json (``time_part``)."""
        if self.time_part is not None:
            write_time_part(
                self.out, self.time_part, time.perf_counter() - self.started, self.timings
            )


#: the priority of the FE beside the rounds (19, the lowest): idle cores only
BACKGROUND_NICE = 19


@contextmanager
def fe_alongside(run: Search) -> Iterator[None]:
    """FE that does not depend on the search, run while the block (the rounds) runs, in one
    background process: silicone and polyurethane on the reference geometry (for the
    figures), then the random stacks of the FE-only screen (``explore._buildable.screen_jobs``).
    The searches and retrainings run on one core and leave the other idle; at the lowest
    priority (``BACKGROUND_NICE``), it takes that core and leaves the rounds' FE alone (at the
    same priority it slowed the first round's FE, the path the rounds wait on, by as much as it
    saved: 199 s in all). When the block ends it has usually finished; if not
    (other work on the machine starved it), it is stopped, the references it did not make are
    run in the foreground (counted as FE time) and the screen makes its own stacks. With one
    worker, or when the records are there already (a resumed run), the references run before
    the block, like any other FE, and the screen's stacks with the screen. The records are the
    same either way: only their timing moves."""
    jobs = [(run.out / "fe" / "references" / f"{m}.json", reference_point(m)) for m in REFERENCES]
    if run.config.workers <= 1 or all(path.exists() for path, _ in jobs):
        with run.timed("fe_s"):
            run_fe(jobs, run.setup.options, workers=1, progress=run.progress,
                   desc="FE references")  # fmt: skip
        yield
        return
    from sim.pool import process_pool, stop_workers

    screen, materials = _screen_jobs(run)
    with process_pool(1, nice=BACKGROUND_NICE) as pool:  # interrupted: its worker stops at once
        future = pool.submit(run_fe, jobs + screen, run.setup.options, workers=1,
                             progress=False, materials=materials)  # fmt: skip
        yield
        with run.timed("fe_s"):
            if future.done():
                future.result()  # its errors, if any
            else:  # starved by other work on the machine: what is left runs in the foreground
                stop_workers(pool)
                run_fe(jobs, run.setup.options, workers=run.config.workers,
                       progress=run.progress, desc="FE references")  # fmt: skip


def _screen_jobs(run: Search) -> tuple[list[tuple[Path, dict[str, Any]]], dict | None]:
    """The FE-only screen's random stacks (``fe_only_screen``), when it will run."""
    s, config = run.setup, run.config
    if not _screen_asked(run):
        return [], None
    return screen_jobs(run.out, s.space, s.catalogue, s.options, budget=config.buildable_fe,
                       seed=config.seed)  # fmt: skip


def _screen_asked(run: Search) -> bool:
    """Whether the FE-only screen runs: it is asked and some catalogue material is one the
    surrogate cannot predict."""
    s, config = run.setup, run.config
    fe_only = set(s.catalogue) - predictable_materials(s.surrogate.space)
    return bool(config.buildable_trials and config.buildable_fe and fe_only)


def run_rounds(run: Search):
    """Every round, as far as it goes; returns the surrogate the last round searched with.

    With two workers or more, a helper process runs a round's other studies (the families'
    and the buildable one) while this one runs the continuous study: a study scores its
    trials on one core, and each study is the same whichever process runs it (its own seed,
    the surrogate read from the same file)."""
    from sim.pool import process_pool

    helper = process_pool(1, spawn=True) if run.config.workers > 1 else None
    with helper or nullcontext():  # interrupted: the helper stops at once (``sim.pool.Pool``)
        return _rounds(run, run.setup.surrogate, helper)


def _rounds(run: Search, surrogate, helper):
    from surrogate import load_surrogate

    for r in range(run.config.rounds):
        path = run.setup.record["surrogate"]
        if r > 0:  # the surrogate retrained after round r - 1, as stored (resumed or not)
            path = str(surrogate_path(run.out, r))
            surrogate = load_surrogate(path, allow_solver_mismatch=True)
        round_rows = _search_round(run, surrogate, r, helper, path)
        new = _confirm_round(run, round_rows, surrogate, r)
        info = _log_round(run, r, new)
        # done when the surrogate can be trusted AND an FE-confirmed design meets every tapping
        # target; a trusted surrogate whose best design misses searches again (new seed)
        if (info["agreed"] and info["target_met"]) or r == run.config.rounds - 1:
            break
        if run.setup.dataset is None:
            info["note"] = "no training data found beside the checkpoint: not retrained"
            break
        _retrain_after(run, surrogate, r)
    return surrogate


def _searches(config: OptimizeConfig, s: Setup) -> list[tuple[str, Any, int]]:
    """A round's searches: (name, space, trials), the continuous one first."""
    # the budget and the rule of credibility setup resolved and config.json records
    searches = [("continuous", s.space, s.record["trials"])]
    for fam in FAMILY_SEARCHES if config.family_trials else ():
        sub = family_space(s.space, fam)
        if sub is not None:
            searches.append((fam, sub, config.family_trials))
    if s.build_space is not None:
        searches.append(("buildable", s.build_space, config.buildable_trials))
    return searches


def _search_round(
    run: Search, surrogate, r: int, helper, surrogate_file: str
) -> dict[str, list[TrialRow]]:
    """Round ``r``'s studies, each run (or resumed) to its trials; their scored trials. With a
    ``helper`` process, it runs every study but the first (the continuous one) meanwhile, with
    the surrogate of ``surrogate_file``."""
    config = run.config
    settings = SearchSettings(
        trials=run.setup.record["trials"],
        mode=config.mode,
        seed=config.seed + r,
        max_disagreement=config.max_disagreement,
        allow_untrusted=config.allow_untrusted,
        trust_bound=run.setup.record["credible_at"] == "bound",
        options=run.setup.options,
        screen=config.screen,
    )
    searches = _searches(config, run.setup)
    for search, _, _ in searches:  # studies.json (written here only) in the rounds' order
        add_study(run.out, _study_name(run, r, search), search, r, config.mode)
    elsewhere = {}
    if helper is not None:
        for search, space, n in searches[1:]:
            name = _study_name(run, r, search)
            elsewhere[search] = helper.submit(
                _study_elsewhere, run.setup.record["storage"], surrogate_file, name, space,
                run.setup.targets, dataclasses.replace(settings, trials=n), r, search, run.worker,
            )  # fmt: skip
    round_rows: dict[str, list[TrialRow]] = {}
    for search, space, n in searches:  # in this order, wherever they ran
        if search in elsewhere:
            with run.timed("search_s"):  # the wait for the helper
                rows = elsewhere[search].result()
        else:
            rows = _study(run, surrogate, r, search, space, dataclasses.replace(settings, trials=n))
        round_rows[search] = rows
        run.rows += rows
    return round_rows


def _study_name(run: Search, r: int, search: str) -> str:
    return f"{run.config.study}-r{r}-{search}"


#: the helper process's surrogates, by checkpoint file (loaded once per run and round)
_SURROGATES: dict[str, Any] = {}


def _study_elsewhere(
    storage: str,
    surrogate_file: str,
    name: str,
    space,
    targets: Targets,
    settings: SearchSettings,
    r: int,
    search: str,
    worker: str | None,
) -> list[TrialRow]:
    """A study run (or resumed) in the helper process, as ``_study`` runs it, without a bar."""
    from surrogate import load_surrogate

    from ._storage import open_storage

    if surrogate_file not in _SURROGATES:
        _SURROGATES[surrogate_file] = load_surrogate(surrogate_file, allow_solver_mismatch=True)
    study = create_study(open_storage(storage), name, settings, worker)
    surrogate = _SURROGATES[surrogate_file]
    return _run_round_study(study, surrogate, space, targets, settings, r, search, worker)


def _run_round_study(
    study,
    surrogate,
    space,
    targets: Targets,
    settings: SearchSettings,
    r: int,
    search: str,
    worker: str | None,
    progress: Callable[[int], None] | None = None,
) -> list[TrialRow]:
    """``run_study`` of round ``r``'s study ``search``, in either process."""
    return run_study(
        study, surrogate, space, targets, settings, round_=r, search=search, progress=progress,
        shared=worker is not None, worker=worker,
    )  # fmt: skip


def _study(
    run: Search, surrogate, r: int, search: str, space, settings: SearchSettings
) -> list[TrialRow]:
    """One study of round ``r`` (registered in the run folder by ``_search_round``), with its
    bar."""
    from tqdm import tqdm

    study = create_study(run.storage, _study_name(run, r, search), settings, run.worker)
    total = settings.trials + (settings.screen_keep if settings.screen else 0)  # seeds + sampled
    bar = tqdm(total=total, desc=f"round {r + 1}: search {search}", unit="trial",
               disable=not run.progress)  # fmt: skip
    bar.update(min(total, _finished(study)))
    with run.timed("search_s"):
        rows = _run_round_study(study, surrogate, space, run.setup.targets, settings, r, search,
                                run.worker, progress=bar.update)  # fmt: skip
        # the bar ends at the work done: a screen that kept fewer seeds, or a shared study
        # the other workers filled, makes it differ from the planned total
        bar.total = bar.n
        bar.close()
    return rows


def _confirm_round(
    run: Search, round_rows: dict[str, list[TrialRow]], surrogate, r: int
) -> list[Confirmation]:
    """FE of round ``r``'s candidates (chosen once: a resumed run keeps its earlier choice),
    added to the confirmations; the round's own."""
    s = run.setup
    chosen = read_candidates(run.out, r)
    if chosen is None:
        chosen = choose(round_rows, surrogate, run.config, run.confirmations)
        write_candidates(run.out, r, chosen)
    with run.timed("fe_s"):
        new = confirm(
            chosen, run.out, s.targets, s.options, workers=run.config.workers,
            progress=run.progress, materials=user_tables(s.catalogue), catalogue=s.catalogue,
        )  # fmt: skip
    known = {c.key for c in run.confirmations}
    run.confirmations += [c for c in new if c.key not in known]
    write_confirmations(run.out, run.confirmations, final=False)
    return new


def _log_round(run: Search, r: int, new: list[Confirmation]) -> dict[str, Any]:
    """Round ``r``'s entry of the rounds' log (``_round_info`` and ``target_met``), and the
    trials so far in trials.csv."""
    s, tol = run.setup, run.config.tolerance
    info = _round_info(r, new, s.targets, tol, run.config.allow_untrusted)
    run.rounds.append(info)
    write_trials(run.out, run.rows, s.space.names, list(s.surrogate.metric_names), final=False)
    info["target_met"] = target_met(run.confirmations, s.targets, tol)
    return info


def _retrain_after(run: Search, surrogate, r: int) -> None:
    """The surrogate round ``r + 1`` searches with, retrained on every FE result so far (once:
    a resumed run finds it stored, written whole or not at all)."""
    from tqdm import tqdm

    from surrogate import save_surrogate

    nxt = surrogate_path(run.out, r + 1)
    if nxt.exists():
        return
    config = run.config
    with run.timed("retrain_s"):
        label = f"round {r + 2}: retrain on {len(run.confirmations)} FE designs"
        bar = tqdm(total=retrain_epochs(surrogate, config.retrain_epochs), desc=label,
                   unit="epoch", disable=not run.progress)  # fmt: skip
        try:
            # torch's threads leave the core of the FE beside the rounds (``fe_alongside``:
            # one process with two workers or more) alone
            model = retrain(surrogate, run.setup.dataset, run.confirmations,
                            config.retrain_epochs, config.seed, progress=bar.update,
                            batch_size=config.retrain_batch_size,
                            replay=config.retrain_replay,
                            fe_workers=1 if config.workers > 1 else 0)  # fmt: skip
        finally:
            bar.close()
    nxt.parent.mkdir(parents=True, exist_ok=True)
    save_surrogate(model, nxt)  # atomic: a kill never leaves half a checkpoint


def fe_only_screen(run: Search) -> list[Confirmation]:
    """After the rounds: the FE-only screen of buildable stacks of the catalogue materials the
    surrogate cannot predict (``explore._buildable``), when there are such and it is asked."""
    s, config = run.setup, run.config
    if not _screen_asked(run):
        return []
    trusted = [c for c in run.confirmations if credible(c, s.targets, config.allow_untrusted)]
    with run.timed("fe_s"):
        return fe_screen(
            run.out, min(trusted, key=lambda c: c.fe_score, default=None), s.space, s.catalogue,
            s.targets, s.options, budget=config.buildable_fe, seed=config.seed,
            workers=config.workers, progress=run.progress,
        )  # fmt: skip


def choose(
    round_rows: dict[str, list[TrialRow]],
    surrogate,
    config: OptimizeConfig,
    confirmations: list[Confirmation],
) -> list[Candidate]:
    """This round's FE candidates: the best distinct trusted designs, promising flagged ones,
    and the best buildable design; none that earlier rounds confirmed."""
    done = [c.candidate.point for c in confirmations]
    encoder = surrogate.encoder
    # a multi-fidelity encoder appends the 2D surrogate's predictions: distance is the design's
    n_own = getattr(encoder, "n_own", None)

    def features(pts: list[dict[str, Any]]) -> np.ndarray:
        return encoder.encode(pts).features[:, :n_own]  # unit-scaled columns + active flags

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


def _round_info(
    r: int, new: list[Confirmation], targets: Targets, tol: float, allow_untrusted: bool = False
) -> dict[str, Any]:
    """How round ``r``'s FE results ``new`` compare with the surrogate's predictions, and the
    FE score of its best credible design (``best_fe_score``; None: the round confirmed no
    credible design, e.g. each went beyond the validity limits: a normal outcome)."""
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
        "best_fe_score": min(
            (c.fe_score for c in new if credible(c, targets, allow_untrusted)), default=None
        ),
    }


def user_tables(catalogue: dict) -> dict | None:
    """The user materials of a merged catalogue as tables, for the FE worker processes."""
    from sim.materials import material_tables, user_materials

    return material_tables(user_materials(catalogue)) or None
