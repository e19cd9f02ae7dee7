"""Resumable batch execution over input files: locally, in parallel, or on a Dask cluster.

A batch maps a *job* — a picklable function ``job(input_path, out_dir, **options) -> dict``
that writes its own result files atomically and returns a summary record — over many inputs.
The batch layer

* expands folders into their observation files and names each input's result folder after
  its stem (colliding stems are refused up front);
* skips inputs whose ``summary.json`` says ``"status": "ok"`` for the same input, unless
  ``overwrite`` (resumability: an interrupted batch re-run does no finished work again);
* removes temporary files left by a killed run, so no partial file survives;
* turns any exception of a job into an ``"error"`` record with a one-line message, so a bad
  input never stops the batch;
* runs the jobs serially, in a local process pool (``workers``), or on a Dask distributed
  cluster (``scheduler`` address), with a progress bar of the files and, for jobs that report
  their progress, a bar per running file (in this process or in the pool's workers, whose
  reports come back through a queue);
* writes ``summary.csv`` with one row per input (failures included), atomically.
"""

from __future__ import annotations

import json
import logging
import os
import queue
import time
import traceback
from collections.abc import Callable, Iterable, Sequence
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
from contextlib import nullcontext
from functools import partial
from multiprocessing import get_context
from pathlib import Path
from typing import Any

import pandas as pd
from tqdm.auto import tqdm

from lightcurve.io.atomic import atomic_write_json, atomic_write_table, json_ready, output_folder

__all__ = ["INPUT_SUFFIXES", "collect_inputs", "run_batch", "summary_path"]

logger = logging.getLogger(__name__)

#: File suffixes taken from folders (DAMIT files have no fixed suffix: name them explicitly).
INPUT_SUFFIXES = (".csv", ".parquet", ".pq")
SUMMARY = "summary.json"

Job = Callable[..., dict[str, Any]]
#: ``report(stem, fraction, message)``: progress of the input named ``stem``.
Report = Callable[[str, float, str], None]
#: Seconds between two looks at the workers' progress reports.
_POLL_S = 0.2


def collect_inputs(paths: Iterable[str | os.PathLike[str]]) -> list[Path]:
    """Expand files and folders into a sorted, de-duplicated list of input files.

    Parameters
    ----------
    paths : iterable of path-like
        Files (any format) and folders (their ``*.csv``/``*.parquet`` files, not recursive).

    Returns
    -------
    list of pathlib.Path

    Raises
    ------
    FileNotFoundError
        For a path that does not exist.
    ValueError
        If no input is found, or two inputs share a stem (their results would collide).
    """
    files: list[Path] = []
    for raw in paths:
        path = Path(raw)
        if path.is_dir():
            files.extend(
                sorted(
                    p for p in path.iterdir() if p.suffix.lower() in INPUT_SUFFIXES and p.is_file()
                )
            )
        elif path.is_file():
            files.append(path)
        else:
            raise FileNotFoundError(f"{path}: no such file or folder")
    unique = list(dict.fromkeys(p.resolve() for p in files))
    if not unique:
        raise ValueError("no input files found (folders are searched for .csv and .parquet)")
    stems: dict[str, Path] = {}
    for path in unique:
        if path.stem in stems:
            raise ValueError(
                f"inputs {stems[path.stem]} and {path} share the stem '{path.stem}': their "
                "results would overwrite each other; rename one"
            )
        stems[path.stem] = path
    return unique


def summary_path(out_dir: str | os.PathLike[str], input_path: Path) -> Path:
    """Where the summary of ``input_path`` goes: ``out_dir/<stem>/summary.json``."""
    return Path(out_dir) / input_path.stem / SUMMARY


def _finished(out_dir: Path, input_path: Path) -> dict[str, Any] | None:
    path = summary_path(out_dir, input_path)
    try:
        record = json.loads(path.read_text())
    except (OSError, ValueError):
        return None
    if record.get("status") == "ok" and record.get("input") == str(input_path):
        return record
    return None


def _remove_stale_temporaries(out_dir: Path) -> int:
    count = 0
    for tmp in out_dir.rglob(".*.tmp"):
        tmp.unlink(missing_ok=True)
        count += 1
    return count


