"""Results on disk as they arrive: one Parquet file per finished batch, written whole or not at all.

A sweep that is interrupted keeps every batch it finished; --resume reads them and skips their runs. A sweep
never deletes them unasked: where they are, it starts only with --resume or --overwrite (check_fresh).
A finished sweep's whole table (TABLE) replaces its parts; --resume reads it too. A write interrupted
before its rename leaves a temporary file (.<part>.parquet.<8 hex digits> in PARTS, .TABLE.<8 hex
digits> beside it): never read, and removed with the parts (see is_own_temporary). Files the sweep
did not write are left alone.
"""

from __future__ import annotations

import re
import uuid
import warnings
from pathlib import Path

from ..output import atomic_write

PARTS = "sweep_parts"
TABLE = "stability_map.parquet"
# alpha and n: the Hunt-Crossley law's (NaN under the linear laws, whose zeta and b are NaN under it).
COLUMNS = ("key", "k", "zeta", "m", "h0", "b", "alpha", "n", "t_end", "output_interval", "solver", "contact",
           "status", "reason", "events_found", "events_exact", "event_mismatches", "first_mismatch",
           "max_height_error", "max_event_time_error", "wall_time", "rhs_calls", "steps", "worker", "batch")


_TABLE_TEMPORARY = f".{TABLE}.tmp"
# The temporaries a write leaves when killed before its rename: output.atomic_write's
# .<final name>.<8 hex digits>, and the .<uuid4 hex>.tmp and .TABLE.tmp of earlier versions.
_OWN_TEMPORARY = {
    PARTS: re.compile(r"\.[0-9a-f]{32}(\.tmp|\.parquet\.[0-9a-f]{8})"),
    "": re.compile(re.escape(_TABLE_TEMPORARY) + "|" + re.escape(f".{TABLE}.") + "[0-9a-f]{8}"),
}


def parts_dir(output_dir: Path) -> Path:
    return Path(output_dir) / PARTS


def is_own_temporary(path: Path) -> bool:
    """True for a temporary file that write_part or write_table leaves when interrupted before its rename."""
    pattern = _OWN_TEMPORARY[PARTS if path.parent.name == PARTS else ""]
    return pattern.fullmatch(path.name) is not None


def results_in(output_dir: Path) -> list[Path]:
    """The results an earlier sweep left in output_dir: its whole table and its parts (not their temporaries)."""
    table = Path(output_dir) / TABLE
    parts = sorted(parts_dir(output_dir).glob("*.parquet")) if parts_dir(output_dir).is_dir() else []
    return ([table] if table.is_file() else []) + parts


def check_fresh(output_dir: Path, resume: bool, overwrite: bool, names: tuple[str, str] = ("--resume", "--overwrite"),
                where: str = "--output-dir") -> None:
    """Refuse to start where an earlier sweep's results are, unless told to keep them (resume) or delete them.

    names: how the caller spells resume and overwrite, where the output folder's option; the message names both
    and the results found. A sweep never deletes a result unasked.
    """
    if resume and overwrite:
        raise ValueError(f"{names[0]} and {names[1]} are not allowed together: {names[0]} keeps the results in "
                         f"{where} and runs the rest, {names[1]} deletes them and runs everything")
    found = results_in(output_dir)
    if found and not (resume or overwrite):
        table = [path for path in found if path.name == TABLE]
        parts = len(found) - len(table)
        what = " and ".join(([f"the table {table[0]}"] if table else [])
                            + ([f"{parts} finished batch(es) in {parts_dir(output_dir)}"] if parts else []))
        raise ValueError(f"{where} = {str(output_dir)!r} holds an earlier sweep's results ({what}), which a sweep "
                         f"does not delete unasked: add {names[0]} to keep them and run only the missing runs, or "
                         f"{names[1]} to delete them and start over (or choose another {where})")


def clear(output_dir: Path, table: bool = True) -> None:
    """Remove the parts of an earlier sweep, their leftover temporaries and (with table) its whole table.

    A sweep asked to overwrite (--overwrite) starts with this, and write_table ends with it (table=False).
    The parts folder is removed once empty; a file in it that the sweep did not write keeps it.
    """
    directory = parts_dir(output_dir)
    if directory.is_dir():
        for path in list(directory.iterdir()):
            if path.suffix == ".parquet" or is_own_temporary(path):
                path.unlink(missing_ok=True)
        if not any(directory.iterdir()):
            directory.rmdir()
    for leftover in Path(output_dir).glob(f".{TABLE}.*"):
        if is_own_temporary(leftover):
            leftover.unlink(missing_ok=True)
    if table and (Path(output_dir) / TABLE).is_file():
        (Path(output_dir) / TABLE).unlink()


def write_table(frame, output_dir: Path) -> Path:
    """The whole table as one Parquet file (temporary name, then renamed), then its parts removed.

    The parts are redundant once the table is written: failing to remove them is a warning, and the
    report is still written.
    """
    path = Path(output_dir) / TABLE
    with atomic_write(path) as temporary:
        frame.to_parquet(temporary, index=False)
    try:
        clear(output_dir, table=False)
    except OSError as error:
        warnings.warn(f"the sweep's table is written, but its parts could not be removed: {error}", stacklevel=2)
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
