"""The configuration of a search (``fingertip optimize`` / ``run``) and its inputs, checked
before any work: ``OptimizeConfig``, what the run folder's config.json holds of it
(:func:`config_record`) and the refusal of a resume with another one, the storage URL, the
targets, space and ``--catalogue`` files (:func:`check_inputs`, :func:`check_storage`), and
:func:`setup`: the loaded surrogate, the searched spaces, its training sweep and its FE options.

Importing this module is cheap (the CLI's parser reads ``OptimizeConfig``'s defaults).
"""

from __future__ import annotations

import dataclasses
import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from sim.design import Targets, load_space, load_targets
from sim.errors import DesignError, check_seed
from sim.options import SimOptions
from sim.provenance import check_folder_kind
from sim.sweep import default_workers

from ._buildable import DEFAULT_FE_BUDGET
from ._run_folder import read_config
from ._search import catalogue_only, check_subspace, complete_subspace
from ._storage import check_storage, default_storage

__all__ = [
    "DEFAULT_CHECKPOINT",
    "DEFAULT_CHECKPOINT_3D",
    "OptimizeConfig",
    "Setup",
    "check_inputs",
    "check_storage",
    "config_record",
    "credible_at",
    "default_checkpoint",
    "search_trials",
    "setup",
]

PRETRAINED = Path(__file__).resolve().parents[1] / "surrogate" / "pretrained" / "default"
#: the shipped 2D checkpoint (``--model 2d``'s, and the 3D one's low fidelity); which one a
#: search starts from without ``--surrogate`` is :func:`default_checkpoint`'s rule
DEFAULT_CHECKPOINT = PRETRAINED / "model.safetensors"
#: the shipped multi-fidelity checkpoint: 3D pads, with the 2D one as its low fidelity
DEFAULT_CHECKPOINT_3D = PRETRAINED.parent / "default3d" / "model.safetensors"


def default_checkpoint(model: str | None) -> Path:
    """The checkpoint a search starts from when no ``--surrogate`` is given, by the model of
    its answers: the shipped 2D one for ``--model 2d`` (the paper's plane-strain section),
    else the shipped multi-fidelity one, which searches the 3D pad and confirms in 3D. (A 2D
    checkpoint given with ``--model 3d`` keeps the 2D search and simulates its answers in 3D
    too: ``explore._check3d``.)"""
    return DEFAULT_CHECKPOINT if model == "2d" else DEFAULT_CHECKPOINT_3D


def credible_at(given: str | None, model: str) -> str:
    """What the search judges a design's credibility on (``--credible-at``; ``given`` None:
    the model's default): "bound" for the 3D search, "median" for the 2D one. In 3D the answers
    sit on the validity limits and a confirmation costs minutes: on the shipped multi-fidelity
    surrogate, ``fingertip run --credible-at median`` sent 21 designs to 3D FE and 5 came back
    trusted (best credible FE score 0.300), ``--credible-at bound`` 20 and 13 (best 0.216;
    docs/search.md, "Credible at the interval's bound"). In 2D the bound did not pay (the same
    section)."""
    return given or ("bound" if model == "3d" else "median")


#: the continuous study's trials per round when ``--trials`` is not given, by model: 128 TPE
#: trials after the screen's seeds found a better design than 1000 alone in 2D
#: (benchmarks/bench_search.py); in 3D 1024 find better predicted designs than 128 (the
#: continuous study's best credible score 0.146 / 0.156 against 0.210 / 0.221, seeds 0 / 1,
#: 17 s more: ``python studies/search_budget.py --model 3d``), and a main job with them found a
#: better design by FE in its first round (docs/search.md, "The current answer in detail"):
#: the search costs seconds where a 3D confirmation costs minutes
TRIALS = {"2d": 128, "3d": 1024}


def search_trials(given: int | None, model: str) -> int:
    """The continuous study's trials per round: ``--trials``, else the model's ``TRIALS``."""
    return TRIALS[model] if given is None else given