def _run_one(
    job: Job,
    input_path: Path,
    out_dir: Path,
    options: dict[str, Any],
    error_template: dict[str, Any],
    report: Report | None = None,
) -> dict[str, Any]:
    """Run a job; never raises: failures become error records (also written to disk).

    With ``report``, the job gets ``progress(fraction, message)`` reporting as this input.
    """
    start = time.perf_counter()
    result_dir = out_dir / input_path.stem
    if report is not None:
        options = {**options, "progress": partial(report, input_path.stem)}
    try:
        record = dict(job(input_path, result_dir, **options))
        record.setdefault("status", "ok")
        record.setdefault("error", None)
    except Exception as exc:  # a bad input must not stop the batch: record and continue
        message = " ".join(str(exc).split()) or type(exc).__name__
        logger.debug("input %s failed:\n%s", input_path, traceback.format_exc())
        record = dict(error_template)
        record.update(status="error", error=f"{type(exc).__name__}: {message}")
    record["input"] = str(input_path)
    record["runtime_s"] = time.perf_counter() - start
    try:
        atomic_write_json(result_dir / SUMMARY, json_ready(record))
    except (OSError, ValueError) as exc:
        record = {
            "input": str(input_path),
            "status": "error",
            "error": f"cannot write summary: {exc}",
            "runtime_s": record["runtime_s"],
        }
    return record


def _init_worker(threads: int) -> None:
    import torch

    torch.set_num_threads(threads)


def run_batch(
    job: Job,
    inputs: Sequence[str | os.PathLike[str]],
    out_dir: str | os.PathLike[str],
    *,
    options: dict[str, Any] | None = None,
    overwrite: bool = False,
    workers: int = 1,
    scheduler: str | None = None,
    progress: bool = True,
    summary_columns: Sequence[str] = (),
    error_template: dict[str, Any] | None = None,
    job_progress: bool = False,
) -> pd.DataFrame:
    """Run ``job`` over every input and write ``out_dir/summary.csv``.

    Parameters
    ----------
    job : callable
        ``job(input_path, result_dir, **options) -> dict`` (module-level, picklable).
    inputs : sequence of path-like
        Files and folders (see :func:`collect_inputs`).
    out_dir : path-like
        Result folder; one sub-folder per input.
    options : dict, optional
        Keyword arguments for the job.
    overwrite : bool
        Redo inputs that already have an ``"ok"`` summary.
    workers : int
        Local worker processes (1 runs in this process).
    scheduler : str, optional
        Address of a Dask distributed scheduler (``tcp://host:8786``); the workers must see
        the same file system.
    progress : bool
        Show a progress bar.
    summary_columns : sequence of str
        Columns of ``summary.csv`` in order (records' other keys follow).
    error_template : dict, optional
        Keys and default values every error record carries (so error summaries have the
        same keys as successful ones).
    job_progress : bool
        The job takes a ``progress(fraction, message)`` keyword: with ``progress`` (and no
        Dask ``scheduler``), a bar per running input follows it below the files' bar, for
        one worker or several.

    Returns
    -------
    pandas.DataFrame
        The summary table (one row per input, in input order).
    """
    options = dict(options or {})
    files = collect_inputs(inputs)  # bad inputs fail before the output folder exists
    out_dir = output_folder(out_dir)
    stale = _remove_stale_temporaries(out_dir)
    if stale:
        logger.info("removed %d temporary file(s) of an interrupted run", stale)
    records: dict[Path, dict[str, Any]] = {}
    todo = []
    for path in files:
        done = None if overwrite else _finished(out_dir, path)
        if done is not None:
            records[path] = done
        else:
            todo.append(path)
    logger.info("%d input(s): %d done before, %d to run", len(files), len(records), len(todo))
    bar = tqdm(total=len(todo), desc="invert", unit="file", disable=not progress or not todo)
    file_bars = _FileBars(max(1, workers)) if progress and job_progress and not scheduler else None
    try:
        runs = _execute(
            job,
            todo,
            out_dir,
            options=options,
            workers=workers,
            scheduler=scheduler,
            template=error_template or {},
            report=None if file_bars is None else file_bars.update,
        )
        for path, record in runs:
            records[path] = record
            if file_bars is not None:
                file_bars.finish(path.stem)
            bar.update(1)
            bar.set_postfix_str(f"{path.stem}: {record['status']}")
    finally:
        if file_bars is not None:
            file_bars.close()
        bar.close()
        table = _summary_table([records[p] for p in files if p in records], summary_columns)
        atomic_write_table(table, out_dir / "summary.csv")
    return table


