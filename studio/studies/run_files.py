"""The files of a study's runs: every run writes ``out_dir/runs/<run_id>.h5`` and, last and
atomically, ``out_dir/runs/<run_id>.json`` (its :class:`RunOutcome`, plus a hash of what it
computed); a study writes all of them into ``outcomes.json``. Written and read here, by the
runner (:mod:`studio.studies.runner`), the studies and their tests."""
from __future__ import annotations

import json
import os
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any, Optional, Sequence

from engine.jsonable import json_text, jsonable

DONE_STATUSES = ("completed", "stopped")
STATUSES = ("completed", "stopped", "failed", "cancelled")


@dataclass
class RunOutcome:
    """What became of one run. ``status``: completed | stopped | failed | cancelled;
    ``summary``: what the task returned; ``error``: ``"Type: message"`` for a failed run;
    ``h5``: the run's HDF5 file; ``wall_s``: wall time of the task on its worker;
    ``skipped``: ``True`` when it was already complete from an earlier attempt."""

    run_id: str
    params: dict
    status: str
    summary: dict
    error: Optional[str]
    h5: Path
    wall_s: float
    skipped: bool = False

    @property
    def ok(self) -> bool:
        return self.status in DONE_STATUSES

    def to_dict(self) -> dict:
        d = asdict(self)
        d["h5"] = str(self.h5)
        return d


# ----------------------------------------------------------------------------- JSON helpers
def write_json_atomic(path: Path, data: Any) -> None:
    """Write ``data`` as JSON to ``path`` via a temporary file and ``os.replace``: the path
    holds either the old or the new complete file, never a partial one."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    from engine.io.output_paths import refuse_special

    refuse_special(path)  # renamed onto: never a device, a named pipe or a folder
    refuse_special(tmp)   # opened: a named pipe would hang
    tmp.write_text(json_text(data, indent=1) + "\n")
    os.replace(tmp, path)


def run_paths(out_dir: Path, run_id: str) -> tuple[Path, Path]:
    """``(h5, json)`` paths of a run in a study's output folder."""
    runs = Path(out_dir) / "runs"
    return runs / f"{run_id}.h5", runs / f"{run_id}.json"



def load_outcome(out_dir: Path, run_id: str) -> Optional[dict]:
    """The stored outcome of a run (the ``.json`` as a dict), or ``None`` if there is none
    or it cannot be read."""
    _, js = run_paths(out_dir, run_id)
    try:
        return json.loads(js.read_text())
    except (OSError, ValueError):
        return None


def outcome_from_dict(d: dict, skipped: bool) -> RunOutcome:
    return RunOutcome(run_id=d["run_id"], params=d.get("params", {}), status=d["status"],
                      summary=d.get("summary") or {}, error=d.get("error"),
                      h5=Path(d["h5"]), wall_s=float(d.get("wall_s", 0.0)), skipped=skipped)



def failures_text(outcomes: Sequence[RunOutcome]) -> str:
    """One line per run that did not complete: id, status, error and parameters."""
    lines = []
    for o in outcomes:
        if not o.ok:
            lines.append(f"{o.run_id}: {o.status}: {o.error}; params {json.dumps(jsonable(o.params))}")
    return "\n".join(lines)


def write_outcomes(path: Path, outcomes: Sequence[RunOutcome]) -> None:
    """All outcomes as one JSON list (written atomically)."""
    write_json_atomic(path, [o.to_dict() for o in outcomes])


def outcome_rows(outcomes: Sequence[RunOutcome], columns: Sequence[str]) -> list[dict]:
    """One table row per run: the ``columns`` found in its parameters, then in its summary
    (the summary wins), with its run_id and status."""
    rows = []
    for o in outcomes:
        s = o.summary or {}
        row = {c: o.params.get(c, "") for c in columns}
        row.update({c: s[c] for c in columns if c in s})
        row.update(run_id=o.run_id, status=o.status)
        rows.append(row)
    return rows


def write_table(path: Path, rows: Sequence[dict], columns: Sequence[str]) -> None:
    """``rows`` as a CSV file of ``columns`` (a missing or None value: an empty cell)."""
    import csv

    with open(path, "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=list(columns), extrasaction="ignore")
        w.writeheader()
        for r in rows:
            w.writerow({k: ("" if r.get(k) is None else r.get(k)) for k in columns})

