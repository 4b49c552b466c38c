"""The search-run folder: every file of ``runs/NAME`` made by ``fingertip optimize`` / ``run``
that the search writes and the report reads, with its form, written and read here.

- ``config.json`` (:func:`write_config`, :func:`read_config`): the resolved configuration
  (``explore._config.OptimizeConfig`` and the targets, simulation options, storage URL),
  written once when the folder is made and never changed; ``meta.json``: provenance.
- ``studies.json`` (:func:`add_study`, :func:`read_studies`): the log of the rounds' Optuna
  studies, one entry per study as it starts (``name``, ``search``, ``round``, ``directions``).
  A folder made before this file kept the list in config.json (``studies``): it is read from
  there, and a resumed run continues it in studies.json.
- ``study.log``: the Optuna studies, a journal file (``explore._storage``;
  ``optuna-dashboard runs/NAME/study.log``), or the database ``--storage`` names; folders
  made before journals keep their ``study.db`` (``optuna-dashboard sqlite:///runs/NAME/study.db``).
- ``trials.csv`` (:func:`write_trials`, :func:`read_trials`): every finished trial of every
  round, one row each: ``round``, ``trial``, ``search`` ("continuous" | "buildable" | a
  family), the design-space parameters (inactive = empty), ``score``, the objectives
  ``OBJECTIVE_NAMES`` (``explore._objective``), ``pred.<metric>`` / ``std.<metric>``
  (surrogate point prediction = median, and std), ``in_domain``, ``disagreement`` and
  ``trusted`` (0/1). The parameter columns are every column outside the others
  (:func:`parameter_columns`).
- ``fe/records/<key>.json``: FE records of the confirmed designs (the sweep's record form, with
  ``curves``; ``explore._confirm``), and ``fe/references/<name>.json``: silicone and
  polyurethane on the reference geometry (same form) for the plots.
- ``rounds/round-<r>-candidates.json`` (:func:`write_candidates`, :func:`read_candidates`):
  the designs round r sent to FE (``Candidate``s; a resumed run reuses them);
  ``surrogates/round-<r>.safetensors`` (:func:`surrogate_path`): the retrained surrogate that
  round r searched with (round 0: the given checkpoint; written by
  ``surrogate.save_checkpoint``, atomically).
- ``confirmations.json`` (:func:`write_confirmations`, :func:`read_confirmations`): a list of
  ``Confirmation.to_json()``.
- ``rounds/buildable-fe-candidates.json`` and ``buildable_fe.json``: the FE-only screen of
  catalogue materials the surrogate cannot predict (search "buildable-fe", no prediction;
  ``explore._buildable``), its candidates and their ``Confirmation.to_json()``; never used to
  retrain the surrogate.
- ``time.json`` (:func:`write_time_part`, :func:`run_time`): how long each invocation that
  worked on the run took, one entry each in order (``wall_time_s`` and ``timings``, the time
  of its stages: ``search_s``, ``fe_s``, ``retrain_s``; ``sweep_s``, ``train_s`` for
  ``run --from-scratch``), updated as each stage ends, so a killed invocation keeps what it
  spent up to its last finished stage (an interrupted one, its interrupted stage too).
- ``summary.json`` (:func:`write_summary`, :func:`read_summary`): ``Summary.to_json()`` and the
  timing of the run when the answer was written (``TIMING_KEYS``: every invocation's part of
  time.json summed); ``report.md`` and ``figures/*.png``. :func:`read_answer`: one answer of
  it by name (``fingertip simulate RUN --answer NAME``).
- ``answers/<name>.toml`` (:func:`write_answers`, :func:`answer_path`): each answer of
  summary.json that exists ("best", "gel", "foam", "buildable") as a design file
  (``sim.design.skin.design_to_toml``, the text from ``explore._summary.answer_file_text``), which
  ``fingertip simulate`` and ``fingertip predict`` read as it is.

Every file is written atomically (``sim.provenance``), and only when its content changes.
"""

