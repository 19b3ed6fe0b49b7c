"""The sweep on dask.distributed: batches of runs as tasks, results streamed to disk as they arrive."""

from __future__ import annotations

import logging
import math
import os
import signal
import sys
import threading
import time
from collections.abc import Callable
from contextlib import contextmanager
from pathlib import Path

from ..capped import close_all
from . import child, store
from .grid import Grid

# Measured on the default grid (2 cores): the median run, the exact solution's comparison included,
# takes ~30 ms (CVODE ~10 ms, the SciPy runs that finish 50 ms to 1 s).
TYPICAL_RUN_TIME = 0.03  # s
OVERHEAD_SHARE = 0.05  # Dask's per-task overhead at most this share of a batch's work
BATCHES_PER_SLOT = 4  # at least this many batches per worker thread, so that slow cells spread out
OVERHEAD_TASKS = 200
POLL_INTERVAL = 0.05  # s between looks for finished batches: how long Ctrl-C may wait to be taken


def local_cluster(workers: int | None = None):
    """A LocalCluster with one single-threaded worker process per core (or workers of them)."""
    from distributed import LocalCluster

    # Ctrl-C reaches every process of the terminal's group: each worker printed its KeyboardInterrupt
    # traceback. The worker processes start with SIGINT ignored (Python keeps an ignored SIGINT), and
    # this process, which alone takes the interrupt, closes the cluster on its way out.
    main_thread = threading.current_thread() is threading.main_thread()
    previous = signal.signal(signal.SIGINT, signal.SIG_IGN) if main_thread else None
    try:
        # No dashboard; the scheduler's HTTP server (its health routes) runs anyway, on 8787 unless told: on a
        # free port, so that a second cluster on the machine does not warn "Port 8787 is already in use".
        return LocalCluster(n_workers=workers or os.cpu_count() or 1, threads_per_worker=1, processes=True,
                            dashboard_address=None, scheduler_kwargs={"dashboard_address": "127.0.0.1:0"},
                            silence_logs=logging.ERROR)
    finally:
        if main_thread:
            signal.signal(signal.SIGINT, previous)


class HideDaskSyncCancelBug(logging.Filter):
    """Drop the NameError that distributed's sync() logs when Ctrl-C comes before its coroutine has started.

    distributed.utils.sync answers a KeyboardInterrupt by scheduling cancel() on the event loop, which
    reads its future before the coroutine has assigned it (distributed 2026.8): tornado then logs a
    NameError traceback after the user's Ctrl-C. The interrupt itself is raised as it should be.
    """

    def filter(self, record: logging.LogRecord) -> bool:
        """False for that NameError's record (dropped), True for every other record."""
        error = record.exc_info[1] if record.exc_info else None
        if not isinstance(error, NameError) or "'future'" not in str(error):
            return True
        frame = error.__traceback__
        while frame is not None and frame.tb_next is not None:
            frame = frame.tb_next
        code = frame.tb_frame.f_code if frame is not None else None
        return not (code is not None and code.co_name == "cancel"
                    and code.co_filename.endswith(os.path.join("distributed", "utils.py")))


def hide_dask_sync_cancel_bug() -> None:
    """Install HideDaskSyncCancelBug on tornado's callback logger, once per process."""
    logger = logging.getLogger("tornado.application")
    if not any(isinstance(installed, HideDaskSyncCancelBug) for installed in logger.filters):
        logger.addFilter(HideDaskSyncCancelBug())


def measure_overhead(client, tasks: int = OVERHEAD_TASKS) -> float:
    """Seconds per task that Dask adds: the wall time of `tasks` no-op tasks over all workers, per task."""
    client.gather(client.map(child.noop, range(20), pure=False))  # warm the connections
    started = time.perf_counter()
    client.gather(client.map(child.noop, range(tasks), pure=False))
    return (time.perf_counter() - started) / tasks


