"""``fingertip optimize`` and ``fingertip run``: search -> FE confirmation -> active learning
-> summary, resumable in a run folder (its files: ``explore._run_folder``).

One round: an Optuna study searches the surrogate over the design space ("continuous") and
others over each family's part of it and over catalogue materials only ("buildable"); the best
distinct trusted designs, one or more promising-but-uncertain ones and the best of each other
search are simulated with full FE; the round's surrogate-vs-FE errors decide whether to stop
(all tapping metrics within ``tolerance`` on every confirmed design, and a design within it of
every tapping target) or to retrain the surrogate, warm-started, on its training data plus
every FE result so far, and search again. The answer is always an FE result: the best confirmed
design and the best confirmed design of each family (``summary.json``).

The jobs, one module each: the configuration and the checks of every input before any work
(``explore._config``), the rounds (``explore._rounds``), the retraining
(``explore._retrain``), the answer and its notes (``explore._summary``), the run folder's files
(``explore._run_folder``). Here: the whole pipeline, from the inputs to the ``Summary``
(:func:`optimize`), after a sweep and a training for ``fingertip run --from-scratch``
(:func:`run`), and the answers as design files (:func:`write_answer_files`: every run writes
them at its end; ``fingertip report`` writes them for an existing run folder).
"""

from __future__ import annotations

import dataclasses
import socket
import sys
import time
from collections.abc import Mapping
from pathlib import Path

from sim.errors import DesignError
from sim.metrics import SOLVER_VERSION, same_metrics
from sim.provenance import check_folder_kind, provenance

from ._buildable import screen_summary
from ._config import OptimizeConfig, Setup, check_inputs, check_storage, setup
from ._rounds import Search, fe_alongside, fe_only_screen, run_rounds
from ._run_folder import (
    CONFIG,
    SUMMARY,
    read_config,
    read_meta,
    read_summary,
    run_time,
    time_parts,
    write_answers,
    write_config,
    write_confirmations,
    write_summary,
    write_trials,
)
from ._storage import is_database_url, open_storage, repair_journal
from ._summary import ANSWER_KINDS, answer_file_text, summarise
from ._types import Summary

__all__ = ["optimize", "run", "scratch_folders", "write_answer_files"]


def optimize(
    config: OptimizeConfig,
    out: str | Path,
    *,
    progress: bool = True,
    stages: Mapping[str, float] | None = None,
) -> Summary:
    """Run (or resume) a search in ``out``; returns the summary (also written to disk, with
    the run's timing: ``Summary.timing``, every invocation that worked on it summed, from the
    run folder's time.json). ``stages``: seconds this invocation spent before the search, by
    stage (``run --from-scratch``: ``sweep_s``, ``train_s``), counted in the run's time.

    Resumable at any point, with the same answer as an uninterrupted run: what each round has
    done is read from its own files (its studies, ``rounds/round-<r>-candidates.json``, the FE
    records, ``surrogates/round-<r+1>.safetensors``), and each round decides from the
    confirmations of the rounds up to it only. A finished run re-run computes and rewrites
    nothing (``summary.json`` keeps its ``wall_time_s``; time.json gets no part for it)."""
    out = Path(out)
    s = setup(config, out)
    _warn_of_another_solver(config, s)
    _note_validity_override(s)
    resumed = (out / CONFIG).exists()
    if not resumed:
        write_config(out, s.record, provenance(s.record, config.seed, kind="optimize"))
    # a shared storage: this worker is its run folder (resumed, it finds its trials again)
    worker = None if config.storage is None else f"{socket.gethostname()}:{out.resolve()}"
    search = Search(config, out, s, _open_own_storage(config, s.record["storage"]), worker,
                    progress)  # fmt: skip
    search.timings.update(stages or {})
    search.started -= sum((stages or {}).values())
    if not (out / SUMMARY).is_file():  # a finished run re-run adds no part to its time
        search.time_part = time_parts(out)
    with fe_alongside(search):
        surrogate = run_rounds(search)
    write_confirmations(out, search.confirmations, final=True)
    write_trials(out, search.rows, s.space.names, list(s.surrogate.metric_names), final=True)
    screen = fe_only_screen(search)
    summary = summarise(
        search.confirmations + screen, s.targets, config.tolerance, search.rounds, search.rows,
        s.space, catalogue=s.catalogue, allow_untrusted=config.allow_untrusted,
        surrogate=surrogate,
    )  # fmt: skip
    if screen:
        summary.notes.append(screen_summary(screen, len(s.catalogue)))
    if s.build_note:
        summary.notes.append(s.build_note)
    search.record_time()
    wall_time_s, timings = run_time(out)
    timing = write_summary(out, summary, wall_time_s, timings, resumed)
    write_answer_files(out)
    if config.model == "3d" and s.model == "2d":  # 2D answers, each simulated in 3D too
        from ._check3d import check_in_3d, options_3d
        from ._rounds import user_tables

        check_in_3d(
            out, s.targets, options_3d(s.options), tolerance=config.tolerance,
            workers=config.workers, progress=progress, materials=user_tables(s.catalogue),
            catalogue=s.catalogue,
        )  # fmt: skip
    return dataclasses.replace(summary, timing=timing)