class _FileBars:
    """One progress bar (total 1) per running input, in ``slots`` lines below the files' bar.

    A bar opens at an input's first report and closes when its record comes back.
    """

    def __init__(self, slots: int) -> None:
        self._bars: dict[str, tuple[tqdm, int]] = {}
        self._free = list(range(slots, 0, -1))  # screen lines below the files' bar

    def update(self, stem: str, fraction: float, message: str) -> None:
        if stem not in self._bars:
            line = self._free.pop() if self._free else len(self._bars) + 1
            bar = tqdm(
                total=1.0,
                desc=stem,
                position=line,
                leave=False,
                bar_format="{desc}: {percentage:3.0f}%|{bar}| {postfix}",
            )
            self._bars[stem] = (bar, line)
        bar = self._bars[stem][0]
        bar.n = min(max(float(fraction), 0.0), 1.0)
        bar.set_postfix_str(message[:60], refresh=False)
        bar.refresh()

    def finish(self, stem: str) -> None:
        if stem in self._bars:
            bar, line = self._bars.pop(stem)
            bar.close()
            self._free.append(line)

    def close(self) -> None:
        for stem in list(self._bars):
            self.finish(stem)


class _QueueReport:
    """``report(stem, fraction, message)`` of a worker process: puts it on a managed queue."""

    def __init__(self, reports: Any) -> None:
        self.reports = reports

    def __call__(self, stem: str, fraction: float, message: str) -> None:
        self.reports.put((stem, fraction, message))


def _drain(reports: Any, report: Report) -> None:
    """Hand every queued worker report to ``report``."""
    while True:
        try:
            report(*reports.get_nowait())
        except queue.Empty:
            return


def _execute(
    job: Job,
    todo: list[Path],
    out_dir: Path,
    *,
    options: dict[str, Any],
    workers: int,
    scheduler: str | None,
    template: dict[str, Any],
    report: Report | None = None,
) -> Iterable[tuple[Path, dict[str, Any]]]:
    """``(input, record)`` of every input of ``todo`` as they finish; ``report`` receives the
    progress of the running inputs (not from a Dask cluster)."""
    if not todo:
        return
    if scheduler:
        try:
            from dask.distributed import Client
            from dask.distributed import as_completed as dask_completed
        except ImportError:
            raise ValueError(
                "--scheduler needs Dask's distributed scheduler, which is not installed: "
                "pip install 'space-lightcurves[distributed]' (or dask[distributed])"
            ) from None

        with Client(scheduler) as client:
            futures = {
                client.submit(
                    _run_one,
                    job,
                    path,
                    out_dir,
                    options,
                    template,
                    key=f"invert-{path.stem}",
                    pure=False,
                ): path
                for path in todo
            }
            for future in dask_completed(futures):
                yield futures[future], future.result()
    elif workers > 1:
        threads = max(1, (os.cpu_count() or 1) // workers)
        context = get_context("spawn")
        with (
            context.Manager() if report is not None else nullcontext() as manager,
            ProcessPoolExecutor(
                max_workers=workers,
                mp_context=context,
                initializer=_init_worker,
                initargs=(threads,),
            ) as pool,
        ):
            reports = manager.Queue() if manager is not None else None
            remote = _QueueReport(reports) if reports is not None else None
            futures = {
                pool.submit(_run_one, job, path, out_dir, options, template, remote): path
                for path in todo
            }
            pending = set(futures)
            while pending:
                done, pending = wait(pending, timeout=_POLL_S, return_when=FIRST_COMPLETED)
                if reports is not None:
                    _drain(reports, report)
                for future in done:
                    yield futures[future], future.result()
    else:
        for path in todo:
            yield path, _run_one(job, path, out_dir, options, template, report)


def _summary_table(records: list[dict[str, Any]], columns: Sequence[str]) -> pd.DataFrame:
    rows = []
    for record in records:
        row = {}
        for key, value in record.items():
            row[key] = json.dumps(json_ready(value)) if isinstance(value, dict | list) else value
        rows.append(row)
    table = pd.DataFrame(rows)
    ordered = [c for c in columns if c in table] + [c for c in table if c not in columns]
    return table[ordered] if len(table) else pd.DataFrame(columns=list(columns))
