"""What every panel shares: display constants, number and text formatting for the page."""
from __future__ import annotations

from typing import Optional

from studio.fmt import fmt_rate as _fmt_rate, fmt_seconds  # noqa: F401 (_fmt_rate: the panels' name)

STREAM_HZ = 20.0          # at most this many live frames per second into the view
POLL_S = 0.1              # job polling period
STUDIES_POLL_S = 0.5      # the Studies tab's polling period
PLOT_CURSOR_S = 0.25      # plot cursor updates at most this often while playing
MAX_VIEW_SEGMENTS = 2_000_000  # above this the view draws every bristle as one segment
SPEEDS = ("0.1x", "0.25x", "0.5x", "1x", "2x", "4x")
COLOR_MODES = ("bending moment", "deflection", "none")
# viser 1.1 draws a plotly figure ``aspect`` times as tall as it is wide (its docstring says
# width / height; the page sets height = width * aspect, over the layout's height): 0.62
# gives a 540 px wide plot 335 px of height (the studio passed 1.4-1.6: plots taller than wide)
PLOT_ASPECT = 0.62


def _fmt_s(s) -> str:
    return fmt_seconds(s, decimals=1)


def _fmt_value(value) -> str:
    if isinstance(value, (tuple, list)):
        return "(" + ", ".join(_fmt_value(c) for c in value) + ")"
    if isinstance(value, float):
        return f"{value:g}"
    return str(value)


def _md_escape(text: str) -> str:
    return str(text).replace("|", "\\|").replace("<", "&lt;").replace(">", "&gt;")


def _safe_name(name: str) -> str:
    keep = "".join(c if c.isalnum() or c in "-_." else "_" for c in str(name)).strip("._")
    return keep or "scene"


RUN_ROW_CHARS = 40        # a message in a Runs/Studies table row: at most three short lines


def _one_line(text, limit: int = RUN_ROW_CHARS) -> str:
    """The first line of a message, cut to ``limit`` characters with "…" (a table row stays
    one line tall; the full text is shown on demand)."""
    line = str(text or "").strip().split("\n", 1)[0].strip()
    more = len(line) > limit or "\n" in str(text or "").strip()
    return (line[:limit].rstrip() + " …") if more else line


NO_JOBS = "(none)"        # the only entry of an empty Runs/Studies dropdown


def set_job_choices(dropdown, jobs, keep: Optional[str]) -> None:
    """Fill a Runs/Studies dropdown: one entry ``"<id> <name> (<status>)"`` per job
    (:data:`NO_JOBS` when there is none), the entry of the job ``keep`` (an id) selected when
    it is listed (else viser selects the first)."""
    options = tuple(f"{j.id} {j.name} ({j.status})" for j in jobs) or (NO_JOBS,)
    dropdown.options = options
    for o in options:
        if keep is not None and job_of(o) == keep:
            dropdown.value = o


def job_of(entry: Optional[str]) -> Optional[str]:
    """The job id a dropdown entry of :func:`set_job_choices` names; None for none."""
    return entry.split(" ", 1)[0] if entry and entry != NO_JOBS else None


def follow_job(jobs, job_id: str, progress, md_status, what: str, running):
    """One poll of the job a panel follows (its Run or Study): its progress into the bar
    ``progress`` and, while it waits or runs, a status line into ``md_status`` (``what``:
    "Job", "Study"; ``running(info)``: the text after "running: "). Returns None while it
    waits or runs, its final state once it has ended (the panel then says how)."""
    info = jobs.get(job_id)
    progress.value = 100.0 * float(info.progress or 0.0)
    if info.status == "queued":
        md_status.content = f"{what} `{job_id}` queued (waiting for a worker)."
    elif info.status == "running":
        md_status.content = f"{what} `{job_id}` running: {running(info)}"
    else:
        return info
    return None
