"""Executors: run a DAG of stages in-process, on a local process pool, or on Ray.

All three call the same :func:`repbench.pipeline.stages.execute`, so a deterministic stage gives the
same artifact wherever it runs. The scheduler submits a stage as soon as its inputs exist; a failed
stage is reported and its dependants are skipped, the rest of the suite still runs.

Ctrl-C: pool workers ignore SIGINT (they start with it blocked, so not even a Ctrl-C during
their start-up reaches them); the parent gets the KeyboardInterrupt, kills its workers (their
running stages are never committed) and re-raises it, so the command line prints its
one-line "interrupted" message. SIGTERM to the parent is the same (the command line turns it
into a KeyboardInterrupt); a worker's SIGTERM releases its named semaphores and exits at once.
In-process, :func:`repbench.pipeline.stages.execute` itself makes sure an interrupted stage is
not committed.
"""

from __future__ import annotations

import concurrent.futures as cf
import contextlib
import ctypes
import multiprocessing as mp
import os
import signal
import statistics
import sys
import threading
import time
import traceback
from collections import defaultdict
from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass, field
from typing import Any, Protocol

from tqdm.auto import tqdm

from repbench.errors import ConfigError, DiskFullError
from repbench.pipeline.stages import StageSpec, execute
from repbench.pipeline.store import Store


@dataclass
class RunReport:
    """What happened to every stage of a run."""

    done: dict[str, float] = field(default_factory=dict)  # stage id → seconds
    cached: list[str] = field(default_factory=list)
    failed: dict[str, str] = field(default_factory=dict)  # stage id → one-line error
    skipped: list[str] = field(default_factory=list)  # dependants of failed stages
    labels: dict[str, str] = field(default_factory=dict)

    def summary(self) -> str:
        return (f"{len(self.done)} computed, {len(self.cached)} reused from the store, "
                f"{len(self.failed)} failed, {len(self.skipped)} skipped")


class Executor(Protocol):
    capacity: int

    def submit(self, spec: StageSpec) -> Any: ...
    def wait_any(self, handles: Iterable[Any]) -> list[tuple[Any, dict[str, Any] | BaseException]]:
        ...
    def shutdown(self) -> None: ...
    def abort(self) -> None: ...


def _stage_id(spec: StageSpec) -> str:
    return f"{spec.kind}/{spec.key}"


def _execute_catching(spec: StageSpec, root: str) -> dict[str, Any]:
    try:
        return execute(spec, root)
    except DiskFullError as exc:  # fatal: run_stages stops, every later stage would fail too
        return {"error": str(exc), "fatal": True}
    except Exception as exc:  # shipped back as data: exceptions from plugins may not pickle
        return {"error": f"{type(exc).__name__}: {exc}", "traceback": traceback.format_exc()}


class InProcessExecutor:
    """Runs stages one at a time in this process (workers=1; easiest to debug)."""

    capacity = 1

    def __init__(self, store_root: str) -> None:
        self.root = store_root
        self._results: dict[int, dict[str, Any]] = {}

    def submit(self, spec: StageSpec) -> int:
        handle = len(self._results)
        self._results[handle] = _execute_catching(spec, self.root)
        return handle

    def wait_any(self, handles: Iterable[Any]) -> list[tuple[Any, Any]]:
        return [(h, self._results.pop(h)) for h in list(handles)]

    def shutdown(self) -> None:
        pass

    def abort(self) -> None:
        pass


