"""Exporting a bundle's graphs side by side: tracing and graph optimisation are single-threaded Python, so on a
machine of several cores the graphs of one bundle export in separate processes at once (a bundle's heaviest graph
then sets the time)."""

from __future__ import annotations

import multiprocessing
import os
import sys
import time
from collections.abc import Callable, Sequence
from concurrent.futures import ProcessPoolExecutor, as_completed
from typing import Any, NamedTuple

from core.errors import InputError
from core.threads import set_cpu_threads


class GraphJob(NamedTuple):
    """One export of a bundle: ``export(*args)`` writes the graph (or graphs) ``name``. ``export`` is a module-level
    function and ``args`` can be pickled, so that a worker process can run it."""

    name: str
    export: Callable[..., Any]
    args: tuple


def timed_export(job: GraphJob) -> float:
    """Run ``job``; returns the seconds it took."""
    start = time.perf_counter()
    job.export(*job.args)
    return time.perf_counter() - start


def export_jobs(prog: str, jobs: Sequence[GraphJob], workers: int | None = None) -> None:
    """Run the ``jobs`` (best given heaviest first, so that the workers end together) by ``workers`` processes at
    once: default one per core, at most one per job; 1 runs them in this process. Each worker gets an equal share
    of the cores' threads. A line on stderr, headed ``prog``, reports each job done. A failed job cancels the
    jobs not yet started and its error reaches the caller as itself."""
    workers = min(len(jobs), os.cpu_count() or 1) if workers is None else workers
    if not isinstance(workers, int) or workers < 1:
        raise InputError(f"--workers must be at least 1, got {workers}")

    def report(done: int, job: GraphJob, seconds: float) -> None:
        sys.stderr.write(f"{prog}: {job.name} exported in {seconds:.0f} s ({done}/{len(jobs)})\n")

    if workers == 1:
        for done, job in enumerate(jobs, 1):
            report(done, job, timed_export(job))
        return
    threads = max(1, (os.cpu_count() or 1) // workers)
    context = multiprocessing.get_context("spawn")  # no fork of a process whose thread pools are running
    with ProcessPoolExecutor(workers, mp_context=context, initializer=set_cpu_threads, initargs=(threads,)) as pool:
        futures = {pool.submit(timed_export, job): job for job in jobs}
        try:
            for done, future in enumerate(as_completed(futures), 1):
                report(done, futures[future], future.result())
        except BaseException:
            pool.shutdown(cancel_futures=True)
            raise
