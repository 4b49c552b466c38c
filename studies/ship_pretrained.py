"""Regenerates surrogate/pretrained/default/ or surrogate/pretrained/default3d/ (and its
README.md): a trained surrogate and its training data copied into the shipped folder.

    python studies/ship_pretrained.py runs/default_surrogate runs/default_sweep
    python studies/ship_pretrained.py runs/default3d_mf runs/sweep3d   # a multi-fidelity one

The shipped folder is what ``fingertip run`` starts from (``default3d``; ``default`` with
``--model 2d``): ``model.safetensors`` (the
checkpoint), ``table.csv.gz`` + ``config.json`` (the training sweep without its curves,
gzipped: the checkpoint's header records the sha256 of the uncompressed table, and active
learning retrains on it),
``report.md`` / ``report.json`` (the held-out evaluation) and a README saying how it was made.
A multi-fidelity checkpoint (``fingertip train SWEEP3D --low-fidelity ...``) goes to
``default3d/``; the 2D checkpoint it was trained on must be the shipped one
(``surrogate/pretrained/default``), whose file its header names by path and sha256.
"""

from __future__ import annotations

import argparse
import json
import shutil
from pathlib import Path

from sim.sweep import TABLE, TABLE_GZ, table_path, table_sha256, write_table_gz
from surrogate import is_multifidelity, load_checkpoint, load_multifidelity
from surrogate._spread import SPREAD_MD
from surrogate._train import TrainConfig

TRAIN_DEFAULTS = TrainConfig()

PRETRAINED = Path(__file__).resolve().parents[1] / "surrogate" / "pretrained"
#: where each kind of checkpoint is shipped: the 2D surrogate, the multi-fidelity one
DEST_2D, DEST_3D = PRETRAINED / "default", PRETRAINED / "default3d"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("run", type=Path, help="fingertip train output folder")
    ap.add_argument("sweep", type=Path, help="the sweep it was trained on")
    ap.add_argument(
        "--spread",
        type=Path,
        help="the folder of `fingertip train SWEEP --seeds ... --out FOLDER` for this sweep: its "
        "spread.md (the targets over other seeds' splits) is shipped beside the report",
    )
    ap.add_argument(
        "--migrated-from",
        metavar="SOURCE",
        help="for a sweep begun by `fingertip migrate-sweep SOURCE SWEEP --revalidate`: the "
        "folder it was first carried from, named in the README's commands (a record keeps only "
        "its last hop, which may be a folder of the machine it was made on)",
    )
    args = ap.parse_args()
    spread = args.spread / SPREAD_MD if args.spread else None
    computed_by = _computed_by(args.sweep)
    migrated = sum(n for (_, carried), n in computed_by.items() if carried)
    if migrated and not args.migrated_from:
        raise SystemExit(
            f"--migrated-from: {migrated} of the sweep's records were carried over by "
            "fingertip migrate-sweep; name the folder the sweep was first carried from"
        )
    if spread is not None and not spread.is_file():  # before anything is copied
        raise SystemExit(f"--spread: {spread} not found (run fingertip train --seeds first)")
    three_d = is_multifidelity(args.run / "model.safetensors")
    if three_d and spread is not None:
        raise SystemExit("--spread: fingertip train --seeds trains 2D sweeps only")
    if three_d:
        model = load_multifidelity(args.run / "model.safetensors")
        low = model.header["low_fidelity"]
        if (PRETRAINED.parent.parent / low["path"]).resolve() != (
            DEST_2D / "model.safetensors"
        ).resolve():
            raise SystemExit(
                f"the multi-fidelity checkpoint's 2D surrogate is {low['path']}: train it on "
                "the shipped one (--low-fidelity surrogate/pretrained/default)"
            )
    else:
        model = load_checkpoint(args.run / "model.safetensors")
    dest = DEST_3D if three_d else DEST_2D
    table = table_path(args.sweep)
    digest = table_sha256(table)
    header = model.header
    if header["training_data"]["table_sha256"] != digest:
        raise SystemExit(f"the checkpoint was not trained on this sweep's table ({table})")
    dest.mkdir(parents=True, exist_ok=True)
    for src, name in (
        (args.run / "model.safetensors", "model.safetensors"),
        (args.run / "report.md", "report.md"),
        (args.run / "report.json", "report.json"),
        (args.sweep / "config.json", "config.json"),
    ):
        shutil.copyfile(src, dest / name)
    if table != dest / TABLE_GZ:
        write_table_gz(table, dest / TABLE_GZ)
    (dest / TABLE).unlink(missing_ok=True)  # the plain table of an earlier ship
    if spread is not None:
        shutil.copyfile(spread, dest / SPREAD_MD)
    else:
        (dest / SPREAD_MD).unlink(missing_ok=True)  # an earlier ship's, not this checkpoint's
    sweep_cfg = json.loads((args.sweep / "config.json").read_text())
    data = header["training_data"]
    report = json.loads((args.run / "report.json").read_text())
    sweep, run = args.sweep.as_posix(), args.run.as_posix()
    title = (
        "# The shipped multi-fidelity surrogate of the default 3D design space"
        if three_d
        else "# The shipped surrogate of the default design space"
    )
    train = f"fingertip train {sweep} --out {run} --seed {header['training']['seed']}"
    if three_d:
        train = (
            f"fingertip train {sweep} --low-fidelity surrogate/pretrained/default "
            f"--method {header['method']} --out {run} --seed {header['training']['seed']}"
        )
    members = header["architecture"]["members"]
    if members != TRAIN_DEFAULTS.members:  # the command names what the default does not give
        train += f" --members {members}"
    lines = [
        title,
        "",
        "How it was made (on the 2-core development machine):",
        "",
        "```bash",
        *(
            [f"fingertip migrate-sweep {args.migrated_from} {sweep} --revalidate"]
            if migrated
            else []
        ),
        *_sweep_commands(sweep, sweep_cfg),
        train,
        f"python studies/ship_pretrained.py {run} {sweep}"
        + (f" --spread {args.spread.as_posix()}" if spread else ""),
        "```",
        "",
        *_segments_note(sweep_cfg),
        *_computed_by_note(computed_by, header["solver_version"]),
        *(
            [
                f"- low fidelity: `{header['low_fidelity']['path']}` (sha256 "
                f"`{header['low_fidelity']['sha256']}`, its data of solver "
                f"{header['low_fidelity']['solver_version']}); method `{header['method']}` "
                "(`docs/multifidelity.md`)"
            ]
            if three_d
            else []
        ),
        f"- design space: `sim/data/{'default_space_3d' if three_d else 'default_space'}.toml` "
        f"({sweep_cfg['sampler']} sampling, "
        f"seed {sweep_cfg['seed']}), solver version {header['solver_version']}",
        f"- dataset: `table.csv.gz` (gzip of the sweep's `table.csv`; the sha256 is that of the "
        f"uncompressed table), {data['n_rows']} designs, {data['n_used']} with FE results "
        f"(train {len(data['split_table_index']['train'])}, validation "
        f"{len(data['split_table_index']['val'])}, test {len(data['split_table_index']['test'])})"
        f"; sha256 `{digest}`",
        f"- checkpoint: `model.safetensors` ({(dest / 'model.safetensors').stat().st_size:,} "
        f"bytes), {header['architecture']['members']} members, git commit "
        f"`{header['git_commit'][:12]}`",
        f"- held-out test designs: {report['n_test']}; see `report.md`",
        *(
            [
                "- the same sweep trained with other seeds (other held-out designs): `spread.md` "
                "(its first line gives the command)"
            ]
            if spread
            else []
        ),
        "",
    ]
    (dest / "README.md").write_text("\n".join(lines))
    print(f"shipped to {dest}")