def _init_worker(parent: int, death_signal: bool) -> None:
    """Pool worker start-up: die with the parent process ``parent``; ignore Ctrl-C (the parent
    stops its workers), then unblock SIGINT, which the worker was started with blocked
    (:func:`_sigint_blocked`)."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # also discards one already pending
    signal.signal(signal.SIGTERM, _stop_worker)
    if hasattr(signal, "pthread_sigmask"):
        signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGINT})
    _die_with_parent(parent, death_signal)


def _stop_worker(signum: int, frame: Any) -> None:
    """SIGTERM in a pool worker (the parent stopping it on Ctrl-C or SIGTERM): release the
    named semaphores this process made (tqdm's lock, joblib's ...), then exit at once, so its
    running stage is never committed. Killed without this, the worker left them registered
    and the resource tracker warned of "leaked semaphore objects" as the run exited."""
    from multiprocessing import util

    with contextlib.suppress(Exception):
        util._run_finalizers(0)  # type: ignore[attr-defined]  # SemLock cleanups: unlink
    os._exit(128 + signum)


#: prctl option: the signal a process gets when its parent dies (Linux, <sys/prctl.h>)
_PR_SET_PDEATHSIG = 1


def _die_with_parent(parent: int, death_signal: bool) -> None:
    """Make this worker exit when process ``parent`` dies, even by kill -9, so no worker
    outlives its run (each holds hundreds of MB): on Linux the kernel sends it SIGKILL
    (``prctl(PR_SET_PDEATHSIG)``; only when ``death_signal``: it fires when the *thread* that
    started the worker ends, so it is asked for only when that is the parent's main thread);
    everywhere a watchdog thread exits once the worker's parent process id changes."""
    if death_signal and sys.platform.startswith("linux"):
        with contextlib.suppress(OSError, AttributeError):
            libc = ctypes.CDLL(None, use_errno=True)
            libc.prctl(_PR_SET_PDEATHSIG, int(signal.SIGKILL), 0, 0, 0)
    if os.getppid() != parent:  # the parent died before this worker got here
        os._exit(1)
    threading.Thread(target=_watch_parent, args=(parent,), daemon=True,
                     name="repbench-parent-watchdog").start()


def _watch_parent(parent: int, interval_s: float = 1.0) -> None:
    while os.getppid() == parent:
        time.sleep(interval_s)
    os._exit(1)  # orphaned: the run is gone; its temporary folder is cleaned by the next run


@contextlib.contextmanager
def _sigint_blocked() -> Iterator[None]:
    """Block SIGINT in this thread while worker processes are started: they inherit the mask,
    so a Ctrl-C before their initializer runs stays pending there and is then discarded
    (:func:`_init_worker`). This process still gets it: another of its threads takes it, or
    it is delivered when the block ends."""
    if (not hasattr(signal, "pthread_sigmask")
            or threading.current_thread() is not threading.main_thread()):
        yield
        return
    old = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
    try:
        yield
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, old)


class LocalPoolExecutor:
    """A process pool sized to the machine (spawned workers; every stage, here as everywhere,
    runs with :data:`repbench.pipeline.stages.STAGE_THREADS` threads)."""

    def __init__(self, store_root: str, workers: int) -> None:
        self.root = store_root
        self.capacity = workers
        # workers are started by submit(), in the thread that runs the stages
        death_signal = threading.current_thread() is threading.main_thread()
        self._pool = cf.ProcessPoolExecutor(max_workers=workers,
                                            mp_context=mp.get_context("spawn"),
                                            initializer=_init_worker,
                                            initargs=(os.getpid(), death_signal))

    def submit(self, spec: StageSpec) -> cf.Future[dict[str, Any]]:
        with _sigint_blocked():  # submit starts a worker process when none is idle
            return self._pool.submit(_execute_catching, spec, self.root)

    def wait_any(self, handles: Iterable[Any]) -> list[tuple[Any, Any]]:
        done, _ = cf.wait(list(handles), return_when=cf.FIRST_COMPLETED)
        out = []
        for f in done:
            try:
                out.append((f, f.result()))
            except BaseException as exc:  # a worker died (e.g. killed, out of memory)
                out.append((f, {"error": f"worker process failed: {exc}"}))
        return out

    def shutdown(self) -> None:
        self._pool.shutdown(wait=False, cancel_futures=True)

    def abort(self) -> None:
        """Stop at once (Ctrl-C, SIGTERM): stop the workers (:func:`_stop_worker`), so no
        running stage is committed."""
        processes = list((getattr(self._pool, "_processes", None) or {}).values())
        for p in processes:
            with contextlib.suppress(OSError, ValueError):
                p.terminate()
        self._pool.shutdown(wait=False, cancel_futures=True)
        for p in processes:
            with contextlib.suppress(OSError, ValueError, AssertionError):
                p.join(timeout=5)
                if p.is_alive():
                    p.kill()


#: How often Ray reruns a stage whose worker process or node died (a node lost, preempted or
#: out of memory) before the stage is reported failed; Ray's own default for tasks. Python
#: exceptions are never retried: :func:`_execute_catching` returns them as data.
RAY_MAX_RETRIES = 3


class RayExecutor:
    """Runs each stage as a Ray task (``num_cpus=1``). The store root must be on a filesystem
    every Ray node sees (shared disk) for a multi-node cluster.

    A stage lost with its node or worker process is rerun by Ray (up to
    :data:`RAY_MAX_RETRIES` times, on any node with a free CPU): the store's stage lock, which
    the kernel drops with the dead process, lets the rerun start, and the dead one's
    half-written temporary folder never becomes an artifact (the next run removes it). Stages
    that finished stay in the store. A stage lost more often is reported failed; running the
    command again computes just the stages missing.
    """

    def __init__(self, store_root: str, address: str | None, workers: int | None) -> None:
        try:
            import ray
        except ImportError:
            raise ConfigError("the Ray executor needs Ray: pip install 'repbench[ray]'") from None
        self._ray = ray
        if not ray.is_initialized():
            if address:
                ray.init(address=address, log_to_driver=False)
            else:  # "local": a new instance, even where `ray start` left a cluster's address
                ray.init(address="local", num_cpus=workers or os.cpu_count() or 1,
                         log_to_driver=False, include_dashboard=False)
        self.root = store_root
        self.capacity = max(1, int(ray.cluster_resources().get("CPU", 1)))
        self._remote = ray.remote(num_cpus=1, max_retries=RAY_MAX_RETRIES)(_execute_catching)

    def submit(self, spec: StageSpec) -> Any:
        # named after the stage in Ray's dashboard and `ray list tasks`
        return self._remote.options(name=spec.label or _stage_id(spec)).remote(spec, self.root)

    def wait_any(self, handles: Iterable[Any]) -> list[tuple[Any, Any]]:
        ready, _ = self._ray.wait(list(handles), num_returns=1)
        out = []
        for ref in ready:
            try:
                out.append((ref, self._ray.get(ref)))
            except Exception as exc:
                out.append((ref, {"error": _ray_failure(exc)}))
        return out

    def shutdown(self) -> None:
        pass

    def abort(self) -> None:
        pass


