"""Sweeps: every design of a sample of a design space evaluated by FE, kept safely.

- ``run``: sample a space, evaluate each design (``run_sweep``), merge segments (``merge_sweeps``);
- ``folder``: every file of a sweep folder, written and read (``SweepStore``, the table);
- ``_migrate``: carry a sweep over to this solver version (``fingertip migrate-sweep``);
- ``_bracket``: hand-picked designs of the default space that bracket the human targets.
"""

from .folder import (
    CONFIG,
    CURVES,
    DAMAGED_GZIP,
    META,
    RECORDS,
    TABLE,
    TABLE_GZ,
    SweepStore,
    merge_tables,
    open_table,
    read_config,
    table_header,
    table_path,
    table_sha256,
    write_config,
    write_meta,
    write_table_gz,
)
from .run import (
    PointPart,
    SweepSummary,
    catalogue_hashes,
    default_workers,
    evaluate_point,
    merge_sweeps,
    point_record,
    protocol_costs,
    record_key,
    run_sweep,
    sample_points,
    simulate_part,
    sweep_config,
    with_todays_defaults,
)

__all__ = [
    "CONFIG",
    "CURVES",
    "DAMAGED_GZIP",
    "META",
    "RECORDS",
    "TABLE",
    "TABLE_GZ",
    "PointPart",
    "SweepStore",
    "SweepSummary",
    "catalogue_hashes",
    "default_workers",
    "evaluate_point",
    "merge_sweeps",
    "merge_tables",
    "open_table",
    "point_record",
    "protocol_costs",
    "read_config",
    "record_key",
    "run_sweep",
    "sample_points",
    "simulate_part",
    "sweep_config",
    "table_header",
    "table_path",
    "table_sha256",
    "with_todays_defaults",
    "write_config",
    "write_meta",
    "write_table_gz",
]
