"""Results on disk as they arrive: one Parquet file per finished batch, written whole or not at all.

A sweep that is interrupted keeps every batch it finished; --resume reads them and skips their runs.
A finished sweep's whole table (TABLE) replaces its parts; --resume reads it too.
"""

from __future__ import annotations

import uuid
from pathlib import Path

from ..output import atomic_write

PARTS = "sweep_parts"
TABLE = "stability_map.parquet"
COLUMNS = ("key", "k", "zeta", "m", "h0", "b", "t_end", "output_interval", "solver", "status", "reason",
           "events_found", "events_exact", "event_mismatches", "first_mismatch", "max_height_error",
           "max_event_time_error", "wall_time", "rhs_calls", "steps", "worker", "batch")


def parts_dir(output_dir: Path) -> Path:
    return Path(output_dir) / PARTS


def clear(output_dir: Path, table: bool = True) -> None:
    """Remove the parts of an earlier sweep and (with table) its whole table: a fresh sweep, not --resume."""
    directory = parts_dir(output_dir)
    if directory.is_dir():
        for path in directory.glob("*.parquet"):
            path.unlink()
        directory.rmdir()
    if table and (Path(output_dir) / TABLE).is_file():
        (Path(output_dir) / TABLE).unlink()


def write_table(frame, output_dir: Path) -> Path:
    """The whole table as one Parquet file (temporary name, then renamed), then its parts removed."""
    path = Path(output_dir) / TABLE
    with atomic_write(path) as temporary:
        frame.to_parquet(temporary, index=False)
    clear(output_dir, table=False)
    return path


def write_part(output_dir: Path, rows: list[dict]) -> Path:
    """Write one batch's rows as a Parquet file (to a temporary name, then renamed: never half a file)."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    directory = parts_dir(output_dir)
    directory.mkdir(parents=True, exist_ok=True)
    path = directory / f"{uuid.uuid4().hex}.parquet"
    table = pa.Table.from_pylist([{column: row[column] for column in COLUMNS} for row in rows])
    with atomic_write(path) as temporary:
        pq.write_table(table, temporary)
    return path


def read_parts(output_dir: Path):
    """Every row written so far (the whole table, then the parts) as a pandas DataFrame (empty if none)."""
    import pandas as pd
    import pyarrow.parquet as pq

    table = Path(output_dir) / TABLE
    paths = [table] if table.is_file() else []
    paths += sorted(parts_dir(output_dir).glob("*.parquet")) if parts_dir(output_dir).is_dir() else []
    if not paths:
        return pd.DataFrame(columns=list(COLUMNS))
    frame = pd.concat([pq.read_table(path).to_pandas() for path in paths], ignore_index=True)
    return frame.drop_duplicates("key", keep="first").reset_index(drop=True)
