"""Where the scenario runs of the trials go: this process (one worker) or the Dask cluster
the other studies use (:mod:`studio.studies.runner`), started once for the whole search.

Each run is a :class:`~studio.studies.runner.RunSpec` executed by the runner's own
``execute_spec`` (its ``runs/<run_id>.h5`` and ``.json``); a run already finished in the
output folder with the same hash (a resumed search re-asking an interrupted trial) is not run
again.
"""
from __future__ import annotations

from pathlib import Path
from typing import Optional

from ..run_files import DONE_STATUSES, load_outcome
from ..runner import RunSpec, _connect, default_workers, execute_spec


def _spec_dict(spec: RunSpec) -> dict:
    from engine.jsonable import jsonable

    return {"run_id": spec.run_id, "scene": spec.scene, "params": jsonable(spec.params),
            "task": spec.task, "digest": spec.digest()}


def cached(out_dir: Path, spec: RunSpec) -> Optional[dict]:
    """The outcome of ``spec`` if it already finished in ``out_dir`` (same hash)."""
    old = load_outcome(out_dir, spec.run_id)
    if old and old.get("status") in DONE_STATUSES and old.get("digest") == spec.digest() \
            and Path(old.get("h5", "")).exists():
        return dict(old, skipped=True)
    return None


class Executor:
    """``submit(specs) -> handle``; ``wait_any() -> [(handle, outcomes)]``."""

    def __init__(self, out_dir: Path, scheduler: Optional[str], workers: Optional[int]):
        self.out_dir = Path(out_dir).resolve()
        (self.out_dir / "runs").mkdir(parents=True, exist_ok=True)
        self.local = scheduler is None and (workers or default_workers()) == 1
        self.client = self.cluster = None
        self.parallel = 1
        if not self.local:
            self.client, self.cluster = _connect(scheduler, workers)
            n = len(self.client.scheduler_info().get("workers", {})) or (workers or 1)
            self.parallel = max(1, n)
        self._pending: dict = {}
        self._next = 0

    def submit(self, specs: list[RunSpec]) -> int:
        handle = self._next
        self._next += 1
        items = []
        for spec in specs:
            old = cached(self.out_dir, spec)
            if old is not None:
                items.append(old)
            elif self.local:
                from .. import api

                api.check_cancel()  # between the runs of a trial: Ctrl-C keeps those done
                items.append(execute_spec(_spec_dict(spec), str(self.out_dir),
                                          reraise_interrupt=True))
            else:
                d = _spec_dict(spec)
                items.append(self.client.submit(execute_spec, d, str(self.out_dir),
                                                key=f"brush-run-{d['run_id']}-{d['digest']}",
                                                pure=False, retries=0))
        self._pending[handle] = items
        return handle

    def wait_any(self, timeout: float = 0.5) -> list:
        """The submissions whose runs have all finished: ``[(handle, outcomes)]`` (waits up
        to ``timeout`` s for one)."""
        from .. import api

        done = []
        for handle, items in list(self._pending.items()):
            futures = [x for x in items if not isinstance(x, dict)]
            if futures and not all(f.done() for f in futures):
                continue
            outs = []
            for x in items:
                if isinstance(x, dict):
                    outs.append(x)
                    continue
                try:
                    outs.append(x.result())
                except Exception as exc:  # the worker died, ...
                    outs.append({"status": "failed", "error": f"{type(exc).__name__}: {exc}",
                                 "summary": {}})
            del self._pending[handle]
            done.append((handle, outs))
        if not done and self._pending:
            from distributed import wait

            futures = [x for items in self._pending.values() for x in items
                       if not isinstance(x, dict)]
            try:
                wait(futures, timeout=timeout, return_when="FIRST_COMPLETED")
            except TimeoutError:
                pass
            api.check_cancel()
        return done

    def cancel_pending(self) -> None:
        """Cancel the runs still queued (a stopped search); the cluster stays."""
        futures = [x for items in self._pending.values() for x in items
                   if not isinstance(x, dict)]
        self._pending.clear()
        if futures and self.client is not None:
            self.client.cancel(futures)

    def close(self) -> None:
        if self.client is not None:
            try:
                self.cancel_pending()
            finally:
                self.client.close()
                if self.cluster is not None:
                    self.cluster.close()
        self.client = self.cluster = None