def _sweep_commands(sweep: str, cfg: dict) -> list[str]:
    """The commands that made the sweep: one ``fingertip sweep``, or, for a sweep merged from
    segments (``config.json``'s ``segments``), one per segment and the merge."""
    seed = cfg["seed"]
    segments = cfg.get("segments")
    three_d = "--model 3d " if _is_3d(cfg) else ""
    if not segments:
        return [f"fingertip sweep {three_d}--n {cfg['n']} --out {sweep} --workers 2 --seed {seed}"]
    lines = []
    for seg in sorted(segments, key=lambda seg: seg["start"]):  # merged in the given order
        start = f"--start {seg['start']} " if seg["start"] else ""
        lines.append(
            f"fingertip sweep {three_d}{start}--n {seg['n']} "
            f"--out runs/seg_{seg['start']}_{seg['n']} "
            f"--workers 2 --seed {seed}  # kept as {seg['folder']}"
        )
    folders = " ".join(seg["folder"] for seg in segments)
    lines.append(f"fingertip merge-sweeps {folders} --out {sweep}")
    return lines


def _is_3d(cfg: dict) -> bool:
    """Whether a sweep's ``config.json`` is one of the 3D model."""
    return cfg.get("options", {}).get("model", {}).get("dimension") == "3d"


def _segments_note(cfg: dict) -> list[str]:
    if not cfg.get("segments"):
        return []
    versions = cfg.get("solver_versions", [])
    joined = (
        f" Its segments were computed by solvers {', '.join(versions)}, whose metrics are those"
        f" of solver {cfg['solver_version']} (`sim.metrics.SAME_METRICS_AS`, with the evidence"
        " for each version)."
        if len(versions) > 1
        else ""
    )
    kept = (
        " The 3D segments stay in `datasets/default3d/`."
        if _is_3d(cfg)
        else " A segment kept as `surrogate/pretrained/default` is the table shipped before this"
        " one; the `datasets/` copies are removed once shipped: both stay in the git history."
    )
    return [
        "The sweep was made in segments of the same Sobol sample (designs `start` to `n - 1`"
        " each), whose tables were kept where each command's comment says, and merged"
        " (`sim.sweep.run.merge_sweeps`)." + kept + joined,
        "",
    ]


def _computed_by(sweep: Path) -> dict[tuple[str, bool], int]:
    """(solver version, carried over by ``fingertip migrate-sweep``) -> how many of the sweep's
    records. A computed record names the version that computed it; a carried one that of the
    folder it was carried from (a row carried from a table alone has no version of its own)."""
    out: dict[tuple[str, bool], int] = {}
    for path in (sweep / "records").glob("*.json"):
        rec = json.loads(path.read_text())
        key = (str(rec.get("solver_version")), "migrated" in rec)
        out[key] = out.get(key, 0) + 1
    return out


def _computed_by_note(computed_by: dict[tuple[str, bool], int], solver: str) -> list[str]:
    """A line on the records carried over from earlier solver versions; none if none were."""
    if not any(carried for _, carried in computed_by):
        return []
    counts = "; ".join(
        f"{n} carried over from a sweep of solver {version}"
        if carried
        else f"{n} computed by solver {version}"
        for (version, carried), n in sorted(computed_by.items())
    )
    return [
        f"The sweep's records: {counts}. A carried record is what solver {solver} computes, "
        "within the tolerance `sim.metrics.SAME_METRICS_AS` records for the versions between "
        "(`sim/sweep/_migrate.py`, `sim/sweep/_revalidate.py`); `migrated` in each record "
        "names the folder it was carried from.",
        "",
    ]


if __name__ == "__main__":
    main()