def _ray_failure(exc: BaseException) -> str:
    """One line for a Ray task that did not return: lost (its node or worker process died more
    often than Ray retries), or another Ray error."""
    import ray.exceptions as rex

    lines = str(exc).strip().splitlines()
    first = lines[0].split(". ")[0].rstrip(".") if lines else ""
    lost = tuple(c for c in (getattr(rex, n, None) for n in (
        "NodeDiedError", "WorkerCrashedError", "OutOfMemoryError", "LocalRayletDiedError",
        "ObjectLostError")) if isinstance(c, type))
    if lost and isinstance(exc, lost):
        return (f"lost with its Ray node or worker process, on Ray's reruns too "
                f"({type(exc).__name__}: {first}); the stages that finished are kept: run the "
                "same command again to compute the rest")
    return f"Ray task failed ({type(exc).__name__}): {first}"


def make_executor(kind: str, store_root: str, workers: int | None = None,
                  ray_address: str | None = None) -> Any:
    """``local`` (in-process when workers == 1, else a process pool) or ``ray``."""
    if workers is not None and workers < 1:
        raise ConfigError(f"workers must be at least 1, got {workers}")
    if kind == "local":
        n = workers or os.cpu_count() or 1
        return InProcessExecutor(store_root) if n <= 1 else LocalPoolExecutor(store_root, n)
    if kind == "ray":
        if ray_address:
            from repbench.pipeline.preflight import check_ray_address

            check_ray_address(ray_address)  # before ray.init, which may wait minutes
        return RayExecutor(store_root, ray_address, workers)
    raise ConfigError(f"unknown executor {kind!r}; choose 'local' or 'ray'")


def run_stages(specs: list[StageSpec], store: Store, executor: Any, *, progress: bool = True,
               echo: Callable[[str], None] | None = None) -> RunReport:
    """Run every stage whose artifact is missing, respecting dependencies."""
    report = RunReport()
    echo = echo or tqdm.write
    if (cleaned := store.clean_tmp()):
        echo(f"removed {cleaned} temporary stage folders left by killed runs in {store.root}")
    by_id = {_stage_id(s): s for s in specs}
    report.labels = {i: s.label or i for i, s in by_id.items()}
    deps = {i: [f"{k}/{key}" for k, key in s.deps] for i, s in by_id.items()}
    finished: set[str] = set()
    times = StageTimes()
    for i, s in by_id.items():
        if (art := store.get(s.kind, s.key)) is not None:
            finished.add(i)
            report.cached.append(i)
            times.add_earlier(s.kind, art.meta.get("wall_time_s"), s.cost_group)
    todo = [i for i in by_id if i not in finished]
    for kind in sorted({by_id[i].kind for i in todo}):  # other plans' stages in this store
        for meta in store.metas(kind):
            times.add_elsewhere(kind, meta.get("wall_time_s"), meta.get("cost_group") or "")
    running: dict[Any, str] = {}
    started: dict[str, float] = {}
    blocked: set[str] = set()
    # no rate-based "<remaining" from tqdm: stages differ by 1000x (a metric vs an RL run);
    # the postfix has the estimate by stage kind (_status)
    bar = tqdm(total=len(by_id), initial=len(finished), desc="stages", unit="stage",
               disable=not progress, dynamic_ncols=True,
               bar_format="{desc}: {percentage:3.0f}%|{bar}| {n_fmt}/{total_fmt} "
                          "[{elapsed}{postfix}]")
    if report.cached:
        echo(f"reusing {len(report.cached)} finished stages from {store.root}")
    try:
        while todo or running:
            for i in list(todo):
                if len(running) >= executor.capacity:
                    break
                if any(d in blocked or d in report.failed for d in deps[i]):
                    todo.remove(i)
                    blocked.add(i)
                    report.skipped.append(i)
                    bar.update(1)
                    continue
                if all(d in finished for d in deps[i]):
                    todo.remove(i)
                    started[i] = time.time()
                    running[executor.submit(by_id[i])] = i
            if not running:
                if todo:  # nothing runnable: the rest depends on missing stages
                    for i in todo:
                        report.skipped.append(i)
                    break
                continue
            bar.set_postfix_str(_status(running, by_id, todo, times, executor.capacity,
                                        started), refresh=True)
            for handle, result in executor.wait_any(list(running)):
                i = running.pop(handle)
                spec = by_id[i]
                if result.get("fatal"):
                    raise DiskFullError(result["error"])
                if "error" in result:
                    report.failed[i] = result["error"]
                    echo(f"FAILED {report.labels[i]}: {result['error']}")
                elif result.get("status") == "cached":  # another run computed it meanwhile
                    report.cached.append(i)
                    finished.add(i)
                    echo(f"reused {report.labels[i]} (computed by another run; waited "
                         f"{result.get('waited_s', 0.0):.1f} s)")
                else:
                    secs = time.time() - started[i]
                    times.add(spec.kind, secs, spec.cost_group)
                    report.done[i] = secs
                    finished.add(i)
                    echo(f"done   {report.labels[i]} ({secs:.1f} s)")
                bar.update(1)
            bar.set_postfix_str(_status(running, by_id, todo, times, executor.capacity,
                                        started), refresh=True)
    except BaseException:  # Ctrl-C (KeyboardInterrupt) or a bug: stop the running stages
        bar.close()
        executor.abort()
        raise
    bar.close()
    executor.shutdown()
    return report