def choose_batch_size(overhead: float, runs: int, slots: int) -> int:
    """Runs per task: few enough per task, enough tasks for every worker thread.

    Enough runs that the per-task overhead is <= OVERHEAD_SHARE of the work, few enough that every
    worker thread gets BATCHES_PER_SLOT batches (a lost worker then costs little to run again).

    Parameters
    ----------
    overhead : float
        Dask's overhead per task [s] (measure_overhead).
    runs : int
        Runs to do.
    slots : int
        Worker threads of the cluster.

    Returns
    -------
    int
        The batch size, >= 1.

    Examples
    --------
    >>> choose_batch_size(0.004, runs=273, slots=2)
    3
    >>> choose_batch_size(0.004, runs=12, slots=2)
    1
    """
    wanted = math.ceil(overhead / (OVERHEAD_SHARE * TYPICAL_RUN_TIME))
    balanced = max(1, runs // (BATCHES_PER_SLOT * max(slots, 1)))
    return max(1, min(wanted, balanced))


def run_sweep(grid: Grid, client=None, *, output_dir: str | Path | None = None, resume: bool = False,
              overwrite: bool = False, workers: int | None = None, time_cap: float = child.DEFAULT_TIME_CAP,
              batch_size: int | None = None,
              progress: bool = True, on_batch: Callable[[list[dict]], None] | None = None):
    """Run every cell of grid with every solver on a Dask cluster and compare each run with the exact solution.

    Parameters
    ----------
    grid : Grid
        The cells and solvers.
    client : distributed.Client, optional
        A client of a running cluster. None starts a LocalCluster with one worker process per core
        (or `workers` of them) and closes it afterwards.
    output_dir : str or Path, optional
        Where each finished batch is written (output_dir/sweep_parts/*.parquet) as it arrives.
    resume : bool
        Keep the runs already in output_dir and run only the others.
    overwrite : bool
        Delete the runs already in output_dir first. Where there are some, one of resume and overwrite
        must be True (ValueError otherwise: a sweep never deletes a result unasked).
    workers : int, optional
        Worker processes of the LocalCluster (ignored with a client).
    time_cap : float
        Wall time [s] a run may take; past it, its child process is killed and the run is "timed out".
    batch_size : int, optional
        Runs per Dask task; None chooses it from the measured per-task overhead (choose_batch_size).
    progress : bool
        Show a progress bar on stderr when it is a terminal (never into a file or a pipe).
    on_batch : callable, optional
        Called with each batch's rows as it arrives.

    Returns
    -------
    pandas.DataFrame
        One row per (cell, solver) in grid order, the columns of store.COLUMNS. attrs holds
        wall_time [s] (first task submitted to last result), workers, threads, overhead [s per task],
        batch_size and runs_done (the runs this call ran).

    Raises
    ------
    ValueError
        If time_cap, workers or batch_size is not > 0, or output_dir holds results and neither resume
        nor overwrite is given (or both are).

    Examples
    --------
    >>> from bouncingball.sweep import Grid, run_sweep
    >>> frame = run_sweep(Grid(k=(1e3, 1e6, 2), zeta=(0.01, 1.0, 2), solvers=("cvode",)), workers=2,
    ...                   progress=False)  # doctest: +SKIP
    >>> frame["status"].tolist()  # doctest: +SKIP
    ['finished', 'finished', 'finished', 'finished']
    """
    import pandas as pd

    check_settings(time_cap, workers, batch_size)
    runs = grid.runs()
    done = None
    if output_dir is not None:
        store.check_fresh(output_dir, resume, overwrite, ("resume=True", "overwrite=True"), "output_dir")
        if resume:
            done = store.read_parts(output_dir)
        else:
            store.clear(output_dir)
    finished = set() if done is None else set(done["key"])
    hide_dask_sync_cancel_bug()
    todo = [run for run in runs if run["key"] not in finished]
    cluster = None
    if client is None:
        from distributed import Client

        cluster = local_cluster(workers)
        client = Client(cluster)
    rows: list[dict] = []
    try:
        client.wait_for_workers(1, timeout=120)
        threads = sum(client.nthreads().values())
        overhead = measure_overhead(client)
        size = batch_size or choose_batch_size(overhead, len(todo), threads)
        started = time.perf_counter()
        rows = _run_batches(client, todo, size, time_cap, output_dir, progress, on_batch)
        wall_time = time.perf_counter() - started
        workers_seen = len(client.scheduler_info()["workers"])
        try:  # free the children of a cluster that stays up
            client.run(close_all)
        except Exception:
            pass
    finally:
        if cluster is not None:
            client.close()
            cluster.close()
    if output_dir is not None:
        frame = store.read_parts(output_dir)
    else:
        frame = pd.DataFrame([{column: row[column] for column in store.COLUMNS} for row in rows],
                             columns=list(store.COLUMNS))
    order = {run["key"]: i for i, run in enumerate(runs)}
    frame = frame[frame["key"].isin(order)]
    frame = frame.sort_values("key", key=lambda keys: keys.map(order)).reset_index(drop=True)
    frame.attrs.update(wall_time=wall_time, workers=workers_seen, threads=threads, overhead=overhead,
                       batch_size=size, runs_done=len(rows))
    return frame


def check_settings(time_cap: float, workers: int | None, batch_size: int | None) -> None:
    """Raise ValueError naming the setting if time_cap, workers or batch_size is not > 0."""
    from .. import validation

    validation.positive("--time-cap", time_cap, "s")
    for name, value in (("--workers", workers), ("--batch-size", batch_size)):
        if value is not None and (isinstance(value, bool) or not isinstance(value, int) or value < 1):
            raise ValueError(f"{name} = {value!r} is not allowed: it must be an integer >= 1")


@contextmanager
def _ctrl_c_between_results():
    """Hold Ctrl-C while batches run; yield an Event set by it, for the loop to raise KeyboardInterrupt itself.

    A KeyboardInterrupt raised inside Dask's client code leaves its requests half done, and it logs them as
    errors while the cluster closes. Python's default handler only: a caller's own handler, or SIGINT
    ignored, stays as it is (and off the main thread nothing is installed).
    """
    interrupted = threading.Event()
    installed = (threading.current_thread() is threading.main_thread()
                 and signal.getsignal(signal.SIGINT) is signal.default_int_handler)
    if installed:
        signal.signal(signal.SIGINT, lambda signum, frame: interrupted.set())
    try:
        yield interrupted
    finally:
        if installed:
            signal.signal(signal.SIGINT, signal.default_int_handler)


def _run_batches(client, todo: list[dict], size: int, time_cap: float, output_dir, progress: bool,
                 on_batch) -> list[dict]:
    from distributed import as_completed
    from tqdm import tqdm

    batches = [[{**run, "batch": i} for run in todo[start:start + size]]
               for i, start in enumerate(range(0, len(todo), size))]
    futures = client.map(child.run_batch, batches, time_cap=time_cap, pure=False)
    pending = as_completed(futures)
    rows: list[dict] = []
    shown = progress and sys.stderr.isatty()  # a bar redirected into a file is a mess of \r lines: step lines there
    told = 0  # the tenths of the runs said as step lines so far
    with tqdm(total=len(todo), desc="sweep", unit="run", file=sys.stderr, disable=not shown) as bar, \
            _ctrl_c_between_results() as interrupted:
        while not pending.is_empty():
            done = pending.next_batch(block=False)
            if not done:
                time.sleep(POLL_INTERVAL)
            for future in done:
                batch = future.result()
                if output_dir is not None:
                    store.write_part(output_dir, batch)
                rows += batch
                bar.update(len(batch))
                if progress and not shown and len(rows) * 10 // len(todo) > told:
                    told = len(rows) * 10 // len(todo)
                    print(f"sweep: {len(rows)} of {len(todo)} runs done", file=sys.stderr, flush=True)
                if on_batch is not None:
                    on_batch(batch)
            if interrupted.is_set():
                raise KeyboardInterrupt
    return rows
