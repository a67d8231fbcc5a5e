"""Executors: run a DAG of stages in-process, on a local process pool, or on Ray.

All three call the same :func:`repbench.stages.execute`, so a deterministic stage gives the same
artifact wherever it runs. The scheduler submits a stage as soon as its inputs exist; a failed
stage is reported and its dependants are skipped, the rest of the suite still runs.
"""

from __future__ import annotations

import concurrent.futures as cf
import multiprocessing as mp
import os
import time
import traceback
from collections import defaultdict
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from typing import Any, Protocol

from tqdm.auto import tqdm

from repbench.errors import ConfigError, DiskFullError
from repbench.stages import StageSpec, execute
from repbench.store import Store


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


def _stage_id(spec: StageSpec) -> str:
    return f"{spec.kind}/{spec.key}"


def _execute_catching(spec: StageSpec, root: str, threads: int | None) -> dict[str, Any]:
    try:
        return execute(spec, root, threads)
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
        self._results[handle] = _execute_catching(spec, self.root, None)
        return handle

    def wait_any(self, handles: Iterable[Any]) -> list[tuple[Any, Any]]:
        return [(h, self._results.pop(h)) for h in list(handles)]

    def shutdown(self) -> None:
        pass


class LocalPoolExecutor:
    """A process pool sized to the machine (spawned workers, one torch thread each)."""

    def __init__(self, store_root: str, workers: int) -> None:
        self.root = store_root
        self.capacity = workers
        self._pool = cf.ProcessPoolExecutor(max_workers=workers,
                                            mp_context=mp.get_context("spawn"))

    def submit(self, spec: StageSpec) -> cf.Future[dict[str, Any]]:
        return self._pool.submit(_execute_catching, spec, self.root, 1)

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


class RayExecutor:
    """Runs each stage as a Ray task (``num_cpus=1``). The store root must be on a filesystem
    every Ray node sees (shared disk) for a multi-node cluster."""

    def __init__(self, store_root: str, address: str | None, workers: int | None) -> None:
        try:
            import ray
        except ImportError:
            raise ConfigError("the Ray executor needs Ray: pip install 'repbench[ray]'") from None
        self._ray = ray
        if not ray.is_initialized():
            if address:
                ray.init(address=address, log_to_driver=False)
            else:
                ray.init(num_cpus=workers or os.cpu_count() or 1, log_to_driver=False,
                         include_dashboard=False)
        self.root = store_root
        self.capacity = max(1, int(ray.cluster_resources().get("CPU", 1)))
        self._remote = ray.remote(num_cpus=1, max_retries=1)(_execute_catching)

    def submit(self, spec: StageSpec) -> Any:
        return self._remote.remote(spec, self.root, 1)

    def wait_any(self, handles: Iterable[Any]) -> list[tuple[Any, Any]]:
        ready, _ = self._ray.wait(list(handles), num_returns=1)
        out = []
        for ref in ready:
            try:
                out.append((ref, self._ray.get(ref)))
            except Exception as exc:
                out.append((ref, {"error": f"Ray task failed: {exc}"}))
        return out

    def shutdown(self) -> None:
        pass


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
            from repbench.preflight import check_ray_address

            check_ray_address(ray_address)  # before ray.init, which may wait minutes
        return RayExecutor(store_root, ray_address, workers)
    raise ConfigError(f"unknown executor {kind!r}; choose 'local' or 'ray'")


def run_stages(specs: list[StageSpec], store: Store, executor: Any, *, progress: bool = True,
               echo: Callable[[str], None] | None = None) -> RunReport:
    """Run every stage whose artifact is missing, respecting dependencies."""
    report = RunReport()
    echo = echo or tqdm.write
    by_id = {_stage_id(s): s for s in specs}
    report.labels = {i: s.label or i for i, s in by_id.items()}
    deps = {i: [f"{k}/{key}" for k, key in s.deps] for i, s in by_id.items()}
    finished: set[str] = set()
    for i, s in by_id.items():
        if store.get(s.kind, s.key) is not None:
            finished.add(i)
            report.cached.append(i)
    todo = [i for i in by_id if i not in finished]
    durations: dict[str, list[float]] = defaultdict(list)
    running: dict[Any, str] = {}
    started: dict[str, float] = {}
    blocked: set[str] = set()
    bar = tqdm(total=len(by_id), initial=len(finished), desc="stages", unit="stage",
               disable=not progress, dynamic_ncols=True)
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
            for handle, result in executor.wait_any(list(running)):
                i = running.pop(handle)
                spec = by_id[i]
                if result.get("fatal"):
                    raise DiskFullError(result["error"])
                if "error" in result:
                    report.failed[i] = result["error"]
                    echo(f"FAILED {report.labels[i]}: {result['error']}")
                else:
                    secs = time.time() - started[i]
                    durations[spec.kind].append(secs)
                    report.done[i] = secs
                    finished.add(i)
                    echo(f"done   {report.labels[i]} ({secs:.1f} s)")
                bar.update(1)
            bar.set_postfix_str(_status(running, by_id, todo, durations, executor.capacity),
                                refresh=True)
    finally:
        bar.close()
        executor.shutdown()
    return report


def _status(running: dict[Any, str], by_id: dict[str, StageSpec], todo: list[str],
            durations: dict[str, list[float]], capacity: int) -> str:
    names = [by_id[i].label or by_id[i].kind for i in running.values()]
    known = [s for v in durations.values() for s in v]
    fallback = sum(known) / len(known) if known else 10.0
    remaining = sum(
        (sum(durations[by_id[i].kind]) / len(durations[by_id[i].kind]))
        if durations[by_id[i].kind] else fallback for i in todo
    )
    eta = remaining / max(1, capacity)
    shown = ", ".join(names[:2]) + (f" +{len(names) - 2}" if len(names) > 2 else "")
    return f"running: {shown or '-'} | ~{eta / 60:.1f} min left"