def write_answer_files(out: str | Path) -> list[Path]:
    """Write ``answers/<name>.toml`` for every answer of the run folder's summary.json (an
    old folder's too; none before its summary is written): each a design file that
    ``fingertip simulate`` and ``fingertip predict`` read as it is, its header naming the
    answer, its FE score, the run's command and the ``--set`` options its FE ran with (when not
    the defaults). Files whose text is unchanged are left alone. Returns the files."""
    out = Path(out)
    summary = read_summary(out)
    answers = summary.get("answers") if isinstance(summary, dict) else None
    if not isinstance(answers, dict):
        return []
    config = read_config(out) or {}
    reading = config.get("displacement_reading")
    raw_targets = config.get("targets") or {}
    if isinstance(raw_targets, dict) and reading is None:
        reading = raw_targets.get("displacement_reading")
    texts: dict[str, str | None] = {}
    for kind in (*ANSWER_KINDS, *(k for k in answers if k not in ANSWER_KINDS)):
        answer = answers.get(kind)
        if not isinstance(answer, dict) or not isinstance(answer.get("design"), dict):
            texts[kind] = None
            continue
        texts[kind] = answer_file_text(
            kind,
            answer,
            run_name=out.resolve().name,
            made_by=_command(read_meta(out).get("command")),
            reading=reading or "from_undeformed_top",
            tolerance=summary.get("tolerance"),
            option_overrides=_option_overrides(config.get("sim_options")),
        )
    return write_answers(out, texts)


def _command(command: object) -> str | None:
    """A run's recorded command line (meta.json) with the program's name only
    (``/venv/bin/fingertip run ...`` -> ``fingertip run ...``)."""
    if not isinstance(command, str) or not command.strip():
        return None
    program, *rest = command.split(" ")
    return " ".join([Path(program).name, *rest])


def _option_overrides(recorded: object) -> list[str]:
    """The ``--set section.field=value`` options that give the simulation options a run
    recorded (config.json's ``sim_options``), from the defaults: none when they are the
    defaults (or not recorded)."""
    from sim.options import SimOptions, options_from_dict

    if not isinstance(recorded, Mapping):
        return []
    run, base = options_from_dict(dict(recorded)), SimOptions()
    out = []
    for section in dataclasses.fields(base):
        ours, default = getattr(run, section.name), getattr(base, section.name)
        for f in dataclasses.fields(ours):
            value = getattr(ours, f.name)
            if value != getattr(default, f.name):
                out.append(f"{section.name}.{f.name}={value}")
    return out