class StageTimes:
    """Expected wall seconds of a stage, from its cost group (:attr:`StageSpec.cost_group`)
    if stages of that group have a known time, else from its kind. For each, the first of: the
    mean of this run's finished stages; the median of the wall times the store recorded for
    this plan's finished stages (a resumed run knows an RL stage's length before its first one
    ends); the median over the store's other stages (another suite's metrics and RL runs).
    Else the mean over every kind known, else 10 s."""

    def __init__(self) -> None:
        self.now: dict[str, list[float]] = defaultdict(list)
        self.earlier: dict[str, list[float]] = defaultdict(list)
        self.elsewhere: dict[str, list[float]] = defaultdict(list)

    def add(self, kind: str, seconds: float, group: str = "") -> None:
        for name in _names(kind, group):
            self.now[name].append(float(seconds))

    def add_earlier(self, kind: str, seconds: Any, group: str = "") -> None:
        _add_known(self.earlier, kind, seconds, group)

    def add_elsewhere(self, kind: str, seconds: Any, group: str = "") -> None:
        _add_known(self.elsewhere, kind, seconds, group)

    def expected(self, kind: str, group: str = "") -> float:
        for name in _names(kind, group)[::-1]:  # the group first, then the kind
            if self.now.get(name):
                return sum(self.now[name]) / len(self.now[name])
            for known in (self.earlier, self.elsewhere):
                if known.get(name):
                    return float(statistics.median(known[name]))
        known = [t for name, v in (*self.now.items(), *self.earlier.items())
                 if not name.startswith(_GROUP) for t in v]
        return sum(known) / len(known) if known else 10.0


def _add_known(times: dict[str, list[float]], kind: str, seconds: Any, group: str) -> None:
    if isinstance(seconds, (int, float)) and seconds >= 0:
        for name in _names(kind, group):
            times[name].append(float(seconds))


_GROUP = "group: "


def _names(kind: str, group: str) -> list[str]:
    """Where a stage's time is counted: its kind, and its cost group when it has one."""
    return [kind, _GROUP + group] if group else [kind]


def _status(running: dict[Any, str], by_id: dict[str, StageSpec], todo: list[str],
            times: StageTimes, capacity: int, started: dict[str, float]) -> str:
    """The running stages and the time left: the expected time of every stage not started and
    what is left of the running ones' expected times, shared over ``capacity`` workers."""
    names = [by_id[i].label or by_id[i].kind for i in running.values()]
    now = time.time()

    def expected(i: str) -> float:
        return times.expected(by_id[i].kind, by_id[i].cost_group)

    remaining = sum(expected(i) for i in todo) + sum(
        max(expected(i) - (now - started.get(i, now)), 0.0) for i in running.values())
    shown = ", ".join(names[:2]) + (f" +{len(names) - 2}" if len(names) > 2 else "")
    return f"running: {shown or '-'} | {_time_left(remaining / max(1, capacity))}"


def _time_left(seconds: float) -> str:
    """``~40 s left``, ``~12 min left`` or ``~2 h 05 min left``."""
    if seconds < 60:
        return f"~{seconds:.0f} s left"
    minutes = round(seconds / 60)
    if minutes < 60:
        return f"~{minutes} min left"
    return f"~{minutes // 60} h {minutes % 60:02d} min left"
