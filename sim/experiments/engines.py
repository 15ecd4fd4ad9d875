"""Where a sweep's runs execute: a plain loop, local processes, or a Dask cluster.

An engine maps a function over jobs and yields `(job, outcome)` as runs finish, in any order.
The outcome is the function's return value, or `Lost` when the process running it died (killed,
out of memory, `os._exit`) more often than the engine retries: a dead worker costs only its run.
The function itself must not raise (a sweep turns a failing run into a row with its error).
"""

from __future__ import annotations

import gc
import importlib
import logging
import multiprocessing
import os
import signal
import threading
import time
from collections import deque
from collections.abc import Callable, Iterable, Iterator
from contextlib import contextmanager, suppress
from dataclasses import dataclass, field
from multiprocessing.connection import wait
from typing import Any

RETRIES = 3
"""How often a run whose worker died is started again (Dask's default `allowed-failures`)."""


PRELOAD = ["sim.experiments.sweeping", "sim.experiments.warm"]
"""Modules a worker imports (and runs, `warm`) before its first run: once in a fork server or a
Dask worker, or in each worker forked from a process that has not yet."""


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


def _serve(conn, inherited: list) -> None:  # noqa: ANN001 (multiprocessing Connections)
    """A worker process: run batches of jobs from the pipe, sending back each outcome as its run
    finishes, until it gets None or the pipe closes. Ctrl-C is the parent's to handle: it stops
    the workers. `inherited`: the parent's ends of pipes a fork copied here, closed at once so
    that the parent alone holds them (a worker sees the pipe close when the parent is gone)."""
    for other in inherited:
        other.close()
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)  # (not a handler forked from the parent's command line)
    for module in PRELOAD:
        importlib.import_module(module)
    try:
        while True:
            message = conn.recv()
            if message is None:
                return
            fn, batch = message
            for job in batch:
                conn.send(fn(job))
    except (EOFError, OSError):  # the parent is done with us (or gone)
        return


POLL_S = 0.05
"""Seconds a parallel engine waits for outcomes before it looks for a signal again (`_HeldSignals`)."""


class _HeldSignals:
    """Ctrl-C and SIGTERM while a parallel engine hands out outcomes, acted on where it is safe.
    Meanwhile their handlers only note the signal, and `deliver` calls the handler that was in
    place (default: KeyboardInterrupt; `ctsim`'s SIGTERM handler: Terminated) where the engine
    looks: every POLL_S while it waits, and whenever it is asked for the next outcome. Raised
    wherever the main thread happens to be, as a handler raises, the exception could be lost: in a
    finalizer the garbage collector ran ("Exception ignored", pymunk's) or in C code that clears
    the errors of what it calls, while the sweep wrote a row (pandas and pyarrow); the sweep then
    ran to its end and exited 0 (2 of 56 Dask sweeps SIGTERMed here). Only handlers written in Python
    are held (a signal that kills or is ignored stays so), and only in the main thread."""

    def __init__(self) -> None:
        self.noted: list[int] = []
        self.previous: dict[int, Any] = {}

    def __enter__(self) -> _HeldSignals:
        if threading.current_thread() is threading.main_thread():
            for number in (signal.SIGINT, signal.SIGTERM):
                if callable(signal.getsignal(number)):
                    self.previous[number] = signal.signal(number, self._note)
        return self

    def _note(self, signum: int, frame: Any) -> None:
        self.noted.append(signum)

    def deliver(self) -> None:
        """Call the handler of the first signal noted (which raises, for a stop)."""
        if self.noted:
            signum = self.noted[0]
            self.noted.clear()
            self.previous[signum](signum, None)

    def __exit__(self, *exc: object) -> None:
        for number, handler in self.previous.items():
            signal.signal(number, handler)
        self.deliver()  # (a signal noted as the engine ended: the caller's now)


@dataclass
class _Worker:
    """A worker process, its pipe and the jobs sent to it whose outcomes have not come back, in order."""

    process: Any
    conn: Any
    queued: deque = field(default_factory=deque)


