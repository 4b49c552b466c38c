"""The ``fingertip`` command line: thin subcommands over the library.

Errors in user input print one line ``fingertip: error: <field>: <message>`` and exit with 2,
without a traceback.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from collections.abc import Callable

from sim import DesignError, design_from_dict, homogeneous_design, load_design, simulate
from sim.metrics import PROTOCOLS, metric_registry
from sim.options import MODELS, SimOptions, apply_overrides, parse_override
from sim.protocols import shown_hysteresis
from sim.provenance import check_new_folder, json_text

__all__ = ["main"]


class UsageError(Exception):
    """Bad command-line input: printed as one line, exit code 2."""


def _workers_help() -> str:
    from sim.sweep import default_workers

    return (
        f"FE processes (default {default_workers()}: one per usable core; one design's FE runs "
        "on one core, and the answer never depends on the number)"
    )


def _add_catalogue_option(p) -> None:
    from pathlib import Path

    p.add_argument(
        "--catalogue",
        action="append",
        type=Path,
        metavar="FILE.toml",
        help="a user material catalogue (e.g. from fit-material), merged with the shipped one; "
        "a name defined twice is refused (repeatable)",
    )


def _user_catalogues(args: argparse.Namespace):
    """The ``--catalogue`` files and the merged catalogue (shipped + user), read once per
    command (the note on untested materials and the command itself share them)."""
    from sim.materials import load_user_catalogues

    if getattr(args, "_catalogues", None) is None:
        args._catalogues = load_user_catalogues(args.catalogue or [])
    return args._catalogues


def _note_untested_materials(args: argparse.Namespace) -> None:
    """One ``note:`` line on stderr for each ``--catalogue`` material whose tested strain range
    is unknown (no ``fit-material`` provenance, not of a family's law): it is held to the
    paper's limit, flagged "untested" in its results, which its own tests might not license."""
    if not getattr(args, "catalogue", None):
        return
    from pathlib import Path

    from sim.protocols.validity import PAPER_LOG_STRAIN, layer_limit

    for user in _user_catalogues(args)[0]:
        for material in user.materials:
            if layer_limit(material).basis == "untested":
                print(
                    f"note: {Path(user.path).name}:{material.name}: no tested strain range "
                    f"(fingertip fit-material records it); held to the paper's compressive log "
                    f"strain of {PAPER_LOG_STRAIN:g}, flagged untested",
                    file=sys.stderr,
                )


#: the answers a search run names (summary.json's ``answers``; ``fingertip ... --answer NAME``)
ANSWER_NAMES = ("best", "gel", "foam", "buildable")
_ANSWER_HELP = (
    "an answer of the search run given as the input (a run folder of fingertip run / optimize, "
    f"or its summary.json): {', '.join(ANSWER_NAMES)}, e.g. runs/main --answer gel (the same "
    "design as the run's answers/NAME.toml)"
)


def _answer_design(source, name: str) -> dict:
    """The design-file dict of answer ``name`` of the search run ``source`` (a run folder or
    its summary.json): one error line naming --answer otherwise."""
    from explore._run_folder import read_answer

    return read_answer(source, name)["design"]


def _not_a_run(path, field: str) -> None:
    """A search run folder (or its summary.json) given where a design file is expected, without
    --answer: one error line saying how to name one of its answers."""
    from pathlib import Path

    path = Path(path)
    run = path.is_dir() and (path / "summary.json").is_file()
    if run or path.name == "summary.json":
        what = "search run folder" if run else "search run's summary"
        raise DesignError(
            field,
            f"{path} is a {what}: name one of its answers with --answer NAME "
            f"({', '.join(ANSWER_NAMES)}), or give a design file such as "
            f"{(path if run else path.parent) / 'answers' / 'best.toml'}",
        )


def _cmd_simulate(args: argparse.Namespace) -> int:
    if (args.design is None) == (args.material is None):
        raise UsageError(
            "simulate: give either DESIGN.toml (or a search run folder with --answer NAME) or "
            "--material NAME"
        )
    if args.answer is not None and args.design is None:
        raise UsageError(
            "--answer: give the search run folder (or its summary.json) whose answer it names, "
            "e.g. fingertip simulate runs/main --answer best"
        )
    user, catalogue = _user_catalogues(args)
    if args.answer is not None:
        design = design_from_dict(_answer_design(args.design, args.answer), catalogue)
    elif args.material:
        design = homogeneous_design(args.material, catalogue=catalogue)
    else:
        _not_a_run(args.design, "DESIGN")
        design = load_design(args.design, catalogue)
    protocols = PROTOCOLS if args.protocol == "all" else (args.protocol,)
    options = _sim_options(args)
    if args.out is not None:
        check_new_folder(args.out)  # fail before computing, not after
    result = simulate(design, protocols, options, keep_fields=args.out is not None)
    if args.out is not None:
        from sim.output import write_result

        write_result(result, args.out, options, catalogues=user)
    tap = result.protocols.get("tapping", {})
    if args.json:
        sys.stdout.write(json_text(result.to_json()) + "\n")
    else:
        registry = metric_registry(options.dimension)
        for name, value in result.metrics.items():
            unit = registry[name][1]
            if name == "hysteresis_Nmm":  # 0 below what the solver's tolerances resolve
                value = shown_hysteresis(result.metrics, design, options)
            if value is None or not math.isfinite(value):
                if registry[name][0] in result.stopped:
                    text = "not computed: beyond the validity limits"
                elif result.failures:
                    text = "failed"
                else:
                    text = "not reached (see the options)"
            else:
                text = f"{value:.4f} {unit}"
            print(f"{name:28s} {text}")
        if "settled" in tap:
            print(_settle_line(tap))
        for protocol, summary in result.validity_summaries().items():
            print(_validity_line(protocol, summary, protocol in result.stopped, options))
        print(f"({result.n_dofs} dofs, {result.wall_time_s:.2f} s)")
        if args.out is not None:
            print(f"written to {args.out}")
    for f in result.failures:
        print(
            f"fingertip: simulation failed: {f.protocol} at t = {f.time_s:.4g} s: {f.reason}",
            file=sys.stderr,
        )
    for protocol, violation in result.violations():  # a warning: the exit code is unchanged
        print(f"warning: {protocol}: {violation.warning()}", file=sys.stderr)
    for option, value in result.validity["overridden"].items():
        print(
            f"note: --set validity.{option}={value:g} holds every layer to {value:g}, "
            "overriding the limit its material was tested to",
            file=sys.stderr,
        )
    for protocol, stop in result.validity["stopped"].items():
        print(
            f"warning: {protocol}: stopped at t = {stop['time_s']:.4g} s, its first step beyond "
            "the validity limits: no metrics (--set validity.stop_at_violation=false runs on)",
            file=sys.stderr,
        )
    if tap.get("settled") is False:
        why = "out of reach at its rate of convergence" if tap.get("stalled") else "not reached"
        print(
            f"warning: tapping: periodic state {why} after {tap['taps']} taps (residual "
            f"{tap['residual']:.1e}): the tapping metrics are not converged in time "
            "(--set tapping.max_taps=... --set tapping.stall_window=0)",
            file=sys.stderr,
        )
    return 0 if result.ok else 1


def _sim_options(args: argparse.Namespace) -> SimOptions:
    """The simulation options of ``--model`` and ``--set`` (the model first: which options
    apply depends on it; ``sim.options.apply_overrides`` refuses the other model's)."""
    overrides = dict(parse_override(s) for s in getattr(args, "set", None) or [])
    model = getattr(args, "model", None)
    if model is not None:
        if overrides.get("model.dimension", model) != model:
            raise UsageError(f"--model {model} and --set model.dimension=... disagree")
        overrides = {"model.dimension": model, **overrides}
    return apply_overrides(SimOptions(), overrides)


def _add_model_option(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--model",
        choices=MODELS,
        help="2d: the paper's plane-strain section, forces x 10 mm (default); 3d: the pad swept "
        "along the finger (geometry.half_length_mm, geometry.length_exponent), forces of the "
        "whole pad, with the contact patch (docs/model_3d.md)",
    )


def _settle_line(tap: dict) -> str:
    """Whether the taps reached their periodic state, with the residual and error estimate."""
    state = "periodic state reached" if tap["settled"] else "NOT settled"
    err = tap.get("max_estimated_error")
    err_text = "n/a" if err is None or not math.isfinite(err) else f"{100 * err:.2g} %"
    return (
        f"tapping: {state} after {tap['taps']} taps (residual {tap['residual']:.1e}, "
        f"estimated error of the metrics <= {err_text})"
    )


def _validity_line(
    protocol: str, summary: dict, stopped: bool = False, options: SimOptions | None = None
) -> str:
    """How far the protocol deformed the design, in one line (limits: README, --set validity.*),
    with the layer nearest its compressive limit (``sim.protocols.validity.binding_strain_limit``
    with the ``options``' limits); ``stopped``: up to the step at which it stopped
    (``validity.stop_at_violation``)."""
    from sim.protocols.validity import binding_strain_limit

    validity = (options or SimOptions()).validity
    binding = binding_strain_limit(summary, validity)
    nearest = (
        f" ({binding.label} nearest its limit: {binding.strain:.2f} of {binding.limit:.2f}, "
        f"{binding.basis_words})"
        if binding is not None and binding.label
        else ""
    )
    width = summary["contact_width_at_peak_mm"]
    flags = [
        text
        for text, on in (
            ("reached the base", summary["reached_base"]),
            ("folded", summary["folded"]),
        )
        if on
    ]
    return (
        f"validity ({protocol}): compressive log strain {summary['max_compressive_log_strain']:.2f}"
        + nearest
        + f", min J {summary['min_J']:.2f}"
        + (f", contact width {width:.2f} mm" if width is not None else "")
        + (
            f" x length {summary['contact_length_at_peak_mm']:.2f} mm"
            if summary.get("contact_length_at_peak_mm") is not None
            else ""
        )
        + f", nominal compression {100 * summary['nominal_compression']:.0f} %"
        + "".join(f", {f}" for f in flags)
        + (" (up to its stop)" if stopped else "")
    )


def _add_simulate(p: argparse.ArgumentParser) -> None:
    from pathlib import Path

    p.description = (
        "Simulate one design by FE. Inputs: a design TOML file (docs/designs/*.toml, a search "
        "run's answers/<answer>.toml), or a search run folder or its summary.json with --answer "
        "NAME, or --material NAME of the material catalogue; --catalogue adds a user catalogue."
    )
    p.add_argument(
        "design",
        nargs="?",
        type=Path,
        help="design TOML file; or, with --answer, a search run folder or its summary.json",
    )
    p.add_argument("--answer", metavar="NAME", help=_ANSWER_HELP)
    p.add_argument("--material", help="a catalogue material on the reference geometry")
    p.add_argument("--protocol", choices=[*PROTOCOLS, "all"], default="all")
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.add_argument("--out", type=Path, help="run folder for result, plots and VTU meshes")
    _add_model_option(p)
    p.add_argument(
        "--set",
        action="append",
        metavar="SECTION.FIELD=VALUE",
        help="override an option, e.g. tapping.peak_force_N=4, tapping.frequency_Hz=1, "
        "tapping.rest_s=0.5, tapping.settle_tol=1e-3, wedge.hold_s=50, mesh.h_apex_mm=0.03, "
        "mesh3d.h_apex_mm=0.5 with --model 3d (repeatable; see sim.options.option_names())",
    )
    _add_catalogue_option(p)
    p.set_defaults(func=_cmd_simulate)


def _cmd_sweep(args: argparse.Namespace) -> int:
    from sim.design import DEFAULT_SPACE_3D_PATH, load_space
    from sim.sweep import run_sweep

    user, catalogue = _user_catalogues(args)
    options = _sim_options(args)
    default = DEFAULT_SPACE_3D_PATH if options.model.dimension == "3d" else None
    space = load_space(args.space or default, catalogue)
    summary = run_sweep(
        space,
        args.n,
        args.out,
        workers=args.workers,
        scheduler=args.scheduler,
        seed=args.seed,
        sampler=args.sampler,
        options=options,
        retry_failed=args.retry_failed,
        progress=not args.no_progress,
        catalogues=user,
        start=args.start,
    )
    print(
        f"{summary.n_designs} designs in {summary.folder}: {summary.ok} ok, {summary.failed} "
        f"failed ({summary.computed} computed now in {summary.wall_time_s:.0f} s, "
        f"{summary.skipped} already done)"
    )
    if summary.failed:
        print("  failed designs keep their reason in table.csv; --retry-failed runs them again")
    return 0


def _add_sweep(p: argparse.ArgumentParser) -> None:
    from pathlib import Path

    p.description = (
        "Evaluate a sampled design space by FE into a sweep folder (a dataset for train; "
        "resumable). Inputs: a design-space TOML (default: the shipped one; sim/data/*_space.toml "
        "are examples); --catalogue adds a user catalogue; --out a sweep folder (new, or one to "
        "resume)."
    )
    p.add_argument(
        "space",
        nargs="?",
        type=Path,
        help="design-space TOML (default: the shipped one, sim/data/default_space.toml; with "
        "--model 3d sim/data/default_space_3d.toml, which adds the pad's length and profile)",
    )
    p.add_argument("--n", type=int, required=True, help="number of designs")
    p.add_argument("--out", type=Path, required=True, help="sweep folder, e.g. runs/NAME")
    from sim.sweep import default_workers

    p.add_argument("--workers", type=int, default=default_workers(), help=_workers_help())
    p.add_argument("--scheduler", help="Dask distributed scheduler address (tcp://host:port)")
    p.add_argument(
        "--seed",
        type=int,
        default=0,
        help="seed of the scrambled Sobol / Latin-hypercube sample (default 0); resuming a "
        "folder needs the same seed",
    )
    p.add_argument("--sampler", choices=["sobol", "lhs"], default="sobol")
    p.add_argument(
        "--start",
        type=int,
        default=0,
        help="first design of the sample to run (default 0): --start 4096 --n 6144 runs designs "
        "4096-6143 of the Sobol sample, a segment that fingertip merge-sweeps joins to others",
    )
    p.add_argument("--retry-failed", action="store_true", help="run failed designs again")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    _add_model_option(p)
    p.add_argument("--set", action="append", metavar="SECTION.FIELD=VALUE")
    _add_catalogue_option(p)
    p.set_defaults(func=_cmd_sweep)


#: the methods of ``fingertip train SWEEP3D --method`` (``surrogate.MULTIFIDELITY_METHODS``,
#: named here so that the parser does not import the surrogate; a test holds them equal)
MULTIFIDELITY_METHODS = (
    "3d",
    "input",
    "delta",
    "delta-contact",
    "delta-trend",
    "delta-slice",
    "finetune",
)


def _sweep_dimension(folder) -> str:
    """The model ("2d", "3d") a sweep folder's config.json names; "2d" when it names none or
    cannot be read (the training then says what is wrong with the folder)."""
    from sim.sweep import read_config

    try:
        config = read_config(folder)
        return str(config["options"]["model"]["dimension"])
    except (OSError, ValueError, KeyError, TypeError):
        return "2d"


def _cmd_train(args: argparse.Namespace) -> int:
    three_d = _sweep_dimension(args.sweep) == "3d"
    if three_d or args.low_fidelity is not None or args.method is not None:
        return _train_multifidelity(args, three_d)
    if args.seeds is not None:
        return _train_seeds(args)
    if getattr(args, "jobs_given", False):
        raise UsageError("--jobs: the trainings at once of --seeds; give --seeds too")
    from surrogate import train_surrogate

    ckpt = train_surrogate(
        args.sweep,
        args.out,
        seed=args.seed,
        members=args.members,
        max_epochs=args.max_epochs,
        progress=not args.no_progress,
        include_untrusted=args.include_untrusted,
    )
    return _print_training(ckpt)


def _train_multifidelity(args: argparse.Namespace, three_d: bool) -> int:
    """``fingertip train SWEEP3D [--low-fidelity CHECKPOINT] [--method NAME]``: a multi-fidelity
    surrogate of the 3D model's metrics (3D designs alone without --low-fidelity)."""
    if not three_d:
        option = "--low-fidelity" if args.low_fidelity is not None else "--method"
        raise UsageError(
            f"{option}: {args.sweep} is not a sweep of the 3D model; a multi-fidelity surrogate "
            "learns from a 3D sweep (fingertip sweep --model 3d) and a 2D surrogate"
        )
    if args.method is not None and args.method not in MULTIFIDELITY_METHODS:
        raise UsageError(
            f"--method: must be one of {', '.join(MULTIFIDELITY_METHODS)}, got {args.method!r}"
        )
    if args.seeds is not None or getattr(args, "jobs_given", False):
        raise UsageError("--seeds: one training per seed is for 2D sweeps; give --seed")
    from surrogate import train_multifidelity

    ckpt = train_multifidelity(
        args.sweep,
        args.low_fidelity,
        args.method,
        args.out,
        seed=args.seed,
        members=args.members,
        max_epochs=args.max_epochs,
        progress=not args.no_progress,
        include_untrusted=args.include_untrusted,
    )
    report = json.loads((ckpt.parent / "report.json").read_text())
    low = report.get("low_fidelity")
    print(f"method: {report['method']} (low fidelity: {low['path'] if low else 'none, 3D only'})")
    return _print_training(ckpt)


def _print_training(ckpt) -> int:
    """A training run's held-out scores, speed, report and checkpoint, printed."""
    report = json.loads((ckpt.parent / "report.json").read_text())
    left_out = ", ".join(f"{n} {why}" for why, n in sorted(report.get("excluded", {}).items()))
    if left_out:
        print(f"left out (taps not settled / beyond the validity limits): {left_out}")

    def fmt(x, spec: str) -> str:
        return format("-", f">{spec.split('.')[0]}") if x is None else format(x, spec)

    print(f"{'metric (test designs)':28s} {'R2':>7s} {'median err':>10s} {'in 90% int':>10s}")
    for name, s in report["metrics"].items():
        print(
            f"{name:28s} {fmt(s['r2'], '7.3f')} {fmt(s['median_rel_error'], '10.2%')} "
            f"{fmt(s['coverage_90'], '10.0%')}"
        )
    sp = report["speed"]
    print(
        f"inference, batched: {sp['model_designs_per_s']:,.0f} designs/s on "
        f"{sp['torch_threads']} threads, {sp['model_designs_per_s_1_thread']:,.0f} on 1 thread"
    )
    print(f"report: {ckpt.parent / 'report.md'}")
    print(f"checkpoint: {ckpt}")
    return 0


def _train_seeds(args: argparse.Namespace) -> int:
    """``fingertip train SWEEP --seeds ...``: one training per seed and the spread table."""
    from sim.sweep import default_workers

    if getattr(args, "seed_given", False):
        raise UsageError("--seed and --seeds: give one of them (--seeds trains once per seed)")
    if args.out is None:
        raise UsageError(
            "--seeds: give --out, the folder of the trainings (OUT/seed<S> and OUT/spread.md)"
        )
    from surrogate._spread import train_seeds, write_spread

    jobs = args.jobs if args.jobs is not None else min(len(args.seeds), default_workers())
    reports = train_seeds(
        args.sweep,
        args.out,
        args.seeds,
        jobs=jobs,
        members=args.members,
        max_epochs=args.max_epochs,
        include_untrusted=args.include_untrusted,
    )
    command = " ".join(
        [
            f"fingertip train {args.sweep.as_posix()} --seeds",
            *map(str, args.seeds),
            *(["--members", str(args.members)] if args.members != 5 else []),
            *(["--max-epochs", str(args.max_epochs)] if args.max_epochs is not None else []),
            *(["--include-untrusted"] if args.include_untrusted else []),
            f"--out {args.out.as_posix()}",
        ]
    )
    path = write_spread(reports, args.out, command)
    print(path.read_text(), end="")
    for seed in args.seeds:
        print(f"checkpoint (seed {seed}): {args.out / f'seed{seed}' / 'model.safetensors'}")
    print(f"spread: {path}")
    return 0


def _add_train(p: argparse.ArgumentParser) -> None:
    from pathlib import Path

    p.description = (
        "Train the neural surrogate (a deep ensemble) on a sweep. Input: a sweep folder of "
        "fingertip sweep (the dataset: table.csv and config.json); --out a new training run "
        "folder (its model.safetensors is the checkpoint). With --seeds, one training per seed "
        "into OUT/seed<S> and OUT/spread.md: the accuracy targets met by each seed's held-out "
        "designs and by the mean over the seeds. A sweep of the 3D model (fingertip sweep "
        "--model 3d) trains a multi-fidelity surrogate of the 3D metrics: with --low-fidelity, "
        "from a 2D surrogate and the 3D designs (--method), without it from the 3D designs "
        "alone (docs/multifidelity.md)."
    )
    p.add_argument("sweep", type=Path, help="sweep folder (runs/NAME with table.csv)")
    p.add_argument(
        "--out",
        type=Path,
        help="run folder (default: runs/<sweep>-surrogate); with --seeds the folder of the "
        "trainings (required; the same command resumes it)",
    )
    p.add_argument(
        "--seed",
        type=int,
        default=0,
        action=_Given,
        help="seed of the train/validation/test split, the initial weights and the minibatch "
        "order (default 0): the same seed gives the same surrogate",
    )
    p.add_argument(
        "--seeds",
        type=int,
        nargs="+",
        metavar="SEED",
        help="train once per seed (other splits, weights and minibatch orders) and tabulate the "
        "accuracy targets per seed and over the seeds, e.g. --seeds 0 1 2; a seed already "
        "trained in --out is not trained again",
    )
    p.add_argument(
        "--jobs",
        type=int,
        action=_Given,
        help="with --seeds: trainings at once, one process and one torch thread each (default: "
        "one per usable core, at most one per seed)",
    )
    p.add_argument("--members", type=int, default=5, help="ensemble members (default 5)")
    p.add_argument("--max-epochs", type=int, help="cap on epochs (early stopping decides)")
    p.add_argument(
        "--include-untrusted",
        action="store_true",
        help="also learn from designs whose taps did not settle or that went beyond the "
        "validity limits (left out by default)",
    )
    p.add_argument(
        "--low-fidelity",
        type=Path,
        metavar="CHECKPOINT",
        help="with a 3D sweep: the 2D surrogate (a checkpoint file or a training run folder, "
        "e.g. surrogate/pretrained/default) whose predictions the multi-fidelity surrogate "
        "learns from",
    )
    p.add_argument(
        "--method",
        metavar="NAME",
        help="with a 3D sweep, how the 2D surrogate's predictions are used: "
        f"{', '.join(MULTIFIDELITY_METHODS)} (default delta-slice with --low-fidelity, 3d without: "
        "the 3D designs alone)",
    )
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.set_defaults(func=_cmd_train)


def _cmd_predict(args: argparse.Namespace) -> int:
    from surrogate import is_multifidelity, load_checkpoint, load_multifidelity, read_points

    if is_multifidelity(args.checkpoint):  # the 3D metrics, from a multi-fidelity surrogate
        model = load_multifidelity(args.checkpoint)
    else:
        model = load_checkpoint(args.checkpoint, allow_solver_mismatch=args.allow_solver_mismatch)
    if args.answer is not None:
        from sim.design import point_from_design
        from surrogate import check_point

        design = design_from_dict(_answer_design(args.designs, args.answer), model.space.catalogue)
        points = [check_point(model.space, point_from_design(design, model.space))]
    else:
        _not_a_run(args.designs, "DESIGNS")
        points = read_points(args.designs, model.space)
    pred = model.predict(points)
    if args.json:
        out = {
            "checkpoint": str(args.checkpoint),
            "units": dict(zip(pred.metric_names, pred.units, strict=True)),
            "designs": pred.to_records(),
        }
        sys.stdout.write(json_text(out) + "\n")
        return 0
    records = pred.to_records()
    for i, rec in enumerate(records):
        domain = "in domain" if rec["in_domain"] else f"OUT OF DOMAIN ({rec['domain_note']})"
        print(f"design {i}: {domain} (prediction = median, ± std, [90 % interval])")
        for name, unit in zip(pred.metric_names, pred.units, strict=True):
            mid, std = rec["median"][name], rec["std"][name]
            lo, hi = rec["lower_90"][name], rec["upper_90"][name]
            text = "-" if mid is None else f"{mid:.4g} ± {std:.2g} [{lo:.4g}, {hi:.4g}] {unit}"
            print(f"  {name:28s} {text}")
    if any(all(r["mean"][m] is None for r in records) for m in pred.metric_names):
        print("(-: a metric the training sweep never reached, e.g. with a shorter wedge hold)")
    return 0


def _add_predict(p: argparse.ArgumentParser) -> None:
    from pathlib import Path

    p.description = (
        "Predict the metrics of designs with a trained surrogate (a multi-fidelity one, "
        "trained on a 3D sweep, predicts the 3D model's). Inputs: a checkpoint (a "
        ".safetensors file or a training run folder); designs as a design TOML file (a search "
        "run's answers/<answer>.toml too), a design-point TOML (name = value), a CSV of points "
        "(a sweep's table.csv: a dataset), or a search run folder or its summary.json with "
        "--answer NAME."
    )
    p.add_argument(
        "checkpoint",
        type=Path,
        help="surrogate checkpoint: a .safetensors file, or a training run folder holding "
        "model.safetensors (e.g. surrogate/pretrained/default)",
    )
    p.add_argument(
        "designs",
        type=Path,
        help="design TOML file, design-point TOML (name = value) or CSV (one point per row); "
        "or, with --answer, a search run folder or its summary.json",
    )
    p.add_argument("--answer", metavar="NAME", help=_ANSWER_HELP)
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.add_argument(
        "--allow-solver-mismatch",
        action="store_true",
        help="use a checkpoint trained on results of another solver version",
    )
    p.set_defaults(func=_cmd_predict)


def _optimize_config(args: argparse.Namespace):
    from explore._config import OptimizeConfig

    fields = {
        "surrogate": str(args.surrogate) if args.surrogate else None,
        "space": str(args.space) if args.space else None,
        "targets": str(args.targets) if args.targets else None,
        "trials": args.trials,
        "buildable_trials": args.buildable_trials,
        "confirm": args.confirm,
        "uncertain": args.uncertain,
        "rounds": args.rounds,
        "tolerance": args.tolerance,
        "mode": args.mode,
        "max_disagreement": args.max_disagreement,
        "storage": args.storage,
        "study": args.study,
        "seed": args.seed,
        "workers": args.workers,
        "dataset": str(args.dataset) if args.dataset else None,
        "catalogues": tuple(str(p) for p in args.catalogue) if args.catalogue else None,
        "buildable_fe": args.buildable_fe,
        "family_trials": args.family_trials,
        "allow_untrusted": True if args.allow_untrusted else None,
        "credible_at": args.credible_at,
        "screen": args.screen,
        "model": args.model,
    }
    base = OptimizeConfig()
    return OptimizeConfig(
        **{k: v for k, v in fields.items() if v is not None or getattr(base, k) is None}
    )


def _finish(summary, out) -> int:
    """Report a search's ``Summary`` (the one ``optimize`` returned) and write its report."""
    from pathlib import Path

    from explore._report import write_report
    from explore._run_folder import answer_path

    report = write_report(out)
    labels = {
        "best": "best design",
        "gel": "best gel-only design",
        "foam": "best foam-core design",
        "buildable": "best buildable design",
    }
    for kind, label in labels.items():
        a = summary.answers.get(kind)
        if a is None:
            print(f"{label}: none credible confirmed by FE")
            continue
        errs = ", ".join(
            f"{m} {100 * e:+.1f} %{'' if a['within_tolerance'][m] else ' (outside)'}"
            for m, e in a["errors_vs_targets"].items()
        )
        sag = a.get("readings", {}).get("sag_mm")
        sag_text = "" if sag is None else f"; sag {sag:.3g} mm"
        flag = "" if a.get("credible", True) else " [NOT CREDIBLE: --allow-untrusted]"
        print(
            f"{label} (FE){flag}: {errs}; wedge peak "
            f"{a['fe_metrics']['wedge_peak_force_N']:.3g} N{sag_text}"
        )
    for note in summary.notes:
        print(f"  {note}")
    _print_answers_3d(Path(out), labels)
    if summary.timing.get("timings"):
        print(_time_line(summary.timing))
    answers = [p for k in summary.answers if (p := answer_path(Path(out), k)).is_file()]
    if answers:
        print("answers: " + ", ".join(str(a) for a in answers))
    print(f"report: {report}")
    return 0


def _print_answers_3d(out, labels: dict[str, str]) -> None:
    """The answers' 3D results (``--model 3d``: answers_3d.json), one line each."""
    from explore._check3d import not_credible
    from explore._run_folder import read_answers_3d

    answers = read_answers_3d(out).get("answers") or {}
    for kind, label in labels.items():
        a = answers.get(kind)
        if not a:
            continue
        if a.get("status") != "ok":
            print(f"{label} (3D pad): the FE failed ({a.get('reason')})")
            continue
        errs = ", ".join(
            f"{m} {100 * e:+.1f} %{'' if a['within_tolerance'][m] else ' (outside)'}"
            for m, e in a["errors_vs_targets"].items()
        )
        fe = a["fe_metrics"]
        area = "/".join(f"{fe.get(f'contact_area_at_{f}N_mm2') or math.nan:.3g}" for f in (1, 4))
        why = not_credible(a, violations=True)
        flag = f" [not credible: {'; '.join(why)}]" if why else ""
        print(f"{label} (3D pad){flag}: {errs}; contact area at 1 N / 4 N {area} mm^2")


def _time_line(timing: dict) -> str:
    """Where the run's time went: every invocation that worked on it, a resumed run's earlier
    (killed) ones too (``summary.json``'s timing, from the run folder's time.json)."""
    t = timing.get("timings") or {}
    names = (("sweep_s", "sweep"), ("train_s", "training"), ("search_s", "search"),
             ("fe_s", "FE"), ("retrain_s", "retraining"))  # fmt: skip
    stages = ", ".join(
        f"{word} {t.get(key) or 0:.0f} s"
        for key, word in names
        if key in t or key in ("search_s", "fe_s", "retrain_s")
    )
    wall = timing.get("wall_time_s")
    total = "not recorded" if wall is None else f"{wall:.0f} s in all"
    resumed = " (a resumed run: its earlier parts included)" if timing.get("resumed") else ""
    return f"time: {stages}; {total}{resumed}"


def _cmd_optimize(args: argparse.Namespace) -> int:
    from explore._pipeline import optimize

    config = _optimize_config(args)
    summary = optimize(config, args.out, progress=not args.no_progress)
    return _finish(summary, args.out)


def _add_search_options(p, *, defaults_note: str = "") -> None:
    from pathlib import Path

    from explore._config import TRIALS, OptimizeConfig

    d = OptimizeConfig()
    p.add_argument(
        "--surrogate",
        type=Path,
        help="checkpoint (default: the shipped multi-fidelity surrogate/pretrained/default3d, "
        "which searches the 3D pad; with --model 2d the shipped 2D surrogate/pretrained/default)",
    )
    p.add_argument("--space", type=Path, help="design-space TOML inside the surrogate's space")
    p.add_argument("--targets", type=Path, help="targets TOML (default: the human fingertip)")
    p.add_argument(
        "--trials",
        type=int,
        help="surrogate trials per round (default "
        + ", ".join(f"{n} in {m.upper()}" for m, n in TRIALS.items())
        + ")",
    )
    p.add_argument(
        "--buildable-trials",
        type=int,
        help=f"catalogue-only trials per round, 0 = none (default {d.buildable_trials})",
    )
    p.add_argument("--confirm", type=int, help=f"best designs FE-confirmed per round ({d.confirm})")
    p.add_argument(
        "--uncertain", type=int, help=f"flagged promising designs FE-run per round ({d.uncertain})"
    )
    p.add_argument("--rounds", type=int, help=f"active-learning rounds at most ({d.rounds})")
    p.add_argument(
        "--tolerance",
        type=float,
        help=f"surrogate-FE agreement to stop, and target closeness ({d.tolerance})",
    )
    p.add_argument("--mode", choices=["single", "multi"], help="one score or a Pareto front")
    p.add_argument(
        "--max-disagreement",
        type=float,
        help=f"trust guard: ensemble std/|mean| above this is flagged ({d.max_disagreement})",
    )
    p.add_argument(
        "--storage",
        help="Optuna storage several workers share: a journal file path or a database URL "
        "(default: the run folder's own journal, study.log)",
    )
    p.add_argument("--study", help=f"study name prefix (default {d.study})")
    p.add_argument(
        "--seed",
        type=int,
        help=f"seed of the searches (round r uses seed + r; default {d.seed}): the same seed "
        "gives the same answer, whatever --workers",
    )
    p.add_argument("--workers", type=int, help=_workers_help())
    p.add_argument("--dataset", type=Path, help="the surrogate's training sweep (retraining)")
    p.add_argument(
        "--buildable-fe",
        type=int,
        help="buildable stacks of catalogue materials the surrogate cannot predict, simulated by "
        f"FE only after the rounds, 0 = none (default {d.buildable_fe})",
    )
    p.add_argument(
        "--family-trials",
        type=int,
        help="trials per round of each family's own search (gel only, foam core), whose best "
        f"design is FE-confirmed too; 0 = none (default {d.family_trials})",
    )
    p.add_argument(
        "--screen",
        type=int,
        help="designs of a quasi-random sample the surrogate scores at the start of each search; "
        f"the best seed the sampler, 0 = none (default {d.screen})",
    )
    p.add_argument(
        "--allow-untrusted",
        action="store_true",
        help="let designs that are not credible (beyond the validity limits, unsettled, or "
        "sagging over the targets' limit) compete for the answers, flagged as such",
    )
    p.add_argument(
        "--credible-at",
        metavar="{median,bound}",
        help="what a design's credibility is judged on in the search: the surrogate's median "
        "prediction of each strain, volume ratio, settling figure and sag (default in 2D), or "
        "the side of its 90 %% interval towards the limit (bound: credible where the surrogate "
        "is about 95 %% sure; fewer candidates come back from FE beyond a limit; default in 3D)",
    )
    p.add_argument(
        "--model",
        metavar="{2d,3d}",
        help="the model of the answers (default: the surrogate's; without --surrogate, 3d). A "
        "multi-fidelity surrogate (the shipped one, or fingertip train SWEEP3D --low-fidelity "
        "...) searches the 3D pad and confirms every answer with the 3D FE; 2d searches the "
        "paper's plane-strain section with the shipped 2D surrogate; with a 2D --surrogate, 3d "
        "keeps the 2D search and also simulates every 2D answer with the 3D pad (its default "
        "length and profile: answers_3d.json and the report)",
    )
    _add_catalogue_option(p)
    p.add_argument("--no-progress", action="store_true", help="no progress bars")


#: the inputs of a search (``optimize`` and ``run``), for their --help
_SEARCH_INPUTS = (
    "Inputs: --surrogate a checkpoint (a .safetensors file or a training run folder; default "
    "the shipped one of --model), --space a design-space TOML, --targets a targets TOML "
    "(default the human fingertip, sim/data/human_targets.toml), --dataset the surrogate's "
    "sweep folder (a dataset, for retraining), --catalogue a user catalogue, --storage an "
    "Optuna journal file or database URL; --out the search run folder (new, or one to "
    "resume), which ends with summary.json, report.md and answers/<answer>.toml (design files)."
)


def _add_optimize(p: argparse.ArgumentParser) -> None:
    from pathlib import Path

    p.description = "Search the surrogate, confirm with FE, retrain (resumable). " + _SEARCH_INPUTS
    _add_search_options(p)
    p.add_argument("--out", type=Path, required=True, help="run folder (resumes if it exists)")
    p.set_defaults(func=_cmd_optimize)


class _Given(argparse.Action):
    """An option's value, stored with the fact that it was given (``<dest>_given``): an
    option that only means something beside another one can then be refused without it."""

    def __call__(
        self,
        parser: argparse.ArgumentParser,
        namespace: argparse.Namespace,
        values: object,
        option_string: str | None = None,
    ) -> None:
        setattr(namespace, self.dest, values)
        setattr(namespace, f"{self.dest}_given", True)


def _cmd_run(args: argparse.Namespace) -> int:
    from explore._pipeline import run

    if getattr(args, "n_given", False) and not args.from_scratch:
        raise UsageError(
            "--n: the designs of the --from-scratch sweep; give --from-scratch too, or leave "
            "--n out (without it the search starts from the shipped surrogate)"
        )
    scratch = args.n if args.from_scratch else None
    summary = run(_optimize_config(args), args.out, from_scratch=scratch,
                  progress=not args.no_progress)  # fmt: skip
    return _finish(summary, args.out)


def _add_run(p: argparse.ArgumentParser) -> None:
    from pathlib import Path

    p.description = (
        "The main job: the shipped multi-fidelity surrogate (3D; --model 2d: the shipped 2D "
        "one; or, with --from-scratch, a 2D sweep and a training first) -> search -> FE "
        "confirmation -> report and answer files. " + _SEARCH_INPUTS
    )
    _add_search_options(p)
    p.add_argument(
        "--out", type=Path, default=Path("runs/main"), help="run folder (default runs/main)"
    )
    p.add_argument(
        "--from-scratch",
        action="store_true",
        help="sweep the default space with the 2D model and train a 2D surrogate first, then "
        "search the 2D model with it (about 9 hours on 2 cores: 8.6 h of sweep at 2.8 s a "
        "design, README; the 3D dataset: datasets/README.md)",
    )
    p.add_argument(
        "--n",
        type=int,
        default=11008,
        action=_Given,
        help="designs of the --from-scratch sweep (as shipped; only with --from-scratch)",
    )
    p.set_defaults(func=_cmd_run)


def _cmd_report(args: argparse.Namespace) -> int:
    from explore._report import write_report
    from sim.provenance import KINDS, folder_kind

    if not args.run.is_dir():
        raise UsageError(f"report: {args.run} is not a folder")
    kind = folder_kind(args.run)
    if kind != "optimize":
        what = f"holds a {KINDS[kind]}, not" if kind else "is not"
        raise UsageError(
            f"report: {args.run} {what} a search run folder (fingertip optimize / run); "
            "nothing written"
        )
    from explore._pipeline import write_answer_files

    answers = write_answer_files(args.run)
    report = write_report(args.run)
    if answers:
        print("answers: " + ", ".join(str(a) for a in answers))
    print(f"report: {report}")
    return 0


def _add_report(p: argparse.ArgumentParser) -> None:
    from pathlib import Path

    p.description = (
        "Write a search run's report.md, figures/ and answers/<answer>.toml (the answers as "
        "design files). Input: a search run folder of fingertip run / optimize."
    )
    p.add_argument("run", type=Path, help="search run folder of fingertip optimize / run")
    p.set_defaults(func=_cmd_report)


def _cmd_fit_material(args: argparse.Namespace) -> int:
    from sim.materials import CATALOGUE
    from sim.materials.fit import (
        MODES,
        STABILITY_STRAIN_RANGE,
        fit_material,
        read_curve,
        read_relaxation,
        write_fit,
    )

    if args.name in CATALOGUE:
        raise DesignError(
            "--name", f"{args.name!r} is a shipped catalogue material; choose another"
        )
    curves = [read_curve(getattr(args, m), m) for m in MODES if getattr(args, m) is not None]
    relaxation = read_relaxation(args.relaxation) if args.relaxation is not None else None
    fit = fit_material(
        args.model, curves, name=args.name, relaxation=relaxation, terms=args.terms,
        nu=args.nu, prony_terms=args.prony, source=args.source, rate_per_s=args.rate_per_s,
    )  # fmt: skip
    paths = write_fit(fit, args.out)
    terms = f", {fit.terms} terms" if fit.terms is not None else ""
    nu = f"nu = {fit.nu:g}" + ("" if fit.nu_given else " (assumed: no --nu)")
    print(f"{fit.name}: {fit.model}{terms}, {nu}, moduli = {fit.moduli}")
    for key, value in fit.params.items():
        print(f"  {key:10s} = {value}")
    if fit.prony is not None:
        print(f"  prony_g    = {list(fit.prony.g)}\n  prony_tau_s = {list(fit.prony.tau_s)}")
    print(f"{'test':12s} {'points':>6s} {'nominal strain':>18s} {'R2':>8s} {'rms':>12s}")
    for m in fit.modes:
        span = f"{m.strain_range[0]:g}..{m.strain_range[1]:g}"
        print(f"{m.mode:12s} {m.n_points:6d} {span:>18s} {m.r2:8.4f} {m.rms_MPa:8.3g} MPa")
    if fit.prony is not None:
        p = fit.prony
        span = f"t {p.time_range_s[0]:g}..{p.time_range_s[1]:g} s"
        print(f"{'relaxation':12s} {p.n_points:6d} {span:>18s} {p.r2:8.4f} {p.rms:8.3g} g_R")
    lo, hi = STABILITY_STRAIN_RANGE
    ranges = ", ".join(f"{k} {a:g}..{b:g}" for k, (a, b) in fit.stable_ranges.items())
    print(f"Drucker-stable over nominal strains {lo:g}..{hi:g}: {ranges}")
    if not fit.stable_everywhere:
        print(
            f"warning: {fit.name} is not Drucker-stable over nominal strains {lo:g}..{hi:g} "
            f"({ranges}): a design straining it beyond may not converge or be unphysical",
            file=sys.stderr,
        )
    print("written: " + ", ".join(str(p) for p in paths))
    print(f'use it with --catalogue {paths[0]} (material = "{fit.name}")')
    return 0


def _add_fit_material(p: argparse.ArgumentParser) -> None:
    from pathlib import Path

    from sim.materials.fit import FIT_MODELS, MODES

    p.description = (
        "Fit a catalogue entry to test data. Inputs: CSV files of uniaxial, biaxial, planar or "
        "compression tests (nominal strain, nominal stress) and of a relaxation test; --out the "
        "user catalogue TOML to write (for --catalogue of simulate, sweep, optimize, run)."
    )
    p.add_argument("--model", required=True, choices=FIT_MODELS)
    p.add_argument(
        "--terms",
        type=int,
        help="terms of yeoh (1-3, default 3), ogden, hyperfoam (1-3, default 1)",
    )
    for mode in MODES:
        p.add_argument(
            f"--{mode}",
            type=Path,
            metavar="CSV",
            help=f"{mode} test: nominal_strain,nominal_stress_MPa"
            + (" (negative strain and stress)" if mode == "compression" else ""),
        )
    p.add_argument(
        "--relaxation", type=Path, metavar="CSV", help="time_s,g_R (normalised, 1 at t = 0)"
    )
    p.add_argument("--nu", type=float, help="Poisson's ratio (default 0.499, recorded as assumed)")
    p.add_argument("--prony", type=int, help="Prony terms fitted to --relaxation (default 3)")
    p.add_argument(
        "--rate-per-s",
        type=float,
        help="nominal strain rate of the tests: with --relaxation the curves are fitted through "
        "the Prony terms and the moduli are the instantaneous ones",
    )
    p.add_argument("--name", required=True, help="catalogue name of the material")
    p.add_argument("--out", type=Path, required=True, help="catalogue entry to write (TOML)")
    p.add_argument("--source", help="where the test data come from (default: the CSV files)")
    p.set_defaults(func=_cmd_fit_material)


def _cmd_merge_sweeps(args: argparse.Namespace) -> int:
    from sim.sweep import merge_sweeps

    rows, n = merge_sweeps(args.sweeps, args.out)
    print(f"{args.out}: {rows} designs from {n} sweep folders")
    return 0


def _add_merge_sweeps(p: argparse.ArgumentParser) -> None:
    from pathlib import Path

    p.description = (
        "Join segments of one sweep sample (fingertip sweep --start S --n N, the same space, "
        "seed, sampler, options, solver version and catalogues, not overlapping) into one sweep "
        "folder that fingertip train reads. Inputs: two or more sweep folders (segments); --out "
        "the new merged folder (config.json, meta.json and table.csv: no records; resume a "
        "segment in its own folder, then merge again)."
    )
    p.add_argument("sweeps", type=Path, nargs="+", metavar="SWEEP", help="sweep folders")
    p.add_argument("--out", type=Path, required=True, help="the new, merged sweep folder")
    p.set_defaults(func=_cmd_merge_sweeps)


def _cmd_migrate_sweep(args: argparse.Namespace) -> int:
    from sim.metrics import SOLVER_VERSION
    from sim.sweep._migrate import (
        MAX_METRICS_RTOL,
        VERIFY_RTOL,
        migrate,
        resume_command,
        verify,
    )

    if args.verify < 0:
        raise UsageError(f"--verify: must be >= 0, got {args.verify}")
    if args.rtol is not None and args.verify == 0:
        raise UsageError("--rtol: applies to --verify K with K >= 1, which was not given")
    rtol = VERIFY_RTOL if args.rtol is None else args.rtol
    if not 0.0 <= rtol <= MAX_METRICS_RTOL:  # also NaN
        raise UsageError(f"--rtol: must be in [0, {MAX_METRICS_RTOL:g}], got {args.rtol}")
    metrics_only = args.rtol is not None or args.revalidate  # a table's row has no curves
    if args.revalidate:
        from sim.sweep._revalidate import revalidate

        kept, keys, config, reasons = revalidate(args.source, args.target)
    else:
        kept, keys, config = migrate(args.source, args.target)
        reasons = {}
    total = len(set(keys))
    print(
        f"{len(kept)} of {total} designs carried over to {args.target} (solver "
        f"{SOLVER_VERSION}); {total - len(kept)} left for the resumed sweep"
    )
    for why, count in sorted(reasons.items(), key=lambda kv: -kv[1]):
        print(f"  re-run: {count} {why}")
    what = "metrics and validity" if metrics_only else "metrics, diagnostics and curves"
    checks = verify(args.target, kept, config, args.verify, args.seed, metrics_only)
    for key, worst, where in checks:
        if worst > rtol:
            print(
                f"fingertip: verify: {key}: {where} differs from the carried record by "
                f"{worst:.2g} (more than {rtol:g})",
                file=sys.stderr,
            )
            return 1
        text = "identical" if worst == 0.0 else f"equal to {worst:.1e} relative (at {where})"
        print(f"verify: {key}: {what} {text}", flush=True)
    print(f"resume: {resume_command(args.target, config)}")
    return 0


def _add_migrate_sweep(p: argparse.ArgumentParser) -> None:
    from pathlib import Path

    p.description = (
        "Carry a sweep of an earlier solver version (one whose results this solver reproduces, "
        "sim.metrics.SAME_METRICS_AS) over to this one: the designs that completed within the "
        "validity limits are kept as they are, and those beyond them when the source stopped at "
        "the limits as this solver does; the others are left for the resumed sweep. "
        "Inputs: SOURCE, the earlier sweep folder; TARGET, the new sweep folder to write."
    )
    p.add_argument(
        "source", type=Path, metavar="SOURCE", help="sweep folder of an earlier solver version"
    )
    p.add_argument(
        "target", type=Path, metavar="TARGET", help="the new sweep folder (must not exist)"
    )
    p.add_argument(
        "--verify",
        type=int,
        default=0,
        metavar="K",
        help="re-simulate K carried designs and fail unless they equal their records "
        "(default 0: none)",
    )
    p.add_argument(
        "--rtol",
        type=float,
        default=None,
        metavar="R",
        help="with --verify: compare the metrics within R relative and the validity and "
        "settling exactly, not the curves and counts (for a solver that changed Newton's path, "
        "as the 3D model's solvers have; at most 1e-3, the periodic state's tolerance; "
        "default: everything to round-off)",
    )
    p.add_argument(
        "--seed", type=int, default=0, help="seed of the designs --verify draws (default 0)"
    )
    p.add_argument(
        "--revalidate",
        action="store_true",
        help="carry SOURCE over from its table alone (config.json and table.csv suffice: a "
        "kept segment or the shipped surrogate's folder) to each layer's own strain limit: "
        "when it was made with one limit for every layer (validity.max_compressive_log_strain, "
        "as the shipped surrogate's sweep), the designs whose course the layers' limits "
        "change (and every valid design of several layers) are left for the resumed sweep; "
        "made under the layers' limits, every design is carried (sim/sweep/_revalidate.py)",
    )
    p.set_defaults(func=_cmd_migrate_sweep)


#: ``fingertip learning-curve``'s default sizes (training + validation designs)
LEARNING_CURVE_SIZES = (128, 256, 512, 1024, 4096)


def _cmd_learning_curve(args: argparse.Namespace) -> int:
    if args.out.suffix != ".md":
        raise UsageError(f"--out: a Markdown file (.md), got {args.out}")
    if args.out.is_dir():
        raise UsageError(f"--out: {args.out} is a folder; give the Markdown file to write")
    from surrogate._learning_curve import CHECKED, learning_curve, write_learning_curve

    def show(row: dict) -> None:
        summary = ", ".join(
            f"{m}: R2 {row[m]['r2']:.3f} med {100 * row[m]['median_rel_error']:.1f} %"
            for m in CHECKED
            if row.get(m, {}).get("r2") is not None and row[m].get("median_rel_error") is not None
        )
        print(
            f"n = {row['n_designs']:5d} ({row['train_seconds']:.0f} s per fit): {summary}",
            flush=True,
        )

    sizes = sorted(args.sizes)
    result = learning_curve(
        args.sweep,
        sizes,
        seed=args.seed,
        repeats=args.repeats,
        jobs=args.jobs,
        members=args.members,
        max_epochs=args.max_epochs,
        on_size=show,
    )
    command = " ".join(
        [
            f"fingertip learning-curve {args.sweep.as_posix()} --sizes",
            *map(str, sizes),
            f"--seed {args.seed} --repeats {args.repeats}",
            *(["--members", str(args.members)] if args.members != 5 else []),
            *(["--max-epochs", str(args.max_epochs)] if args.max_epochs is not None else []),
            f"--out {args.out.as_posix()}",
        ]
    )
    paths = write_learning_curve(result, args.out, command)
    print("written: " + ", ".join(str(p) for p in paths))
    return 0


def _add_learning_curve(p: argparse.ArgumentParser) -> None:
    from pathlib import Path

    p.description = (
        "The surrogate's test error against the number of FE designs it is trained on: one "
        "fixed test set (15 % of the sweep's designs), ensembles trained on nested subsets of "
        "the others, and a power law extrapolated to the accuracy targets. Input: a sweep "
        "folder (a dataset of fingertip sweep or merge-sweeps); --out the Markdown file to "
        "write, with its JSON beside it and figures/<name>.png (docs/learning_curve.md is the "
        "default sweep's)."
    )
    p.add_argument("sweep", type=Path, help="sweep folder (runs/NAME with table.csv)")
    p.add_argument(
        "--out", type=Path, required=True, metavar="FILE.md", help="Markdown file to write"
    )
    p.add_argument(
        "--sizes",
        type=int,
        nargs="+",
        default=list(LEARNING_CURVE_SIZES),
        help="training + validation designs of each point (default "
        f"{' '.join(map(str, LEARNING_CURVE_SIZES))}; above the designs left beside the test "
        "set: all of them)",
    )
    p.add_argument(
        "--seed",
        type=int,
        default=0,
        help="seed of the test set; repeat r draws its subset and trains with seed + r (default 0)",
    )
    p.add_argument("--repeats", type=int, default=3, help="trainings per size, averaged (3)")
    p.add_argument(
        "--jobs", type=int, default=1, help="trainings at once, one process each (default 1)"
    )
    p.add_argument("--members", type=int, default=5, help="ensemble members (default 5)")
    p.add_argument("--max-epochs", type=int, help="cap on epochs (early stopping decides)")
    p.set_defaults(func=_cmd_learning_curve)


#: the subcommands: name -> (one-line help, the function that adds its arguments); only the
#: command being run gets its arguments, so that `fingertip simulate` does not import what the
#: other commands' options need (issue 15: instant start)
_SUBCOMMANDS: dict[str, tuple[str, Callable[[argparse.ArgumentParser], None]]] = {
    "simulate": ("simulate one design under the paper's protocols", _add_simulate),
    "sweep": ("evaluate a sampled design space by FE (resumable)", _add_sweep),
    "train": ("train the neural surrogate (deep ensemble) on a sweep", _add_train),
    "predict": ("predict metrics of designs with a trained surrogate", _add_predict),
    "optimize": ("search the surrogate, confirm with FE, retrain (resumable)", _add_optimize),
    "run": ("the main job: shipped surrogate -> search -> FE confirmation -> report", _add_run),
    "report": ("write the one-page report of a search run", _add_report),
    "fit-material": (
        "fit a catalogue entry to test data (Abaqus' nominal stress-strain conventions)",
        _add_fit_material,
    ),
    "merge-sweeps": ("join segments of one sweep sample into one sweep folder", _add_merge_sweeps),
    "migrate-sweep": (
        "carry a sweep of an earlier solver version over to this one",
        _add_migrate_sweep,
    ),
    "learning-curve": (
        "the surrogate's test error against the number of FE designs it is trained on",
        _add_learning_curve,
    ),
}


def build_parser(command: str | None = None) -> argparse.ArgumentParser:
    """The ``fingertip`` parser; with ``command``, only that subcommand gets its arguments
    (the others keep their one-line help, for ``fingertip --help``)."""
    parser = argparse.ArgumentParser(
        prog="fingertip", description="Design explorer for human-like fingertip skins."
    )
    parser.add_argument(
        "--version", action=_Version, help="print the version of the fingertip package and exit"
    )
    sub = parser.add_subparsers(dest="command", required=True)
    for name, (help_, add_arguments) in _SUBCOMMANDS.items():
        p = sub.add_parser(name, help=help_)
        if command is None or command == name:
            add_arguments(p)
    return parser


class _Version(argparse.Action):
    """``--version``: the package version on stdout, exit 0 (looked up only when asked: the
    metadata lookup costs every other command's start-up nothing)."""

    def __init__(self, option_strings: list[str], dest: str, help: str | None = None) -> None:
        super().__init__(option_strings, argparse.SUPPRESS, nargs=0, help=help)

    def __call__(
        self,
        parser: argparse.ArgumentParser,
        namespace: argparse.Namespace,
        values: object,
        option_string: str | None = None,
    ) -> None:
        print(f"fingertip {package_version()}")
        parser.exit()


def package_version() -> str:
    """The installed fingertip package's version (its metadata, from pyproject.toml); from
    pyproject.toml itself in a source tree that is not installed."""
    from importlib import metadata

    try:
        return metadata.version("fingertip")
    except metadata.PackageNotFoundError:
        import tomllib
        from pathlib import Path

        pyproject = Path(__file__).resolve().parents[1] / "pyproject.toml"
        try:
            return tomllib.loads(pyproject.read_text())["project"]["version"]
        except (OSError, KeyError, tomllib.TOMLDecodeError):
            return "unknown"


def _command(argv: list[str]) -> str | None:
    """The subcommand ``argv`` names (its first word that is not an option): "" when it names
    none (``fingertip --help``: no subcommand needs its arguments), None when the word is no
    subcommand (every subcommand is built, for argparse's error)."""
    first = next((a for a in argv if not a.startswith("-")), None)
    if first is None:
        return ""
    return first if first in _SUBCOMMANDS else None


def _input_errors() -> tuple[type[Exception], ...]:
    """The errors printed as one line. ``CheckpointError`` only when the surrogate package was
    loaded (only it raises one): ``fingertip simulate`` never imports the surrogate."""
    errors: tuple[type[Exception], ...] = (DesignError, UsageError, FileExistsError)
    loaded = sys.modules.get("surrogate._errors")
    return errors if loaded is None else (*errors, loaded.CheckpointError)


def _check_seed_option(args: argparse.Namespace) -> None:
    """Every subcommand's ``--seed``, as it is parsed: an integer in [0, 2**32 - 1]
    (``sim.errors.check_seed``), before any work."""
    from sim.errors import check_seed

    if getattr(args, "seed", None) is not None:
        check_seed(args.seed)


class _Terminated(KeyboardInterrupt):
    """SIGTERM, raised like Ctrl-C's ``KeyboardInterrupt`` so that the same clean-up runs
    (``sim.pool.Pool`` stops its workers, files are left whole); ``signum``: the signal."""

    def __init__(self, signum: int) -> None:
        super().__init__(signum)
        self.signum = signum


def _terminate_as_interrupt() -> Callable[[], None]:
    """Make SIGTERM raise ``_Terminated`` in this (main) thread until the returned function
    restores the handler before it; a no-op outside the main thread. A process killed by
    SIGTERM's default action skips every ``finally``: its pools' workers and their queues'
    semaphores were left to the resource tracker ("leaked semaphore objects")."""
    import signal
    import threading

    if threading.current_thread() is not threading.main_thread():
        return lambda: None

    def terminate(signum: int, frame: object) -> None:
        raise _Terminated(signum)

    before = signal.signal(signal.SIGTERM, terminate)
    return lambda: signal.signal(signal.SIGTERM, signal.SIG_DFL if before is None else before)


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    args = build_parser(_command(argv)).parse_args(argv)
    restore = _terminate_as_interrupt()
    try:
        _check_seed_option(args)
        _note_untested_materials(args)
        return args.func(args)
    except _input_errors() as exc:  # evaluated once something is raised
        print(f"fingertip: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt as exc:  # Ctrl-C, or SIGTERM (_Terminated)
        signum = exc.signum if isinstance(exc, _Terminated) else 2
        print(f"fingertip: {'terminated' if signum != 2 else 'interrupted'}", file=sys.stderr)
        return 128 + signum
    except BrokenPipeError:  # e.g. `fingertip predict ... | head`: the reader left, not an error
        import os

        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 0
    finally:
        restore()


if __name__ == "__main__":
    sys.exit(main())