from __future__ import annotations

import csv
import io
import json
import math
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from sim.errors import DesignError
from sim.provenance import atomic_write, json_text, write_if_changed, write_json

from ._objective import OBJECTIVE_NAMES
from ._types import Candidate, Confirmation, Summary

if TYPE_CHECKING:
    from ._search import TrialRow

__all__ = [
    "OBJECTIVE_NAMES",
    "TIMING_KEYS",
    "add_study",
    "answer_path",
    "parameter_columns",
    "read_answer",
    "read_candidates",
    "read_config",
    "read_confirmations",
    "read_json",
    "read_meta",
    "read_studies",
    "read_summary",
    "read_trials",
    "run_time",
    "screened_designs",
    "surrogate_path",
    "time_parts",
    "trials_header",
    "write_answers",
    "write_candidates",
    "write_config",
    "write_confirmations",
    "write_summary",
    "write_time_part",
    "write_trials",
]

CONFIG, META, STUDIES, TRIALS, CONFIRMATIONS, SUMMARY, TIME, ANSWERS = (
    "config.json",
    "meta.json",
    "studies.json",
    "trials.csv",
    "confirmations.json",
    "summary.json",
    "time.json",
    "answers",
)

#: trials.csv: the columns before the parameters, those after them, and the prefixes of the
#: surrogate's prediction columns (the last columns but ``TRIAL_TRUST``)
TRIAL_KEYS = ("round", "trial", "search")
TRIAL_SCORES = ("score", *OBJECTIVE_NAMES)
TRIAL_PREDICTION_PREFIXES = ("pred.", "std.")
TRIAL_TRUST = ("in_domain", "disagreement", "trusted")
_NOT_PARAMETERS = frozenset((*TRIAL_KEYS, *TRIAL_SCORES, *TRIAL_TRUST))

#: summary.json entries that say how long the run took (the rest is the answer)
TIMING_KEYS = ("wall_time_s", "timings", "resumed")


def read_json(path: Path) -> Any:
    """A JSON file of the run folder; a damaged one is one error line naming it."""
    try:
        with path.open(encoding="utf-8") as fh:
            return json.load(fh)
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise DesignError(str(path), f"not readable JSON ({exc})") from None


# ----------------------------------------------------------------------------- config.json
def read_config(out: Path) -> dict[str, Any] | None:
    """The run folder's config.json (None if there is none); unreadable: one error line."""
    path = out / CONFIG
    if not path.exists():
        return None
    try:
        cfg = json.loads(path.read_text())
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise DesignError("--out", f"{path} is not readable JSON ({exc})") from None
    if not isinstance(cfg, dict) or not isinstance(cfg.get("storage"), str):
        raise DesignError("--out", f"{path} is not the configuration of a search run")
    return cfg


def write_config(out: Path, record: dict[str, Any], meta: dict[str, Any]) -> None:
    """A new run folder's config.json (``record``) and meta.json (``meta``)."""
    out.mkdir(parents=True, exist_ok=True)
    write_json(out / CONFIG, record)
    write_json(out / META, meta)


def read_meta(out: Path) -> dict[str, Any]:
    """The run folder's meta.json ({} without it, or when it is not a JSON object)."""
    path = out / META
    meta = read_json(path) if path.is_file() else {}
    return meta if isinstance(meta, dict) else {}


# ----------------------------------------------------------------------------- studies.json
def read_studies(out: Path) -> list[dict[str, Any]]:
    """The studies the rounds started, in order: studies.json, else the ``studies`` of an older
    folder's config.json, else none; a damaged file: one error line."""
    path = out / STUDIES
    if path.is_file():
        studies = read_json(path)
    elif (out / CONFIG).is_file():
        cfg = read_json(out / CONFIG)
        studies = cfg.get("studies", []) if isinstance(cfg, dict) else []
    else:
        studies = []
    if not isinstance(studies, list):
        raise DesignError(str(path), "not a list of studies")
    return studies