class Processes:
    """Local worker processes (default: one per core) that start warm and stay up for every sweep
    this engine runs, until `close`. They are forked from this process when that is safe (it runs
    one thread, so a fork copies no lock held mid-way): they then start with all it imported and
    loaded and warm up (`PRELOAD`) side by side. Otherwise they are forked from a server process
    that imported ctsim and loaded its compiled kernels once. Jobs go out in batches, a batch ahead of the
    one running, so that no worker waits for the parent between runs. A worker that dies is
    replaced and the run it was running started again, up to `retries` times. On Ctrl-C, SIGTERM or
    any other exception in the parent the workers are killed at once: their unfinished runs are
    simply not in the table, and run again when the sweep resumes."""

    def __init__(self, workers: int | None = None, retries: int = RETRIES, batch: int | None = None):
        self.workers = workers or os.cpu_count() or 1
        self.retries = retries
        self.batch = batch
        """Jobs per message (default: `_batch_size`)."""
        self._pool: list[_Worker] = []

    def _start(self) -> _Worker:
        forked = threading.active_count() == 1
        context = multiprocessing.get_context("fork" if forked else "forkserver")
        context.set_forkserver_preload(PRELOAD)
        parent, child = context.Pipe()
        inherited = [parent, *(w.conn for w in self._pool)] if forked else []  # (a fork server's children inherit none)
        process = context.Process(target=_serve, args=(child, inherited), daemon=True)
        process.start()
        child.close()
        worker = _Worker(process, parent)
        self._pool.append(worker)
        return worker

    def _retire(self, worker: _Worker, kill: bool = False) -> None:
        if kill:
            worker.process.kill()
        else:
            try:
                worker.conn.send(None)
            except OSError:  # it is gone already
                pass
        worker.conn.close()
        worker.process.join(timeout=5)
        if worker.process.is_alive():
            worker.process.kill()
            worker.process.join()
        self._pool.remove(worker)

    def imap(self, fn: Callable[[Any], Any], jobs: Iterable[Any]) -> Iterator[tuple[Any, Any]]:
        pending = deque(jobs)
        size = self.batch or _batch_size(len(pending), self.workers)
        while len(self._pool) < min(self.workers, len(pending)):
            self._start()
        finished = False
        try:
            with _HeldSignals() as held:
                yield from self._outcomes(fn, pending, size, held)
            finished = True
        finally:
            if not finished:  # stopped half-way: the workers' queued runs must not outlive this call
                self.close(kill=True)

    def _outcomes(self, fn: Callable[[Any], Any], pending: deque, size: int, held: _HeldSignals) -> Iterator[tuple[Any, Any]]:
        """Batches of `pending` out to the workers, outcomes back as they come; a signal acted on
        (`held`) while waiting and whenever the caller asks for more."""
        deaths: dict[int, int] = {}
        while pending or any(w.queued for w in self._pool):
            for worker in self._pool:
                while pending and len(worker.queued) < 2 * size:  # the running batch and the next
                    batch = [pending.popleft() for _ in range(min(size, len(pending)))]
                    worker.conn.send((fn, batch))
                    worker.queued.extend(batch)
            busy = [w for w in self._pool if w.queued]
            ready = set(wait([w.conn for w in busy] + [w.process.sentinel for w in busy], timeout=POLL_S))
            held.deliver()
            for worker in [w for w in busy if w.conn in ready or w.process.sentinel in ready]:
                try:
                    while worker.queued and worker.conn.poll():
                        outcome = worker.conn.recv()
                        yield worker.queued.popleft(), outcome
                        held.deliver()
                    if worker.queued and not worker.process.is_alive():
                        raise EOFError
                except (EOFError, OSError):  # the worker died running its first queued job
                    job = worker.queued.popleft()
                    pending.extendleft(reversed(worker.queued))  # the rest of its batches, in order
                    worker.queued.clear()
                    self._retire(worker)
                    deaths[id(job)] = deaths.get(id(job), 0) + 1
                    if deaths[id(job)] <= self.retries:
                        pending.appendleft(job)
                    else:
                        yield job, Lost(f"its worker process died {deaths[id(job)]} times (exit code {worker.process.exitcode})")
                    if pending and len(self._pool) < self.workers:
                        self._start()

    def close(self, kill: bool = False) -> None:
        """Stop the workers (`kill`: at once, not after the run each is in)."""
        for worker in list(self._pool):
            self._retire(worker, kill)

    def __del__(self) -> None:  # an engine dropped without `close` (a caller that made its own) takes its workers along
        self.close()


