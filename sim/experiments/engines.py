"""Where a sweep's runs execute: a plain loop, local processes, or a Dask cluster.

An engine maps a function over jobs and yields `(job, outcome)` as runs finish, in any order.
The outcome is the function's return value, or `Lost` when the process running it died (killed,
out of memory, `os._exit`) more often than the engine retries: a dead worker costs only its run.
The function itself must not raise (a sweep turns a failing run into a row with its error).
"""

from __future__ import annotations

import logging
import multiprocessing
import os
import signal
from collections import deque
from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass
from multiprocessing.connection import wait
from typing import Any

RETRIES = 3
"""How often a run whose worker died is started again (Dask's default `allowed-failures`)."""


PRELOAD = ["sim.experiments.sweep", "sim.experiments.warm"]
"""Modules the local workers' fork server imports (and runs, `warm`) once, so that a new worker starts warm."""


@dataclass(frozen=True)
class Lost:
    """A run whose worker died on every attempt."""

    message: str


class Serial:
    """One run after another in this process (the reference a parallel engine is measured against)."""

    workers = 1

    def imap(self, fn: Callable[[Any], Any], jobs: Iterable[Any]) -> Iterator[tuple[Any, Any]]:
        for job in jobs:
            yield job, fn(job)

    def close(self) -> None:
        pass


def _serve(conn, fn: Callable[[Any], Any]) -> None:  # noqa: ANN001 (a multiprocessing Connection)
    """A worker process: run jobs from the pipe until it closes. Ctrl-C is the parent's to handle."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    while True:
        try:
            job = conn.recv()
        except EOFError:
            return
        conn.send(fn(job))


class Processes:
    """Local worker processes (default: one per core), one run at a time each, forked from a
    server process (not from this one, whose threads a fork would copy mid-state). A worker that
    dies is replaced and its run started again, up to `retries` times."""

    def __init__(self, workers: int | None = None, retries: int = RETRIES):
        self.workers = workers or os.cpu_count() or 1
        self.retries = retries
        self._context = multiprocessing.get_context("forkserver")
        self._context.set_forkserver_preload(PRELOAD)  # workers fork from a process that imported these once
        self._live: list[tuple[Any, Any]] = []

    def _start(self, fn: Callable[[Any], Any]) -> tuple[Any, Any]:
        parent, child = self._context.Pipe()
        process = self._context.Process(target=_serve, args=(child, fn), daemon=True)
        process.start()
        child.close()
        self._live.append((process, parent))
        return process, parent

    def _stop(self, worker: tuple[Any, Any]) -> None:
        process, conn = worker
        conn.close()
        process.join(timeout=5)
        if process.is_alive():
            process.kill()
            process.join()
        self._live.remove(worker)

    def imap(self, fn: Callable[[Any], Any], jobs: Iterable[Any]) -> Iterator[tuple[Any, Any]]:
        pending = deque(jobs)
        deaths: dict[int, int] = {}
        idle = [self._start(fn) for _ in range(min(self.workers, len(pending)))]
        busy: dict[Any, tuple[tuple[Any, Any], Any]] = {}  # connection -> (worker, job)
        try:
            while pending or busy:
                while idle and pending:
                    worker, job = idle.pop(), pending.popleft()
                    worker[1].send(job)
                    busy[worker[1]] = (worker, job)
                sentinels = {worker[0].sentinel: conn for conn, (worker, _) in busy.items()}
                for ready in wait([*busy, *sentinels]):
                    conn = sentinels.get(ready, ready)
                    if conn not in busy:  # both its pipe and its death were ready
                        continue
                    worker, job = busy.pop(conn)
                    try:
                        outcome = conn.recv()
                    except (EOFError, OSError):  # the worker died running this job
                        self._stop(worker)
                        deaths[id(job)] = deaths.get(id(job), 0) + 1
                        if deaths[id(job)] <= self.retries:
                            pending.appendleft(job)
                        else:
                            yield job, Lost(f"its worker process died {deaths[id(job)]} times (exit code {worker[0].exitcode})")
                        if pending:
                            idle.append(self._start(fn))
                        continue
                    idle.append(worker)
                    yield job, outcome
        finally:
            self.close()

    def close(self) -> None:
        for worker in list(self._live):
            self._stop(worker)


class Dask:
    """A Dask `distributed` cluster: the scheduler at `address` (`tcp://host:port`, e.g. one started
    by dask-jobqueue or dask-kubernetes), or a LocalCluster of `workers` processes. Dask retries a
    run whose worker died (`distributed.scheduler.allowed-failures`, 3 by default), then reports it
    lost. Workers need ctsim installed and must see the world, robot and controller files by the
    same paths."""

    def __init__(self, address: str | None = None, workers: int | None = None, timeout: float = 30.0):
        from distributed import Client, LocalCluster

        self.cluster = None
        if address is None:
            n = workers or os.cpu_count() or 1
            self.cluster = LocalCluster(n_workers=n, threads_per_worker=1, processes=True, dashboard_address="127.0.0.1:0", silence_logs=logging.ERROR)
            self.client = Client(self.cluster, timeout=timeout)
        else:
            self.client = Client(address, timeout=timeout)
        self.workers = max(1, len(self.client.scheduler_info(n_workers=-1)["workers"]))

    def imap(self, fn: Callable[[Any], Any], jobs: Iterable[Any]) -> Iterator[tuple[Any, Any]]:
        from distributed import KilledWorker, as_completed

        futures = {self.client.submit(fn, job, pure=False): job for job in jobs}
        try:
            for future in as_completed(futures):
                job = futures.pop(future)
                try:
                    yield job, future.result()
                except KilledWorker as err:
                    yield job, Lost(f"its Dask worker died on every attempt ({err})")
        finally:
            self.client.cancel(list(futures))

    def close(self) -> None:
        self.client.close()
        if self.cluster is not None:
            self.cluster.close()


def engine(name: str = "processes", workers: int | None = None, scheduler: str | None = None) -> Serial | Processes | Dask:
    """An engine by name ('serial', 'processes', 'dask'); a scheduler address implies Dask."""
    if scheduler is not None or name == "dask":
        return Dask(scheduler, workers)
    if name == "processes":
        return Processes(workers)
    if name == "serial":
        return Serial()
    raise ValueError(f"unknown engine {name!r} (serial, processes, dask)")