def screened_designs(config: dict[str, Any] | None, studies: Sequence[Any]) -> tuple[int, int]:
    """(designs each study's quasi-random screen scored, designs all the studies screened):
    config.json's ``screen`` times the studies of studies.json; (0, 0) for a run without
    screens. The one count the report and the README block both state."""
    screen = int((config or {}).get("screen") or 0)
    return (screen, screen * len(studies)) if screen and studies else (0, 0)


def add_study(out: Path, name: str, search: str, round_: int, mode: str) -> None:
    """Record a study in studies.json (once)."""
    studies = read_studies(out)
    if not any(s["name"] == name for s in studies):
        directions = ["minimize"] * (3 if mode == "multi" else 1)
        studies.append({"name": name, "search": search, "round": round_, "directions": directions})
        write_json(out / STUDIES, studies)


# ----------------------------------------------------------------------------- trials.csv
def trials_header(names: Sequence[str], metrics: Sequence[str]) -> list[str]:
    """The columns of trials.csv for the space parameters ``names`` and the surrogate's
    ``metrics``."""
    pred, std = TRIAL_PREDICTION_PREFIXES
    return [
        *TRIAL_KEYS, *names, *TRIAL_SCORES,
        *[f"{pred}{m}" for m in metrics], *[f"{std}{m}" for m in metrics],
        *TRIAL_TRUST,
    ]  # fmt: skip


def parameter_columns(header: Sequence[str]) -> tuple[str, ...]:
    """The design-space parameter columns of a trials.csv header: every column that is not a
    trial key, score, objective, prediction or trust column."""
    return tuple(
        n
        for n in header
        if n not in _NOT_PARAMETERS and not n.startswith(TRIAL_PREDICTION_PREFIXES)
    )


def _cell(v: Any) -> Any:
    if v is None:
        return ""
    v = float(v)
    return repr(v) if math.isfinite(v) else ""


def _trial_cells(r: TrialRow, names: Sequence[str], metrics: Sequence[str]) -> list[Any]:
    cells: list[Any] = [r.round, r.trial, r.search]
    for n in names:
        v = r.point.get(n, "")
        cells.append("" if isinstance(v, float) and math.isnan(v) else v)
    cells.append(_cell(r.score))
    cells += [_cell(v) for v in r.objectives]
    cells += [_cell(r.predicted.get(m, {}).get("median")) for m in metrics]
    cells += [_cell(r.predicted.get(m, {}).get("std")) for m in metrics]
    cells += [int(r.in_domain), _cell(r.disagreement), int(not r.flags)]
    return cells


def write_trials(
    out: Path,
    rows: Sequence[TrialRow],
    names: Sequence[str],
    metrics: Sequence[str],
    *,
    final: bool = True,
) -> None:
    """trials.csv: one row per scored trial of every round, rewritten only when its content
    changes (before the end, ``final`` False, a file that continues these rows is kept)."""
    fh = io.StringIO(newline="")
    w = csv.writer(fh)
    w.writerow(trials_header(names, metrics))
    for r in rows:
        w.writerow(_trial_cells(r, names, metrics))
    text = fh.getvalue()
    write_if_changed(out / TRIALS, text, None if final else lambda old: old.startswith(text))


def _parse_column(cells: list[str]) -> np.ndarray:
    """Float array if every non-empty cell is a number (empty -> NaN), else str array."""
    try:
        return np.array([float(c) if c.strip() else np.nan for c in cells], dtype=float)
    except ValueError:
        return np.array(cells, dtype=object)


def read_trials(out: Path) -> tuple[dict[str, np.ndarray], tuple[str, ...]]:
    """trials.csv as columns (header order; numeric ones float arrays, empty cell -> NaN, the
    others arrays of str) and its parameter columns; ``({}, ())`` without the file."""
    path = out / TRIALS
    if not path.is_file():
        return {}, ()
    with path.open(newline="") as fh:
        reader = csv.DictReader(fh)
        rows = list(reader)
        header = list(reader.fieldnames or ())
    columns = {name: _parse_column([r.get(name) or "" for r in rows]) for name in header}
    return columns, parameter_columns(header)