#: what the search judges credibility on (``OptimizeConfig.credible_at``)
CREDIBLE_AT = ("median", "bound")


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
    processes (``sim.sweep.run.default_workers``: one per usable core), which never change the
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
    ``trials`` counts the sampler's trials after them; ``model``: the model of the answers
    (None: the surrogate's; a multi-fidelity surrogate searches the 3D pad and confirms in 3D,
    ``Setup.model``), "3d" with a 2D surrogate simulates every 2D answer with the 3D pad too
    (``explore._check3d``, answers_3d.json); without ``surrogate`` it also names the shipped
    checkpoint the search starts from (:func:`default_checkpoint`); ``credible_at``: what the
    search judges a design's credibility on, "median" or "bound", the side of each trust
    prediction's 90 % interval towards its limit (``explore._search._judged``; None: the
    model's default, :func:`credible_at`).
    """

    # None: the shipped checkpoint of ``model`` (``default_checkpoint``), resolved on creation
    surrogate: str | None = None
    space: str | None = None
    targets: str | None = None
    # None: the model's (TRIALS, search_trials: 128 in 2D, 1024 in 3D); families and the
    # buildable search, smaller spaces, take 64
    trials: int | None = None
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
    # the retraining after a round (warm start, ``explore._retrain``): minibatches of 32 (as the
    # sweep's training) for 150 epochs. 128 x 50 is 5 times faster and scored within the noise
    # of a small sample (fine-tuned on the 7 designs of a main job's first round, scored on
    # the 8 of its later rounds, studies/retrain_study.py: hysteresis median 9.7 against 8.4 %,
    # displacements 2.1-2.7 against 1.9-2.3 %), but in the main job (solver 2.3, quiet, same
    # seed) its rounds found worse designs (best FE score per round 0.413 / 0.487 / 0.440
    # against 0.413 / 0.443 / 0.402) for 24 s less (retraining 6 against 30 s; 141 against
    # 155 s in all): the main job is within 3 minutes either way, so the better search is kept
    retrain_epochs: int = 150
    retrain_batch_size: int = 32
    # a rehearsal: every epoch passes over the confirmed designs and 256 designs of the
    # training sweep drawn afresh (``surrogate.fine_tune``'s ``replay``), not the whole sweep,
    # so the retraining's cost does not grow with the sweep. With the solver-2.3 surrogate
    # (1434 training designs) and the main job's defaults, seeds 0, 1, 2
    # (studies/seed_study.py): best FE score of the
    # run 0.398 / 0.397 / 0.391 against 0.411 / 0.385 / 0.391 over the whole sweep, retraining
    # 12-22 s against 45-72 s (the machine's speed varied by a third between those runs)
    retrain_replay: int = 256
    catalogues: tuple[str, ...] = ()
    buildable_fe: int = DEFAULT_FE_BUDGET
    family_trials: int = 64
    allow_untrusted: bool = False
    # 2^16 designs: ~2-3 s per study at the surrogate's ~65 000 designs/s on one thread
    # (benchmarks/bench_predict.py), so a round of four studies stays within 30 s (issue 15)
    screen: int = 65536
    # the model the answers are judged in; None: the surrogate's (a multi-fidelity surrogate
    # searches the 3D model, a 2D one the 2D model). Without --surrogate it names the shipped
    # checkpoint (default_checkpoint): "2d" the 2D one, else the multi-fidelity one.
    # "3d" with a 2D surrogate: the search and its confirmations stay 2D and every answer is
    # also simulated with the 3D pad (explore._check3d), so such a run may be resumed with
    # either; "2d" with a multi-fidelity surrogate is refused (it predicts the 3D model only)
    model: str | None = None
    # None: the model's default (credible_at(): bound in 3D, median in 2D)
    credible_at: str | None = None

    def __post_init__(self) -> None:
        if self.surrogate is None:
            object.__setattr__(self, "surrogate", str(default_checkpoint(self.model)))

    def check(self) -> None:
        def at_least(name: str, value: int, low: int) -> None:
            if value < low:
                raise DesignError(f"--{name.replace('_', '-')}", f"must be >= {low}, got {value}")

        if self.trials is not None:
            at_least("trials", self.trials, 1)
        at_least("buildable_trials", self.buildable_trials, 0)
        at_least("confirm", self.confirm, 1)
        at_least("uncertain", self.uncertain, 0)
        at_least("rounds", self.rounds, 1)
        at_least("workers", self.workers, 1)
        at_least("retrain_epochs", self.retrain_epochs, 1)
        at_least("retrain_batch_size", self.retrain_batch_size, 1)
        at_least("retrain_replay", self.retrain_replay, 0)
        at_least("buildable_fe", self.buildable_fe, 0)
        at_least("family_trials", self.family_trials, 0)
        at_least("screen", self.screen, 0)
        check_seed(self.seed, "--seed", uses=self.rounds)
        if self.model not in (None, "2d", "3d"):
            raise DesignError("--model", f"must be 2d or 3d, got {self.model!r}")
        if self.credible_at not in (None, *CREDIBLE_AT):
            raise DesignError(
                "--credible-at",
                f"must be {' or '.join(CREDIBLE_AT)}, got {self.credible_at!r}",
            )
        if self.mode not in ("single", "multi"):
            raise DesignError("--mode", f"must be single or multi, got {self.mode!r}")
        for name in ("tolerance", "max_disagreement"):
            v = getattr(self, name)
            if not 0 < v < 1:
                raise DesignError(f"--{name.replace('_', '-')}", f"must be in (0, 1), got {v}")


# ----------------------------------------------------------------------------- config.json
#: configuration entries that never change the answer: a run may be resumed with others
_FREE = ("workers", "model")
#: what config.json held beside the configuration before studies.json (``explore._run_folder``)
_OLD_LOG = ("studies",)


def config_record(
    config: OptimizeConfig, out: Path, targets: Targets, options: SimOptions, user: tuple = ()
) -> dict:
    """What config.json holds: the configuration, the FE options, the storage URL, the targets
    and the ``--catalogue`` files ``user`` by content (only when given: older runs had none)."""
    record = {
        **dataclasses.asdict(config),
        "sim_options": options.as_dict(),
        "storage": _storage_url(config, out),
        "targets": dict(targets.values),
        "displacement_reading": targets.reading,
        "max_sag_mm": targets.max_sag_mm,
    }
    record.pop("catalogues")
    if user:
        record["catalogues"] = [c.record() for c in user]
    return json.loads(json.dumps(record))  # as config.json holds it (lists, not tuples)


def _storage_url(config: OptimizeConfig, out: Path) -> str:
    """``--storage``, else the run folder's own journal file; a folder made before journals
    keeps its own SQLite file (config.json names it), so that it resumes where it was."""
    if config.storage is not None:
        return config.storage
    old = read_config(out)
    own_sqlite = f"sqlite:///{(out / 'study.db').resolve()}"
    if old is not None and old.get("storage") == own_sqlite:
        return own_sqlite
    return default_storage(out)


def _check_resume(out: Path, record: dict) -> None:
    """A run folder is resumed only with the configuration it was made with (``_FREE`` aside;
    an older folder's study log in config.json is no configuration)."""
    old = read_config(out)
    if old is None:
        return
    # a folder made when the rule was always the median unless asked otherwise records none
    old, record = ({**d, "credible_at": d.get("credible_at") or "median"} for d in (old, record))
    keys = sorted((set(old) | set(record)) - set(_FREE) - set(_OLD_LOG))
    diff = [k for k in keys if old.get(k) != record.get(k)]
    if diff:
        raise DesignError(
            "--out",
            f"{out} holds a run with another configuration ({', '.join(diff)}); "
            "use another --out or the same options to resume",
        )


def check_inputs(config: OptimizeConfig, out: str | Path) -> Targets:
    """Everything a search can check without its surrogate, before any work: the options, the
    run folder (absent, empty or a search run's), the targets file, the ``--catalogue`` files
    and the space file (the storage URL: ``check_storage``). Returns the targets.
    ``explore._pipeline.run`` calls it before a ``--from-scratch`` sweep; :func:`setup` calls
    it first."""
    config.check()
    out = Path(out)
    check_folder_kind(out, "optimize")
    read_config(out)
    targets = load_targets(config.targets)
    from sim.materials import load_user_catalogues

    catalogue = load_user_catalogues(config.catalogues)[1]  # the --catalogue files, checked
    if config.space:
        load_space(config.space, catalogue)
    if config.dataset:  # given, it is used: never silently replaced by another sweep
        why = _not_a_sweep(config.dataset)
        if why:
            raise DesignError("--dataset", f"{config.dataset} {why}")
    return targets


# ----------------------------------------------------------------------------- setup
def _not_a_sweep(folder: str | Path) -> str:
    """Why ``folder`` is not a sweep folder a surrogate can retrain on ("" when it is one):
    it must hold the sweep's config.json and its table (``table.csv`` or ``table.csv.gz``)."""
    from sim.sweep import folder as sweep_folder

    folder = Path(folder)
    if not folder.is_dir():
        return "is not a folder" if folder.exists() else "does not exist"
    if not (folder / sweep_folder.CONFIG).exists():
        return f"is not a sweep folder: it has no {sweep_folder.CONFIG}"
    if not sweep_folder.table_path(folder).exists():
        return f"is not a sweep folder: it has no {sweep_folder.TABLE} (nor its .gz)"
    return ""


def _find_dataset(config: OptimizeConfig, surrogate) -> Path | None:
    """The surrogate's training sweep: --dataset, the checkpoint's folder (a shipped checkpoint
    carries its table, gzipped), or the sweep named in its header, whichever holds the table whose
    sha256 the header records."""
    from sim.sweep import folder as sweep_folder

    want = surrogate.header.get("training_data", {}).get("table_sha256")
    places = [config.dataset, str(Path(config.surrogate).parent),
              surrogate.header.get("training_data", {}).get("sweep")]  # fmt: skip
    for p in places:
        if not p or _not_a_sweep(p):
            continue
        if config.dataset or sweep_folder.table_sha256(sweep_folder.table_path(p)) == want:
            return Path(p)
    return None


def _sim_options(dataset: Path | None, model: str) -> SimOptions:
    """The FE options of the surrogate's training sweep (so FE confirms like with like), else
    the defaults of the surrogate's ``model``; a sweep of the other model is refused (a 2D
    surrogate retrained on 3D designs, or the reverse, would learn another model)."""
    from sim.options import ModelOptions, options_from_dict
    from sim.sweep import read_config as read_sweep_config

    if dataset is None:
        return SimOptions(model=ModelOptions(model))
    cfg = read_sweep_config(dataset)
    options = options_from_dict(cfg["options"]) if "options" in cfg else SimOptions()
    if options.dimension != model:
        raise DesignError(
            "--dataset",
            f"{dataset} is a sweep of the {options.dimension.upper()} model; the surrogate "
            f"predicts the {model.upper()} model: give its own sweep",
        )
    return options


@dataclass(frozen=True)
class Setup:
    """The checked inputs of a search (:func:`setup`): the surrogate it starts from, the space
    it searches (and its catalogue-only part, or why there is none), the targets, the
    surrogate's training sweep (None: not found, no retraining) and its FE options, what
    config.json holds (``record``), the merged catalogue and the model the search predicts and
    confirms with (``model``: "3d" for a multi-fidelity surrogate, else "2d")."""

    surrogate: Any
    space: Any
    build_space: Any
    build_note: str | None
    targets: Targets
    dataset: Path | None
    options: SimOptions
    record: dict
    catalogue: dict = field(default_factory=dict)  # shipped + user materials, by name
    model: str = "2d"


def setup(config: OptimizeConfig, out: Path) -> Setup:
    """Check every input before any work and before the run folder is made: the options, the
    folder, the targets, the space (inside the surrogate's), the configuration of a resumed
    run, the storage URL."""
    from surrogate import is_multifidelity, load_surrogate

    targets = check_inputs(config, out)
    model = "3d" if is_multifidelity(config.surrogate) else "2d"
    if model == "3d" and config.model == "2d":
        raise DesignError(
            "--model",
            f"2d needs a 2D surrogate: {config.surrogate} is a multi-fidelity one, which "
            "predicts the 3D model (give --model 3d, or a 2D checkpoint)",
        )
    # a surrogate trained on FE results of another solver version still searches (the shipped
    # one until it is re-made), with a warning: every answer is confirmed by this solver's FE
    surrogate = load_surrogate(config.surrogate, allow_solver_mismatch=True)
    user, catalogue = _catalogues(config, surrogate.space)
    space = load_space(config.space, catalogue) if config.space else surrogate.space
    space = complete_subspace(space, surrogate.space)  # e.g. a gel-only core has no core.nu
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
    options = _sim_options(dataset, model)
    if config.allow_untrusted:  # answers beyond the limits: confirm them to the end
        options = options.without_validity_stop()
    record = config_record(config, out, targets, options, user)
    record["credible_at"] = credible_at(config.credible_at, model)  # the rule the search uses
    record["trials"] = search_trials(config.trials, model)  # and its budget
    _check_resume(out, record)
    if config.storage is not None:
        check_storage(config.storage)
    return Setup(
        surrogate, space, build_space, build_note, targets, dataset, options, record, catalogue,
        model,
    )  # fmt: skip


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
