"""The sweep folder: every file of ``runs/NAME`` made by ``fingertip sweep``, written and read here.

- ``config.json`` (:func:`write_config`, :func:`read_config`): the resolved space, n, seed,
  sampler, simulation options (``dataclasses.asdict`` form), solver version and the
  ``--catalogue`` files (path, sha256);
- ``meta.json`` (:func:`write_meta`): provenance (git commit, package versions, command) of the
  latest invocation;
- ``records/<key>.json`` (:class:`SweepStore`): one file per evaluated design, written
  atomically, keyed by a hash of the design, the options and the solver version
  (``sim.sweep.run.record_key``): ``key``, ``params`` (the point, inactive = null), ``status``
  ("ok" | "failed"), ``reason``, ``metrics``, ``diagnostics``, ``curves``, ``n_dofs``,
  ``solver_version``, ``wall_time_s``, ``cpu_time_s`` (the worker's CPU seconds; not in
  records made before it was added), ``cost_by_protocol`` (each completed protocol's seconds,
  steps, Newton iterations, factorisations, evaluations and dofs:
  ``sim.sweep.run.protocol_costs``; not in records made before it was added);
- ``table.csv`` (:meth:`SweepStore.consolidate`, columns :func:`table_header`): parameters +
  metrics + diagnostics (each layer's largest strain by role among them: ``sim.metrics.
  role_strains``) (+ status and reason) of every design, rebuilt from the records at the
  end of each invocation; ``curves.jsonl``: the curves of the designs that succeeded, one line
  ``{"index", "key", "curves"}`` per design. ``surrogate.read_sweep`` reads the table.
- ``table.csv.gz`` instead of ``table.csv`` (:func:`write_table_gz`): the same bytes,
  gzip-compressed, in a folder kept in git (``surrogate/pretrained/default``: the table of
  8960 designs is 6.4 MB, 2.6 MB compressed; the project keeps each tracked file under 5 MB so
  that a clone stays small). Every reader finds the
  table with :func:`table_path`, opens it with :func:`open_table` and hashes it with
  :func:`table_sha256` (the hash of the CSV bytes, whichever form holds them).
"""

from __future__ import annotations

import csv
import gzip
import hashlib
import json
import shutil
import zlib
from pathlib import Path
from typing import IO, Any

from ..metrics import diagnostic_names, metric_registry, role_strain_names, role_strains
from ..protocols.loading import profile_summary
from ..provenance import json_safe, json_text, replacing, sha256_file, write_json

__all__ = [
    "CONFIG",
    "CURVES",
    "DAMAGED_GZIP",
    "META",
    "RECORDS",
    "TABLE",
    "TABLE_GZ",
    "SweepStore",
    "merge_tables",
    "open_table",
    "read_config",
    "table_header",
    "table_path",
    "table_sha256",
    "write_config",
    "write_meta",
    "write_table_gz",
]

CONFIG, META, RECORDS, TABLE, TABLE_GZ, CURVES = (
    "config.json",
    "meta.json",
    "records",
    "table.csv",
    "table.csv.gz",
    "curves.jsonl",
)


def table_path(folder: str | Path) -> Path:
    """The table of a sweep folder: ``table.csv``, else ``table.csv.gz`` when only that exists;
    ``table.csv`` when neither does (so that a message names the file a sweep writes)."""
    folder = Path(folder)
    gz = folder / TABLE_GZ
    if not (folder / TABLE).exists() and gz.exists():
        return gz
    return folder / TABLE


#: what reading a damaged ``.gz`` raises (a cut file: ``EOFError``; a bad header:
#: ``gzip.BadGzipFile``; corrupt data: ``zlib.error``): every reader of a table catches these
DAMAGED_GZIP = (EOFError, gzip.BadGzipFile, zlib.error)


def open_table(path: str | Path) -> IO[str]:
    """A table (``table.csv``, or gzip-compressed ``*.gz``) opened as UTF-8 text for ``csv``
    (``newline=""``). A damaged ``.gz`` raises one of :data:`DAMAGED_GZIP` while it is read."""
    path = Path(path)
    if path.suffix == ".gz":
        return gzip.open(path, "rt", encoding="utf-8", newline="")
    return path.open(encoding="utf-8", newline="")


def table_sha256(path: str | Path) -> str:
    """The sha256 (hex) of a table's CSV bytes, decompressed for a ``.gz``: a checkpoint trained
    on ``table.csv`` names the same table after :func:`write_table_gz`."""
    path = Path(path)
    if path.suffix != ".gz":
        return sha256_file(path)
    with gzip.open(path, "rb") as fh:
        return hashlib.file_digest(fh, "sha256").hexdigest()


def write_table_gz(src: str | Path, dest: str | Path) -> None:
    """Compress the table ``src`` into ``dest`` (``table.csv.gz``), atomically and
    reproducibly: level 9, no file name and a zero time stamp in the gzip header, so the same
    table always gives the same bytes (git sees no change when a table is shipped again)."""
    with (
        replacing(Path(dest)) as tmp,
        Path(src).open("rb") as fin,
        tmp.open("wb") as raw,
        gzip.GzipFile(filename="", mode="wb", fileobj=raw, compresslevel=9, mtime=0) as fout,
    ):
        shutil.copyfileobj(fin, fout, 1 << 20)


def read_config(folder: Path) -> dict[str, Any]:
    """A sweep folder's ``config.json`` (``OSError`` / ``ValueError`` when absent or not JSON:
    the caller says which option it came from)."""
    return json.loads((Path(folder) / CONFIG).read_text())


