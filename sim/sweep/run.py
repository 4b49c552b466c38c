"""Sweeps: sample a design space, evaluate every design by FE, keep every result safely.

A sweep folder ``runs/NAME`` holds its ``config.json``, ``meta.json``, one record per design
(``records/<key>.json``, written atomically), ``table.csv`` and ``curves.jsonl``; the files
and their forms are ``sim.sweep.folder``'s, which alone writes and reads them.

Re-running the same command continues where it stopped (after ``kill -9`` too): designs with a
record are skipped, failed ones only run again with ``retry_failed``. Only the parent process
writes records, so a killed worker can never leave half a record.
"""

from __future__ import annotations

import hashlib
import json
import math
import os
import time
from collections.abc import Callable, Iterable, Mapping, Sequence
from concurrent.futures import FIRST_COMPLETED, wait
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ..design import DesignSpace, point_to_design, space_from_dict
from ..errors import DesignError, SimulationError, check_seed
from ..materials import Material, UserCatalogue, catalogue_from_tables, material_tables
from ..metrics import DEFAULTS_BEFORE, PROTOCOLS, SOLVER_VERSION, same_metrics
from ..options import SimOptions, apply_overrides, options_from_dict
from ..pool import process_pool
from ..provenance import check_folder_kind, json_safe, provenance
from ..simulate import merge_results, simulate
from .folder import (
    DAMAGED_GZIP,
    SweepStore,
    merge_tables,
    read_config,
    write_config,
    write_meta,
)

__all__ = [
    "PointPart",
    "SweepStore",
    "SweepSummary",
    "catalogue_hashes",
    "default_workers",
    "evaluate_point",
    "json_safe",
    "merge_sweeps",
    "options_from_dict",
    "point_record",
    "protocol_costs",
    "record_key",
    "run_sweep",
    "sample_points",
    "simulate_part",
    "sweep_config",
]

SAMPLERS = ("sobol", "lhs")


