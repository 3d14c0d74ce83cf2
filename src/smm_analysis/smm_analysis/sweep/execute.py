"""Running a sweep's batches: locally over processes or on a Dask cluster, streaming, resumable.

A batch is a list of run ids of one scenario; its task gets the runs' full settings (seeds included) as
arguments, so a task is a pure function of its arguments and any worker gives the same result. Every
finished batch is written at once as ``parts/batch-NNNNN.parquet`` under the output folder; a sweep
started again on the same folder with the same spec runs only the batches without a part.
"""

from __future__ import annotations

import contextlib
import json
import math
import os
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pyarrow as pa
import pyarrow.parquet as pq

from smm_analysis.batch.loop import INDEX_NAMES, RunSettings, run_batch
from smm_analysis.errors import AnalysisError
from smm_analysis.sweep.spec import SweepSpec

__all__ = ["Batch", "SchedulerError", "SweepFolderError", "batches", "finished_batches", "run_sweep"]

_STATE_FILE = "sweep.json"
_PARTS = "parts"


class SchedulerError(AnalysisError):
    """The Dask scheduler cannot be reached or failed during the sweep (the message names its address)."""


class SweepFolderError(AnalysisError):
    """The output folder holds another sweep, or its parts cannot be read or written."""


@dataclass(frozen=True)
class Batch:
    """One task: run ids of one scenario.

    Attributes:
        index: Batch number (its part file's name).
        run_ids: The runs, in id order.
    """

    index: int
    run_ids: tuple[int, ...]


def batches(spec: SweepSpec, batch_size: int | None = None) -> list[Batch]:
    """The sweep's batches: per scenario, its run ids in chunks of ``batch_size`` (default the spec's)."""
    size = batch_size or spec.batch_size
    scenarios = len(spec.scenarios)
    result: list[Batch] = []
    for scenario in range(scenarios):
        ids = list(range(scenario, spec.run_count, scenarios))
        for start in range(0, len(ids), size):
            result.append(Batch(len(result), tuple(ids[start : start + size])))
    return result


def run_task(run_ids: Sequence[int], runs: Sequence[RunSettings]) -> list[dict[str, float]]:
    """A batch's task (what a process or Dask worker runs): indices of every run, with its id."""
    return [{"run_id": run_id, **indices} for run_id, indices in zip(run_ids, run_batch(runs), strict=True)]


def _part_path(out: Path, index: int) -> Path:
    return out / _PARTS / f"batch-{index:05d}.parquet"


def _write_part(out: Path, index: int, rows: Sequence[dict[str, float]]) -> None:
    table = pa.table(
        {"run_id": [int(r["run_id"]) for r in rows], **{k: [float(r[k]) for r in rows] for k in INDEX_NAMES}}
    )
    path = _part_path(out, index)
    temporary = path.with_suffix(".tmp")
    pq.write_table(table, temporary)
    os.replace(temporary, path)  # a part is there whole or not at all


def prepare_folder(spec: SweepSpec, out: Path) -> None:
    """Creates the output folder, or checks that it holds this spec's sweep (to resume it).

    Raises:
        SweepFolderError: The folder holds another spec's sweep, or is not writable.
    """
    state = out / _STATE_FILE
    try:
        if state.exists():
            recorded = json.loads(state.read_text(encoding="utf-8"))
            if recorded.get("digest") != spec.digest:
                raise SweepFolderError(
                    f"{out} holds the results of another sweep spec ({recorded.get('name')!r}); "
                    "use another --out"
                )
            return
        (out / _PARTS).mkdir(parents=True, exist_ok=True)
        document = {"name": spec.name, "digest": spec.digest, "spec": spec.source}
        state.write_text(json.dumps(document, indent=2, default=str), encoding="utf-8")
    except OSError as error:
        raise SweepFolderError(f"{out}: {error}") from None


def recorded_spec(out: Path) -> dict[str, Any]:
    """The spec a sweep folder was made with.

    Raises:
        SweepFolderError: No sweep in ``out``.
    """
    try:
        document: dict[str, Any] = json.loads((out / _STATE_FILE).read_text(encoding="utf-8"))["spec"]
    except (OSError, ValueError, KeyError) as error:
        raise SweepFolderError(f"{out} holds no sweep ({error})") from None
    return document