def _batch_size(jobs: int, workers: int) -> int:
    """Jobs per message: about a sixteenth of a worker's share, 1 to 8 (enough to hide the round
    trip between runs, few enough that the last batches still spread over every worker)."""
    return max(1, min(8, jobs // (16 * workers)))


TASK_COST_IN_RUNS = 0.08
"""What a Dask task costs beyond its runs, in runs of the bench's sweep (0.1 s of CPU each): some
8 ms of CPU in its worker and in the client's process together (measured on a LocalCluster: 200
empty tasks 4 ms each; eight tasks of one run each cost the worker 5 ms a task more than one task
of all eight), where a local worker's message costs a fraction of a millisecond."""


def _dask_batch_size(jobs: int, workers: int) -> int:
    """Jobs per Dask task, 1 to 8: fewer tasks cost less (TASK_COST_IN_RUNS each), but the last
    batch leaves the other workers idle for about half a batch; the size of least cost, in runs,
    for a worker's share of the jobs: 2 for the quick bench's 20 runs a worker (one run a task cost
    Dask 8 % more CPU than local processes), 4 for 100."""
    share = jobs / max(workers, 1)
    return min(range(1, 9), key=lambda size: share / size * TASK_COST_IN_RUNS + size / 2)


def _run_batch(fn: Callable[[Any], Any], batch: list[Any]) -> list[Any]:
    """A Dask task: the outcomes of a batch of jobs. Its runs go in a worker's thread, where no
    signal keeps a step time limit: an overrun ends the worker (`StepClock.ends_process`)."""
    from sim.run.clock import StepClock

    StepClock.ends_process = True
    return [fn(job) for job in batch]


LOCAL_CONFIG = {
    "distributed.worker.profile.enabled": False,  # a thread sampling each worker's stack every 10 ms, with the GIL
    "distributed.admin.system-monitor.gil.enabled": False,
    "distributed.admin.tick.interval": "1s",  # (20 ms: each server wakes 50 times a second to see whether its loop is blocked)
    "distributed.admin.system-monitor.interval": "5s",
    "distributed.scheduler.work-stealing": False,  # (tasks of a sweep are alike: nothing to steal, only messages)
    "distributed.nanny.pre-spawn-environ.MALLOC_TRIM_THRESHOLD_": None,  # glibc giving memory back after every run: 3x the system time
}
"""Dask settings of a LocalCluster the engine starts: the measuring that Dask's dashboard feeds
costs CPU on a machine whose cores the runs need (`bench/run.py -k sweep_dask`)."""


QUIET_SCHEDULER = {"dashboard": False, "dashboard_address": "127.0.0.1:0"}
"""A LocalCluster's scheduler without the dashboard still serves a few HTTP routes, on port 8787
unless told otherwise: where another program holds that port, Dask warned on stderr ("Port 8787 is
already in use"). A free port on this machine's loopback instead."""


@contextmanager
def _without_stop_signals() -> Iterator[None]:
    """SIGINT and SIGTERM blocked in this thread meanwhile, and so in every thread and process
    started from it: a LocalCluster's scheduler thread and worker processes never see a terminal's
    Ctrl-C or a job scheduler's SIGTERM (each reaches the whole process group), so that this
    process alone handles them, stopping them at once and quietly (a worker that took SIGTERM
    itself left its scheduler logging a closed connection with a traceback). A signal meanwhile
    is delivered when it ends. (Off the main thread: unchanged.)"""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    blocked = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT, signal.SIGTERM})
    try:
        yield
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, blocked)