def _warn_of_another_solver(config: OptimizeConfig, s: Setup) -> None:
    """A surrogate trained on FE results of another solver version still searches (the
    shipped one until it is re-made), with a warning: every answer is confirmed by this
    solver's FE."""
    trained_on = s.surrogate.header.get("solver_version")
    if not same_metrics(trained_on):
        print(
            f"warning: the surrogate {config.surrogate} was trained on FE results of solver "
            f"{trained_on}, this is solver {SOLVER_VERSION}: its predictions may be off; the "
            "answers are confirmed with this solver",
            file=sys.stderr,
        )


def _note_validity_override(s: Setup) -> None:
    """The FE confirms with the training sweep's options (like with like): a sweep made with a
    validity override (the shipped surrogate's, made before the per-layer limits) holds every
    layer of every confirmation to it; said on stderr and in report.md."""
    for option, value in s.options.validity.overridden.items():
        print(
            f"note: the surrogate's training sweep ran with validity.{option}={value:g}, so "
            f"this search's FE holds every layer to {value:g} too, not to the limit its "
            "material was tested to (a surrogate trained on a sweep without it lifts this)",
            file=sys.stderr,
        )


def _open_own_storage(config: OptimizeConfig, spec: str):
    """The Optuna storage of the run: a journal the run folder owns is first repaired of what a
    kill may have left (``repair_journal``: only its writer may do that)."""
    if config.storage is None and not is_database_url(spec):
        done = repair_journal(Path(spec))
        if done is not None:
            print(f"note: {spec}: {done} (left by a killed run)", file=sys.stderr)
    return open_storage(spec)


def scratch_folders(out: str | Path) -> tuple[Path, Path]:
    """The sweep and training folders of ``run --from-scratch`` beside the run folder ``out``:
    ``<out>-sweep`` and ``<out>-surrogate``."""
    out = Path(out)
    return out.parent / f"{out.name}-sweep", out.parent / f"{out.name}-surrogate"


def run(
    config: OptimizeConfig,
    out: str | Path,
    *,
    from_scratch: int | None = None,
    progress: bool = True,
) -> Summary:
    """``fingertip run``: :func:`optimize`, or with ``from_scratch`` (a number of designs) the
    whole pipeline: a sweep of the default space (``from_scratch`` designs, seed 0) and a
    surrogate trained on it (seed 0), in :func:`scratch_folders`, then the search with them
    (``config``'s ``surrogate`` and ``dataset`` replaced). Every input is checked before the
    sweep; a resumed run finds its sweep and its surrogate done."""
    if from_scratch is None:
        return optimize(config, out, progress=progress)
    from sim.design import load_space
    from sim.sweep import run_sweep
    from surrogate import CHECKPOINT_NAME, train_surrogate

    if config.model == "3d":  # the 3D dataset is days of one core: datasets/README.md
        raise DesignError(
            "--model",
            "3d cannot start --from-scratch: the sweep and training made from scratch are the "
            "2D model's; the 3D search starts from the shipped multi-fidelity surrogate (leave "
            "--from-scratch out) or one trained on a 3D sweep (datasets/README.md)",
        )
    sweep, trained = scratch_folders(out)
    # every input is checked before hours of sweep and training, not after
    check_inputs(config, out)
    check_folder_kind(sweep, "sweep")
    check_folder_kind(trained, "train")
    if config.storage is not None:
        check_storage(config.storage)
    t0 = time.perf_counter()
    run_sweep(load_space(), from_scratch, sweep, workers=config.workers, seed=0,
              progress=progress)  # fmt: skip
    t1 = time.perf_counter()
    ckpt = trained / CHECKPOINT_NAME
    if not ckpt.exists():
        train_surrogate(sweep, trained, seed=0, progress=progress)
    # the run folder is made by the search: the time of a sweep or training killed before it
    # is not in its time.json (the sweep keeps its designs, the training restarts)
    stages = {"sweep_s": t1 - t0, "train_s": time.perf_counter() - t1}
    config = dataclasses.replace(config, surrogate=str(ckpt), dataset=str(sweep))
    return optimize(config, out, progress=progress, stages=stages)