# ----------------------------------------------------------------------------- candidates
def _candidates_path(out: Path, r: int) -> Path:
    return out / "rounds" / f"round-{r}-candidates.json"


def read_candidates(out: Path, r: int) -> list[Candidate] | None:
    """The designs round ``r`` sent to FE; None when it has not chosen them yet."""
    path = _candidates_path(out, r)
    if not path.exists():
        return None
    return [Candidate.from_json(d) for d in json.loads(path.read_text())]


def write_candidates(out: Path, r: int, chosen: list[Candidate]) -> None:
    """Record the designs round ``r`` sends to FE."""
    path = _candidates_path(out, r)
    path.parent.mkdir(parents=True, exist_ok=True)
    atomic_write(path, json_text([c.to_json() for c in chosen], indent=1))


# ----------------------------------------------------------------------------- surrogates
def surrogate_path(out: Path, r: int) -> Path:
    """The checkpoint round ``r`` (>= 1) searches with: the surrogate retrained after round
    ``r - 1``."""
    return out / "surrogates" / f"round-{r}.safetensors"


# ----------------------------------------------------------------------------- confirmations
def read_confirmations(out: Path) -> tuple[Confirmation, ...]:
    """confirmations.json (none without the file; a damaged one: one error line)."""
    path = out / CONFIRMATIONS
    if not path.is_file():
        return ()
    return tuple(Confirmation.from_json(d) for d in read_json(path))


def write_confirmations(out: Path, items: list[Confirmation], *, final: bool) -> None:
    """confirmations.json, rewritten only when its content changes. Before the end of the loop
    (``final`` False) a file that already continues ``items`` (a resumed run that made later
    rounds before) is left as it is."""
    text = json_text([c.to_json() for c in items], indent=1)

    def continues(old: str) -> bool:
        try:
            return json.loads(old)[: len(items)] == json.loads(text)
        except (ValueError, TypeError):
            return False

    write_if_changed(out / CONFIRMATIONS, text, None if final else continues)


# ----------------------------------------------------------------------------- summary.json
def read_summary(out: Path) -> dict[str, Any]:
    """summary.json ({} without the file; a damaged one: one error line)."""
    path = out / SUMMARY
    return read_json(path) if path.is_file() else {}


def write_summary(
    out: Path, summary: Summary, wall_time_s: float, timings: dict[str, float], resumed: bool
) -> dict[str, Any]:
    """summary.json: the answer, and how long the run took (``wall_time_s``, ``timings``:
    :func:`run_time`, every invocation that worked on it; ``resumed``: the invocation that
    wrote it continued a run folder). Left as it is when the answer is the one it holds
    already (a finished run re-run). Returns the timing the file holds (``TIMING_KEYS``: the
    one given, or the one written with the answer first)."""
    data = summary.to_json()
    path = out / SUMMARY
    if path.exists():
        try:
            old = json.loads(path.read_text())
        except (OSError, ValueError):
            old = None
        if isinstance(old, dict):
            answer = {k: v for k, v in old.items() if k not in TIMING_KEYS}
            if answer == json.loads(json_text(data)):
                return {k: old[k] for k in TIMING_KEYS if k in old}
    timing = {"wall_time_s": wall_time_s, "timings": timings, "resumed": resumed}
    write_if_changed(path, json_text({**data, **timing}, indent=1) + "\n")
    return timing


#: the answers simulated with the 3D pad (``fingertip run --model 3d``, ``explore._check3d``)
ANSWERS_3D = "answers_3d.json"


def read_answers_3d(out: Path) -> dict[str, Any]:
    """answers_3d.json ({} if the run's answers were not simulated in 3D)."""
    if not (out / ANSWERS_3D).is_file():
        return {}
    data = read_json(out / ANSWERS_3D)
    return data if isinstance(data, dict) else {}