class Dask:
    """A Dask `distributed` cluster: the scheduler at `address` (`tcp://host:port`, e.g. one started
    by dask-jobqueue or dask-kubernetes), or a LocalCluster of `workers` processes. Dask retries a
    run whose worker died (`distributed.scheduler.allowed-failures`, 3 by default), then reports it
    lost. Workers need ctsim installed and must see the world, robot and controller files by the
    same paths. A LocalCluster's processes ignore Ctrl-C and SIGTERM: on either the sweep stops and
    `close` kills them at once (their runs in flight are not in the table and run again on resume)."""

    def __init__(self, address: str | None = None, workers: int | None = None, timeout: float = 30.0, batch: int | None = None):
        import dask
        from distributed import Client, LocalCluster

        self.cluster = None
        self.batch = batch
        """Jobs per task (default: `_dask_batch_size`); a batch whose worker died is split into single runs."""
        if address is None:
            n = workers or os.cpu_count() or 1
            try:
                with _without_stop_signals(), dask.config.set(LOCAL_CONFIG):
                    self.cluster = LocalCluster(n_workers=n, threads_per_worker=1, processes=True, dashboard_address=None, memory_limit=0,
                                                silence_logs=logging.CRITICAL, preload=PRELOAD, scheduler_kwargs=QUIET_SCHEDULER)  # fmt: skip
                    self.client = Client(self.cluster, timeout=timeout)
            except BaseException:  # (a Ctrl-C while it started arrives here, once it has)
                self._end_cluster()
                raise
        else:
            self.client = Client(address, timeout=timeout)
            self.client.run(importlib.import_module, PRELOAD[-1])  # warm the workers there are now
        self.workers = max(1, len(self.client.scheduler_info(n_workers=-1)["workers"]))

    def imap(self, fn: Callable[[Any], Any], jobs: Iterable[Any]) -> Iterator[tuple[Any, Any]]:
        from distributed import KilledWorker, as_completed

        jobs = list(jobs)
        size = self.batch or _dask_batch_size(len(jobs), self.workers)
        futures = {self.client.submit(_run_batch, fn, jobs[k : k + size], pure=False): jobs[k : k + size] for k in range(0, len(jobs), size)}
        running = as_completed(futures)
        workerless = _Workerless(self)
        try:
            with _HeldSignals() as held:
                while not running.is_empty():
                    held.deliver()
                    if not running.has_ready():
                        if workerless.too_long():
                            for batch in list(futures.values()):
                                yield from ((job, Lost(f"no Dask worker was left for {WORKERLESS_S:g} s (each died, and none came back)")) for job in batch)
                            return
                        time.sleep(POLL_S)  # (as_completed's own wait would not wake for a signal held)
                        continue
                    future = next(running)
                    batch = futures.pop(future)
                    try:
                        outcomes = future.result()
                    except KilledWorker as err:
                        if len(batch) > 1:  # which run killed it is unknown: each again, alone
                            for job in batch:
                                single = self.client.submit(_run_batch, fn, [job], pure=False)
                                futures[single] = [job]
                                running.add(single)
                            continue
                        outcomes = [Lost(f"its Dask worker died on every attempt ({type(err).__name__}: a crash, or a call of the user's code past the step time limit, ends it)")]
                    for pair in zip(batch, outcomes):
                        held.deliver()  # (a signal noted while the caller had this batch's previous outcome: acted on before the next)
                        yield pair
        finally:
            self.client.cancel(list(futures))

    def close(self) -> None:
        """Leave the cluster; a LocalCluster this engine started ends at once: its worker processes
        are killed (every finished run is already back), then its scheduler closed."""
        if self.cluster is None:
            self.client.close()
        else:
            self._end_cluster()

    def _end_cluster(self) -> None:
        # the scheduler logs each killed worker's closed connection with a traceback (at INFO): not the user's news
        dask_log = logging.getLogger("distributed")
        level = dask_log.level
        dask_log.setLevel(logging.CRITICAL)
        try:
            self._kill_cluster()
        finally:
            dask_log.setLevel(level)

    def _kill_cluster(self) -> None:
        nannies = list(self.cluster.workers.values()) if self.cluster is not None else []
        for nanny in nannies:
            nanny.close_gracefully("ctsim: the sweep is over")  # (not started again when killed)
            if nanny.pid:
                with suppress(ProcessLookupError):
                    os.kill(nanny.pid, signal.SIGKILL)
        if getattr(self, "client", None) is not None:
            self.client.close()
        if self.cluster is not None:
            self.cluster.close()
            for nanny in nannies:  # its worker process's queues and their semaphores, freed before the tracker stops
                nanny.process = None
            gc.collect()
            _stop_resource_tracker()


WORKERLESS_S = 60.0
"""Seconds a LocalCluster the engine started may have runs to go and no worker (every worker died
and its nanny could not start another, as under a heavy load after several deaths) before the
runs left are reported lost rather than waited for for ever. A cluster of someone else's may
have none for a while (a batch system starting them): it is waited for."""
WORKERS_EVERY_S = 5.0
"""Seconds between two looks at the number of a cluster's workers (a round trip to its scheduler)."""


class _Workerless:
    """How long a LocalCluster of the engine's own has been without a worker."""

    def __init__(self, engine: Dask):
        self.engine = engine
        self.since: float | None = None
        self.looked = time.monotonic()

    def too_long(self) -> bool:
        """Whether the cluster has had no worker for WORKERLESS_S (looked at every WORKERS_EVERY_S)."""
        now = time.monotonic()
        if self.engine.cluster is None or now - self.looked < WORKERS_EVERY_S:
            return False
        self.looked = now
        if self.engine.client.scheduler_info(n_workers=-1)["workers"]:
            self.since = None
            return False
        self.since = self.since if self.since is not None else now
        return now - self.since >= WORKERLESS_S


def _stop_resource_tracker() -> None:
    """End the process multiprocessing started to track the LocalCluster's semaphores, and wait
    for it: left to end with this process, it would linger unreaped until init collects it. Every
    semaphore this process made for the cluster (a nanny's queues to its worker) is freed first:
    one still alive was unlinked by the stopping tracker as leaked (with a warning), and its own
    cleanup later printed a traceback (seen after a SIGTERM, whose exception's frames held the
    nannies). (Stopped only when this process ends instead, it cost each Ctrl-C 1.4-1.9 s.)"""
    from multiprocessing import resource_tracker

    with suppress(Exception):  # (a private method, present since Python 3.8)
        resource_tracker._resource_tracker._stop()


def engine(name: str = "processes", workers: int | None = None, scheduler: str | None = None) -> Serial | Processes | Dask:
    """An engine by name ('serial', 'processes', 'dask'); a scheduler address implies Dask."""
    if scheduler is not None or name == "dask":
        return Dask(scheduler, workers)
    if name == "processes":
        return Processes(workers)
    if name == "serial":
        return Serial()
    raise ValueError(f"unknown engine {name!r} (serial, processes, dask)")