def write_config(folder: Path, config: dict[str, Any]) -> None:
    """Write ``config.json`` (JSON form: tuples become lists)."""
    write_json(Path(folder) / CONFIG, json.loads(json.dumps(config)))


def write_meta(folder: Path, meta: dict[str, Any]) -> None:
    """Write ``meta.json`` (``sim.provenance.provenance``)."""
    write_json(Path(folder) / META, meta)


def table_header(names: list[str], dimension: str = "2d") -> list[str]:
    """The columns of ``table.csv`` for the space parameters ``names`` and the model's metrics
    (``sim.metrics.metric_registry``: a 3D sweep's table has the contact patch too)."""
    return [
        "index",
        "key",
        "status",
        *names,
        *metric_registry(dimension),
        *diagnostic_names(),
        "wall_time_s",
        "reason",
    ]


class SweepStore:
    """The records of a sweep folder (one JSON file per design), and its table and curves."""

    def __init__(self, folder: Path) -> None:
        self.folder = folder
        self.records_dir = folder / RECORDS

    def load(self) -> dict[str, dict]:
        """Every readable record, by key."""
        out = {}
        if self.records_dir.exists():
            for path in self.records_dir.glob("*.json"):
                try:
                    out[path.stem] = json.loads(path.read_text())
                except (json.JSONDecodeError, OSError):
                    continue  # cannot happen with atomic writes; never trust a broken file
        return out

    def write(self, key: str, record: dict) -> None:
        """Write the record of design ``key`` atomically (one line of JSON)."""
        self.records_dir.mkdir(parents=True, exist_ok=True)
        write_json(self.records_dir / f"{key}.json", {"key": key, **record}, indent=None)

    def consolidate(
        self, keys: list[str], names: list[str], first_index: int = 0, dimension: str = "2d"
    ) -> None:
        """Rebuild table.csv and curves.jsonl for ``keys`` (the sweep's designs, in order; the
        first one's ``index`` is ``first_index``: a segment's, its position in the sample) of a
        sweep of the ``dimension`` model."""
        records = self.load()
        metric_names = list(metric_registry(dimension))
        diag_names = diagnostic_names()
        with (
            replacing(self.folder / TABLE) as tmp_table,
            replacing(self.folder / CURVES) as tmp_curves,
            tmp_table.open("w", newline="") as fh,
            tmp_curves.open("w") as fc,
        ):
            writer = csv.writer(fh)
            writer.writerow(table_header(names, dimension))
            for i, key in enumerate(keys, start=first_index):
                rec = records.get(key)
                if rec is None:
                    continue
                params = rec["params"]
                metrics = dict(rec.get("metrics", {}))
                if rec["status"] == "ok" and "profile_1s_area_2mm_mm2" not in metrics:
                    # records from before the profile summary existed: derive it from the curves
                    metrics.update(json_safe(profile_summary(rec.get("curves", {}))))
                writer.writerow(
                    [
                        i,
                        key,
                        rec["status"],
                        *_cells(params, names),
                        *_cells(metrics, metric_names),
                        *_cells(_diagnostics(rec, params), diag_names),
                        f"{rec.get('wall_time_s', 0.0):.3f}",
                        rec.get("reason", ""),
                    ]
                )
                if rec["status"] == "ok":
                    fc.write(
                        json_text({"index": i, "key": key, "curves": rec.get("curves", {})}) + "\n"
                    )


def merge_tables(folders: list[Path], out: Path) -> tuple[int, list[str]]:
    """Make the folder ``out`` with a table.csv of the rows of every folder's table (plain or
    gzipped: :func:`table_path`), by ``index``; returns the number of rows and the header. A
    ``ValueError`` (and no ``out``) when the headers differ or an ``index`` occurs twice
    (segments of one sample never overlap)."""
    header: list[str] | None = None
    rows: dict[int, list[str]] = {}
    for folder in folders:
        path = table_path(folder)
        with open_table(path) as fh:
            reader = csv.reader(fh)
            head = next(reader)
            if header is None:
                header = head
            elif head != header:
                first = table_path(folders[0])
                raise ValueError(f"{path} has other columns than {first}")
            for row in reader:
                i = int(row[0])
                if i in rows:
                    raise ValueError(f"design {i} is in more than one table ({path})")
                rows[i] = row
    assert header is not None
    Path(out).mkdir(parents=True)
    with replacing(Path(out) / TABLE) as tmp, tmp.open("w", newline="") as fh:
        writer = csv.writer(fh)
        writer.writerow(header)
        writer.writerows(rows[i] for i in sorted(rows))
    return len(rows), header


def _diagnostics(record: dict[str, Any], params: dict[str, Any]) -> dict[str, Any]:
    """A record's diagnostics with each layer's strain by role: a record made before the
    diagnostics had them (``sim.metrics.role_strains``) gets them from its per-layer lists."""
    diagnostics = dict(record.get("diagnostics") or {})
    count = params.get("layers.count")
    if count is not None and all(diagnostics.get(n) is None for n in role_strain_names()):
        diagnostics.update(role_strains(diagnostics, int(count)))
    return diagnostics


def _cells(values: dict[str, Any], names: list[str]) -> list[Any]:
    """Table cells: "" for a value not recorded (inactive, or a record from before the value
    existed)."""
    return ["" if values.get(n) is None else values[n] for n in names]