def write_answers_3d(out: Path, data: dict[str, Any]) -> None:
    """answers_3d.json: each answer's 3D result against the targets (``explore._check3d``);
    left as it is when unchanged."""
    write_if_changed(out / ANSWERS_3D, json_text(data, indent=1) + "\n")


def read_answer(source: Path, name: str) -> dict[str, Any]:
    """Answer ``name`` of a search run: ``source`` is the run folder or its summary.json. Every
    problem is one ``DesignError`` naming ``--answer`` (an unknown name: with the run's names;
    an answer the run has not found: with those it has)."""
    source = Path(source)
    path = source / SUMMARY if source.is_dir() else source
    if not path.is_file() or path.suffix != ".json":
        if source.is_dir():
            what = f"{source} has no {SUMMARY} (not a finished search run)"
        else:
            what = f"no such file: {source}" if not path.exists() else f"{source} is no summary"
        raise DesignError("--answer", f"{what}; give a search run folder or its {SUMMARY}")
    summary = read_json(path)
    answers = summary.get("answers") if isinstance(summary, dict) else None
    if not isinstance(answers, dict):
        raise DesignError("--answer", f"{path} is not the summary of a search run (no answers)")
    if name not in answers:
        raise DesignError("--answer", f"unknown answer {name!r}; allowed: {', '.join(answers)}")
    answer = answers[name]
    if not isinstance(answer, dict) or not isinstance(answer.get("design"), dict):
        found = [k for k, a in answers.items() if isinstance(a, dict) and a.get("design")]
        raise DesignError(
            "--answer",
            f"the run found no {name!r} answer (no credible such design confirmed by FE); "
            f"allowed here: {', '.join(found) or 'none'}",
        )
    return answer


# ----------------------------------------------------------------------------- answers/*.toml
def answer_path(out: Path, name: str) -> Path:
    """The design file of answer ``name``: ``answers/<name>.toml``."""
    return out / ANSWERS / f"{name}.toml"


def write_answers(out: Path, texts: dict[str, str | None]) -> list[Path]:
    """``answers/<name>.toml`` for every answer ``name`` with a text (a design file), each
    written only when its content changes; the file of an answer without one (None: the run
    has none) is removed. Returns the answer files, in the order of ``texts``."""
    paths = []
    for name, text in texts.items():
        path = answer_path(out, name)
        if text is None:
            path.unlink(missing_ok=True)
            continue
        path.parent.mkdir(parents=True, exist_ok=True)
        write_if_changed(path, text)
        paths.append(path)
    return paths


# ----------------------------------------------------------------------------- time.json
def _time_parts(out: Path) -> list[dict[str, Any]]:
    path = out / TIME
    parts = read_json(path) if path.is_file() else []
    if not isinstance(parts, list) or not all(isinstance(p, dict) for p in parts):
        raise DesignError(str(path), "not a list of the run's parts")
    return parts


def write_time_part(out: Path, index: int, wall_time_s: float, timings: dict[str, float]) -> None:
    """Record in time.json that invocation ``index`` (its entry; ``len`` of the entries when it
    started) has run ``wall_time_s`` so far, ``timings`` of it in each stage."""
    parts = _time_parts(out)
    parts[index : index + 1] = [{"wall_time_s": wall_time_s, "timings": dict(timings)}]
    write_json(out / TIME, parts)


def time_parts(out: Path) -> int:
    """How many invocations time.json records (the index of the next one)."""
    return len(_time_parts(out))


def run_time(out: Path) -> tuple[float, dict[str, float]]:
    """How long the run took: the wall time and each stage's time of every invocation that
    worked on it (time.json), summed; a value a part lacks counts 0."""
    parts = _time_parts(out)
    wall = sum(float(p.get("wall_time_s") or 0.0) for p in parts)
    timings: dict[str, float] = {}
    for p in parts:
        for stage, seconds in (p.get("timings") or {}).items():
            timings[stage] = timings.get(stage, 0.0) + float(seconds or 0.0)
    return wall, timings