def default_workers() -> int:
    """The default number of FE processes of ``sweep``, ``run`` and ``optimize``: one per core
    this process may use (2 on the project's machines). One design's FE is solved on one core
    (qdldl's sparse LDLᵀ is serial), so one process per core keeps every core busy and more only
    share them; the answer never depends on it (each design is simulated alone)."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # pragma: no cover - platforms without sched_getaffinity
        return max(1, os.cpu_count() or 1)


@dataclass(frozen=True)
class SweepSummary:
    """What one invocation of a sweep did."""

    folder: Path
    n_designs: int
    ok: int
    failed: int
    skipped: int
    computed: int
    wall_time_s: float


def sample_points(space: DesignSpace, n: int, seed: int, sampler: str = "sobol") -> list[dict]:
    """``n`` space-filling design points (deterministic in seed; Sobol prefixes nest)."""
    from scipy.stats import qmc  # here: `import sim.sweep.run` stays light for the CLI

    d = len(space.sampled)
    if d == 0:
        unit = np.zeros((n, 0))
    elif sampler == "sobol":
        gen = qmc.Sobol(d, scramble=True, seed=seed)
        m = max(0, math.ceil(math.log2(max(n, 1))))
        unit = gen.random_base2(m)[:n]  # a power-of-two draw, cut: prefixes stay identical
    elif sampler == "lhs":
        unit = qmc.LatinHypercube(d, seed=seed).random(n)
    else:
        raise DesignError("--sampler", f"must be one of {', '.join(SAMPLERS)}, got {sampler!r}")
    return [space.point(row) for row in unit]


def record_key(
    point: dict[str, Any], options: SimOptions, catalogue: Mapping[str, Material] | None = None
) -> str:
    """Hash of the design (as built; a user material by its whole table, not its name), the
    simulation options and the solver version; for the 3D model also the pad as simulated
    (its length and side profile, defaults included, so a new default re-keys the records)."""
    built = point_to_design(point, catalogue)
    payload = {"design": built.to_dict(), "options": options.as_dict(), "solver": SOLVER_VERSION}
    if options.dimension == "3d":
        payload["pad"] = built.pad.to_dict()
    return hashlib.sha256(json.dumps(payload, sort_keys=True).encode()).hexdigest()[:20]


def evaluate_point(
    point: dict[str, Any],
    options_dict: dict[str, Any],
    materials: dict[str, dict[str, Any]] | None = None,
) -> dict[str, Any]:
    """Simulate one design point; never raises (failures are records with a reason).

    ``materials``: the user catalogue materials the point may name, as tables
    (``sim.materials.material_tables``): passed explicitly, so that a worker process sees
    them whatever it inherited from its parent.
    """
    return point_record(point, [simulate_part(point, options_dict, materials)])


@dataclass(frozen=True)
class PointPart:
    """Some protocols of one design, simulated (``simulate_part``): the result, or why the
    design could not be simulated (``error``: a record's reason), and the seconds it took."""

    result: Any  # sim.simulate.SimResult, None with an error
    error: str
    wall_time_s: float
    cpu_time_s: float


def simulate_part(
    point: dict[str, Any],
    options_dict: dict[str, Any],
    materials: dict[str, dict[str, Any]] | None = None,
    protocols: Sequence[str] = PROTOCOLS,
) -> PointPart:
    """``protocols`` (default all) of one design point, as ``evaluate_point`` runs them; never
    raises. Parts of disjoint protocols, run in separate processes, give with ``point_record``
    the record of the whole design (``explore``'s FE confirmation of a few designs on more
    cores than designs)."""
    options = options_from_dict(options_dict)
    t0, cpu0 = time.perf_counter(), time.process_time()
    result, error = None, ""
    try:
        catalogue = catalogue_from_tables(materials) if materials else None
        design = point_to_design(point, catalogue)
        result = simulate(design, tuple(protocols), options=options)
    except (DesignError, SimulationError, ArithmeticError, ValueError, RuntimeError) as exc:
        error = f"{type(exc).__name__}: {exc}"
    except Exception as exc:  # a bug must not stop a sweep of thousands: record it, loudly
        error = f"internal error {type(exc).__name__}: {exc}"
    # the worker process's CPU seconds: unlike the wall time, not inflated by other jobs
    # sharing the core or by a paused process (a sweep's records are then a speed figure)
    return PointPart(result, error, time.perf_counter() - t0, time.process_time() - cpu0)


def point_record(point: dict[str, Any], parts: Sequence[PointPart]) -> dict[str, Any]:
    """The record of a design from the parts of its protocols (``simulate_part``; one part for
    all of them in a sweep): the merged result (``sim.simulate.merge_results``), or the first
    part's error; the seconds are the parts' sums."""
    record: dict[str, Any] = {"params": json_safe(point), "solver_version": SOLVER_VERSION}
    errors = [part.error for part in parts if part.error]
    if errors:
        record.update(status="failed", reason=errors[0], metrics={})
    else:
        results = [part.result for part in parts]
        res = merge_results(results) if len(results) > 1 else results[0]
        record.update(
            status="ok" if res.ok else "failed",
            reason="; ".join(
                f"{f.protocol} at t = {f.time_s:.4g} s: {f.reason}" for f in res.failures
            ),
            metrics=json_safe(res.metrics),
            diagnostics=json_safe(res.diagnostics()),
            curves=res.curves,
            n_dofs=res.n_dofs,
            cost_by_protocol=protocol_costs(res.protocols),
        )
    record["wall_time_s"] = sum(part.wall_time_s for part in parts)
    record["cpu_time_s"] = sum(part.cpu_time_s for part in parts)
    return record


#: a completed protocol's solver figures a record keeps (``SimResult.protocols``)
COST_KEYS = ("wall_time_s", "steps", "newton_iterations", "factorizations", "evaluations", "n_dofs")


def protocol_costs(protocols: dict[str, dict[str, Any]]) -> dict[str, dict[str, float]]:
    """What each completed protocol cost (``COST_KEYS``), by protocol: where a design's FE
    time went. Timing, not a result: it varies with the machine's load and is left out
    wherever records are compared."""
    return {name: {k: fig[k] for k in COST_KEYS if k in fig} for name, fig in protocols.items()}


def sweep_config(
    space: DesignSpace, n: int, seed: int, sampler: str, options: SimOptions, start: int = 0
) -> dict:
    """A sweep folder's ``config.json``: what its records depend on (``run_sweep`` refuses to
    resume a folder whose config differs, and ``fingertip migrate-sweep`` writes a new one).
    ``start`` > 0 (a segment: the sample's designs ``start`` to ``n - 1``) is recorded; a whole
    sample's config has no ``start``, as before segments existed."""
    config = {
        "space": space.to_dict(),
        "n": n,
        "seed": seed,
        "sampler": sampler,
        "options": options.as_dict(),
        "solver_version": SOLVER_VERSION,
    }
    if start:
        config["start"] = start
    return config


#: what a sweep's config field is called in an error message
_FIELD_WORDS = {
    "space": "another design space",
    "seed": "another --seed",
    "sampler": "another --sampler",
    "options": "other simulation options (--set)",
    "solver_version": "another solver version",
    "start": "another --start",
}


def _check_config(folder: Path, config: dict) -> None:
    """A folder is resumed only with the configuration it was made with; ``--n`` may grow (a
    larger Sobol sample extends the smaller one) but never shrink: a smaller ``--n`` is refused,
    so the table always lists every design the folder holds."""
    path = folder / "config.json"
    if not path.exists():
        return
    try:
        old = read_config(folder)
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise DesignError(
            "--out", f"{path} is not readable JSON ({exc}); choose a new folder"
        ) from None
    if "segments" in old:
        raise DesignError(
            "--out",
            f"{folder} is a merge of sweep folders (fingertip merge-sweeps): resume the "
            "segments in their own folders, then merge them again",
        )
    for field, words in _FIELD_WORDS.items():
        if old.get(field) != json.loads(json.dumps(config.get(field))):
            raise DesignError(
                "--out",
                f"{folder} holds a sweep with {words}; resume it with the same arguments "
                "(only --n may grow) or choose a new folder",
            )
    if catalogue_hashes(old) != catalogue_hashes(config):
        raise DesignError(
            "--catalogue",
            f"{folder} holds a sweep made with other --catalogue files (by content: sha256 "
            f"{catalogue_hashes(old) or 'none'}); resume it with the same files or choose a "
            "new folder",
        )
    n_old = old.get("n")
    if isinstance(n_old, int) and config["n"] != n_old:
        if config["sampler"] != "sobol":
            raise DesignError(
                "--n",
                f"{folder} holds a {config['sampler']} sweep of {n_old} designs; --n cannot "
                f"change with --sampler {config['sampler']} (a sample of another size is "
                f"another sample), got {config['n']}",
            )
        if config["n"] < n_old:
            raise DesignError(
                "--n",
                f"{folder} holds a sweep of {n_old} designs; --n may only grow, got "
                f"{config['n']} (use --n {n_old} to resume it)",
            )


def run_sweep(
    space: DesignSpace,
    n: int,
    out: str | Path,
    *,
    workers: int = 1,
    scheduler: str | None = None,
    seed: int = 0,
    sampler: str = "sobol",
    options: SimOptions | None = None,
    retry_failed: bool = False,
    progress: bool = True,
    on_record: Callable[[str, dict], None] | None = None,
    catalogues: Sequence[UserCatalogue] = (),
    start: int = 0,
) -> SweepSummary:
    """Evaluate ``n`` sampled designs of ``space`` into the folder ``out`` (resumable).

    ``start`` > 0: a segment, the Sobol sample's designs ``start`` to ``n - 1`` only (their
    ``index`` in table.csv is their position in the sample), so that a large sweep can be made
    in pieces, in several folders or sessions, and joined by ``fingertip merge-sweeps``.

    ``catalogues``: the user's ``--catalogue`` files, recorded (path, sha256) in config.json; a
    resume with other files is refused. The user materials the space names travel with it
    (``space.materials``) to the worker processes."""
    if n < 1:
        raise DesignError("--n", f"must be >= 1, got {n}")
    if workers < 1:
        raise DesignError("--workers", f"must be >= 1, got {workers}")
    check_seed(seed)
    if not 0 <= start < n:
        raise DesignError("--start", f"must be in [0, --n - 1] = [0, {n - 1}], got {start}")
    if start and sampler != "sobol":
        raise DesignError(
            "--start", f"a segment needs --sampler sobol (its prefixes nest), got {sampler}"
        )
    options = options or SimOptions()
    if options.model.inclination_deg:  # every design would fail on the upright-only wedge
        raise DesignError(
            "model.inclination_deg",
            "a sweep runs the wedge, which is upright only: must be 0 in a sweep "
            "(an inclined plate or tapping: fingertip simulate --protocol plate|tapping)",
        )
    folder = Path(out)
    check_folder_kind(folder, "sweep")  # never into another command's folder
    config = sweep_config(space, n, seed, sampler, options, start)
    if catalogues:  # the --catalogue files, for the record (the space holds their materials)
        config["catalogues"] = [c.record() for c in catalogues]
    _check_config(folder, config)
    points = sample_points(space, n, seed, sampler)[start:]
    keys = [record_key(p, options, space.catalogue) for p in points]
    materials = material_tables({str(m.name): m for m in space.materials}) or None
    client = _connect(scheduler) if scheduler else None  # refused before the folder is made
    folder.mkdir(parents=True, exist_ok=True)
    write_config(folder, config)
    write_meta(folder, provenance(config, seed, kind="sweep"))
    store = SweepStore(folder)
    done = store.load()
    todo = []
    seen = set()
    for key, point in zip(keys, points, strict=True):
        if key in seen:
            continue  # the same design twice in a sample: computed once
        seen.add(key)
        rec = done.get(key)
        if rec is None or (retry_failed and rec.get("status") != "ok"):
            todo.append((key, point))
    skipped = len(seen) - len(todo)
    options_dict = options.as_dict()
    t0 = time.perf_counter()
    bar = _progress(len(todo), progress)
    counts = {"ok": 0, "failed": 0}

    def store_result(key: str, record: dict) -> None:
        store.write(key, record)
        counts[record["status"]] = counts.get(record["status"], 0) + 1
        bar.update(1)
        bar.set_postfix(ok=counts["ok"], failed=counts["failed"])
        if on_record is not None:
            on_record(key, record)

    try:
        if client is not None:
            _run_dask(client, todo, options_dict, store_result, materials)
        elif workers == 1:
            for key, point in todo:
                store_result(key, evaluate_point(point, options_dict, materials))
        else:
            _run_local(workers, todo, options_dict, store_result, materials)
    finally:
        bar.close()
        store.consolidate(keys, space.names, first_index=start, dimension=options.dimension)
    final = store.load()
    statuses = [final[k]["status"] for k in dict.fromkeys(keys) if k in final]
    return SweepSummary(
        folder=folder,
        n_designs=len(seen),
        ok=statuses.count("ok"),
        failed=statuses.count("failed"),
        skipped=skipped,
        computed=len(todo),
        wall_time_s=time.perf_counter() - t0,
    )


def _version(text: str | None) -> tuple[int, ...]:
    try:
        return tuple(int(x) for x in str(text).split("."))
    except ValueError:
        return ()


def with_todays_defaults(config: dict) -> dict:
    """A sweep's ``config`` with each option of ``sim.metrics.DEFAULTS_BEFORE`` that its solver
    version kept at the default before today's set to today's default: how a sweep of an
    earlier solver whose metrics are this one's is carried over and joined. Other configs are
    returned as they are."""
    version = _version(config.get("solver_version"))
    options = config.get("options")
    changes = {
        key: before
        for key, (since, before) in DEFAULTS_BEFORE.items()
        if options
        and version
        and version < _version(since)
        and options.get(key[0], {}).get(key[1]) == before
    }
    if not changes:
        return config
    today = SimOptions().as_dict()
    options = {section: dict(fields) for section, fields in options.items()}
    for section, name in changes:
        options[section][name] = today[section][name]
    return {**config, "options": options}


def merge_sweeps(folders: Sequence[str | Path], out: str | Path) -> tuple[int, int]:
    """Join segments of one sample (``run_sweep(..., start=)``: the same space, seed, sampler,
    options and catalogues, and the same solver version or versions whose metrics are this
    solver's, ``sim.metrics.SAME_METRICS_AS``, then listed in ``solver_versions``: a segment
    made before a solver change that kept the metrics joins the later ones, as a migrated
    sweep would) into the new sweep folder ``out``, whose table
    ``fingertip train`` reads: config.json (``n`` the largest, ``start`` the smallest, the
    segments listed), meta.json, and the tables' rows by index (no records nor curves: train
    from it, resume the segments). Returns ``(rows, segments)``; a ``DesignError`` naming the
    folder whose configuration differs or whose designs overlap another's."""
    folders = [Path(f) for f in folders]
    out = Path(out)
    if len(folders) < 2:
        raise DesignError("SWEEPS", f"give at least two sweep folders, got {len(folders)}")
    if out.exists():
        raise DesignError("--out", f"{out} exists; choose a new folder")
    configs = []
    for folder in folders:
        try:
            configs.append(read_config(folder))
        except (OSError, ValueError) as exc:
            raise DesignError("SWEEPS", f"{folder} is not a sweep folder ({exc})") from None
    versions = sorted({c.get("solver_version") for c in configs}, key=str)
    mixed = len(versions) > 1 and all(same_metrics(v) for v in versions)
    if mixed:  # an earlier version's segment at a default changed since: as made at today's
        configs = [with_todays_defaults(c) for c in configs]
    first = configs[0]
    for folder, config in zip(folders[1:], configs[1:], strict=True):
        for field, words in _FIELD_WORDS.items():
            if field == "start" or (field == "solver_version" and mixed):
                continue
            if config.get(field) != first.get(field):
                raise DesignError("SWEEPS", f"{folder} is a sweep with {words} than {folders[0]}")
        if catalogue_hashes(config) != catalogue_hashes(first):
            raise DesignError("SWEEPS", f"{folder} has other --catalogue files than {folders[0]}")
    merged = {k: v for k, v in first.items() if k != "start"}
    if mixed:  # versions whose metrics are this solver's (SAME_METRICS_AS): a table of this one
        merged["solver_version"] = SOLVER_VERSION
        merged["solver_versions"] = versions
    merged["n"] = max(c["n"] for c in configs)
    start = min(c.get("start", 0) for c in configs)
    if start:
        merged["start"] = start
    merged["segments"] = [
        {"folder": str(f), "start": c.get("start", 0), "n": c["n"]}
        for f, c in zip(folders, configs, strict=True)
    ]
    try:
        rows, _ = merge_tables(folders, out)
    except (OSError, ValueError, *DAMAGED_GZIP) as exc:
        raise DesignError("SWEEPS", str(exc).splitlines()[0]) from None
    write_config(out, merged)
    write_meta(out, provenance(merged, merged["seed"], kind="sweep"))
    return rows, len(folders)


def _progress(total: int, enabled: bool):
    from tqdm import tqdm

    return tqdm(total=total, desc="sweep", unit="design", disable=not enabled, smoothing=0.1)


def _run_local(
    workers: int,
    todo: Iterable,
    options_dict: dict,
    store_result: Callable,
    materials: dict | None = None,
) -> None:
    """Local processes; the parent keeps at most 2 x workers designs in flight."""
    items = iter(todo)
    with process_pool(workers) as pool:
        pending = {}
        for key, point in items:
            pending[pool.submit(evaluate_point, point, options_dict, materials)] = key
            if len(pending) >= 2 * workers:
                break
        while pending:
            finished, _ = wait(pending, return_when=FIRST_COMPLETED)
            for fut in finished:
                store_result(pending.pop(fut), fut.result())
                nxt = next(items, None)
                if nxt is not None:
                    pending[pool.submit(evaluate_point, nxt[1], options_dict, materials)] = nxt[0]


def _connect(address: str):
    """A client of the Dask distributed scheduler at ``address`` (one error line if there is
    none)."""
    try:
        from dask.distributed import Client
    except ImportError:  # pragma: no cover - depends on the installation
        raise DesignError(
            "--scheduler", "needs dask.distributed: pip install 'fingertip[cluster]'"
        ) from None
    try:
        return Client(address, timeout="10s")
    except (OSError, ValueError, TypeError) as exc:
        raise DesignError("--scheduler", f"cannot reach {address}: {exc}") from None


def _run_dask(
    client, todo: list, options_dict: dict, store_result: Callable, materials: dict | None = None
) -> None:
    """A Dask distributed cluster: tasks go to the workers, results come back here."""
    from dask.distributed import as_completed

    with client:
        futures = {
            client.submit(
                evaluate_point, point, options_dict, materials, key=f"fingertip-{key}", pure=False
            ): key
            for key, point in todo
        }
        for fut in as_completed(futures):
            store_result(futures[fut], fut.result())
            fut.release()


def catalogue_hashes(config: Mapping[str, Any]) -> list[str]:
    """The sorted sha256 of the ``--catalogue`` files a run's config records (none: [])."""
    return sorted(c["sha256"] for c in config.get("catalogues", []))


def load_space_config(folder: Path) -> DesignSpace:
    """The space a sweep folder was made with."""
    return space_from_dict(read_config(folder)["space"])


def options_with_overrides(overrides: dict[str, str]) -> SimOptions:
    return apply_overrides(SimOptions(), overrides)