def finished_batches(out: Path) -> set[int]:
    """Indices of the batches whose part is written."""
    folder = out / _PARTS
    if not folder.is_dir():
        return set()
    return {int(path.stem.split("-")[1]) for path in folder.glob("batch-*.parquet")}


def read_parts(out: Path) -> pa.Table:
    """Every written run (run_id and indices), in run id order."""
    paths = sorted((out / _PARTS).glob("batch-*.parquet"))
    if not paths:
        return pa.table(
            {"run_id": pa.array([], pa.int64()), **{k: pa.array([], pa.float64()) for k in INDEX_NAMES}}
        )
    table = pa.concat_tables([pq.read_table(path, columns=["run_id", *INDEX_NAMES]) for path in paths])
    return table.sort_by("run_id")


Progress = Callable[[int, int], None]


def _local(
    todo: Sequence[tuple[Batch, list[RunSettings]]], workers: int
) -> Iterator[tuple[Batch, list[dict[str, float]]]]:
    if workers <= 1:
        for batch, runs in todo:
            yield batch, run_task(batch.run_ids, runs)
        return
    with ProcessPoolExecutor(max_workers=workers) as pool:
        pending: dict[Future[list[dict[str, float]]], Batch] = {}
        queue = list(todo)
        while queue or pending:
            while queue and len(pending) < 2 * workers:
                batch, runs = queue.pop(0)
                pending[pool.submit(run_task, batch.run_ids, runs)] = batch
            done, _ = wait(pending, return_when=FIRST_COMPLETED)
            for future in done:
                yield pending.pop(future), future.result()


def _dask(
    todo: Sequence[tuple[Batch, list[RunSettings]]], address: str, digest: str
) -> Iterator[tuple[Batch, list[dict[str, float]]]]:
    from distributed import Client, as_completed  # noqa: PLC0415 (dask loads only for --scheduler)

    try:
        client = Client(address, timeout="10s", set_as_default=False)  # type: ignore[no-untyped-call]
    except (OSError, TimeoutError, ValueError) as error:
        raise SchedulerError(f"cannot reach the Dask scheduler at {address}: {error}") from None
    try:
        futures = {
            client.submit(
                run_task, batch.run_ids, runs, key=f"smm-sweep-{digest}-{batch.index}", retries=2
            ): batch
            for batch, runs in todo
        }
        with client.as_current():
            finished = as_completed(list(futures))  # type: ignore[no-untyped-call]
        for future in finished:
            try:
                result = future.result()
            except Exception as error:
                raise SchedulerError(
                    f"the Dask cluster at {address} failed during the sweep "
                    f"({type(error).__name__}: {error}); finished batches are kept: run the same command "
                    "again to resume"
                ) from None
            yield futures[future], result
    finally:
        with contextlib.suppress(Exception):  # a dead scheduler cannot be closed cleanly
            client.close(timeout=5)  # type: ignore[no-untyped-call]


def run_sweep(
    spec: SweepSpec,
    out: Path,
    *,
    workers: int = 1,
    scheduler: str | None = None,
    progress: Progress | None = None,
) -> int:
    """Runs every batch of the sweep without a part in ``out``; returns the number of batches run.

    Raises:
        SweepFolderError: ``out`` holds another sweep or cannot be written.
        SchedulerError: The scheduler cannot be reached or fails (finished parts are kept).
    """
    prepare_folder(spec, out)
    all_batches = batches(spec)
    done = finished_batches(out)
    todo = [
        (batch, [spec.settings(run_id) for run_id in batch.run_ids])
        for batch in all_batches
        if batch.index not in done
    ]
    total = len(all_batches)
    finished = len(done)
    if progress is not None:
        progress(finished, total)
    stream = _dask(todo, scheduler, spec.digest) if scheduler else _local(todo, workers)
    for batch, rows in stream:
        _write_part(out, batch.index, rows)
        finished += 1
        if progress is not None:
            progress(finished, total)
    return len(todo)


def default_workers() -> int:
    """Processes for a local sweep: the machine's cores."""
    return max(1, os.cpu_count() or 1)


def nan_free(value: float) -> float | None:
    """``value`` or None when it is NaN (for JSON)."""
    return None if math.isnan(value) else value
