"""The Run panel: Start and Cancel, the progress of the running job, the shared Runs list
(every tab sees every run: runs live in the job pool), and the live stream of the running
job's latest frames into the view. A mixin of :class:`studio.app.Studio`."""
from __future__ import annotations

import copy
from typing import Optional

from .common import _fmt_rate, _fmt_s, _md_escape
from .common import _one_line  # (the Runs list's rows)
from .results import ResultFrames


class RunPanel:
    """Run tab of the studio (mixin)."""

    def _build_run_gui(self, gui) -> None:
        with self.tab_run:
            self.bt_start = gui.add_button("Start run", color="green")
            self.bt_start.on_click(self._on_start)
            self.bt_cancel = gui.add_button("Cancel run", color="red", disabled=True)
            self.bt_cancel.on_click(self._on_cancel)
            self.progress = gui.add_progress_bar(0.0, animated=False)
            self.md_status = gui.add_markdown("No run started yet.")
            self.cb_follow = gui.add_checkbox("show the running job live", True)
            with gui.add_folder("Runs"):
                self.md_runs = gui.add_markdown("No runs yet.")
                self.dd_runs = gui.add_dropdown("run", ("(none)",))
                self.dd_runs.on_update(lambda e: self._show_run_detail())
                self.md_run_detail = gui.add_markdown("", visible=False)
                self.bt_load_run = gui.add_button("Load run for playback")
                self.bt_load_run.on_click(self._on_load_run)
                self.bt_cancel_selected = gui.add_button("Cancel selected run")
                self.bt_cancel_selected.on_click(self._on_cancel_selected)

    # ----------------------------------------------------------------- runs
    def start_run(self) -> Optional[str]:
        """Submit the design as a job; returns the job id (None if refused or no pool)."""
        import engine

        if self.jobs is None:
            self.md_status.content = "No job pool: this studio was started without workers."
            return None
        with self.lock:
            scene = copy.deepcopy(self.scene)
            refused = [o for o in self.overlaps if o.kind != "bristle-bristle"]
        if refused:  # (the build would refuse it in the worker: say so now)
            self.md_status.content = "Refused: " + "; ".join(_md_escape(str(o))
                                                             for o in refused)
            return None
        try:
            job_id = self.jobs.submit(scene, name=scene.get("name"))
        except engine.SceneError as exc:
            self.md_status.content = "Refused: " + "; ".join(
                _md_escape(str(p)) for p in exc.problems)
            return None
        except Exception as exc:
            self.md_status.content = f"Could not start: {_md_escape(str(exc))}"
            return None
        self.md_status.content = f"Queued job `{job_id}`."  # (first: the switch to live
        # view below redraws, and the line must not keep naming the previous job meanwhile)
        with self.lock:
            self.my_jobs.append(job_id)
            self.active_job = job_id
            self._select_run = job_id  # (the Runs list selects the new run)
            if self.cb_follow.value:
                self.set_mode("live")
        self.bt_cancel.disabled = False
        return job_id

    def _on_start(self, event) -> None:
        self.start_run()

    def _on_cancel(self, event) -> None:
        if self.jobs is not None and self.active_job is not None:
            self.jobs.cancel(self.active_job, wait=0.0)

    def _on_cancel_selected(self, event) -> None:
        job = self._selected_job()
        if self.jobs is not None and job is not None:
            self.jobs.cancel(job, wait=0.0)

    def _selected_job(self) -> Optional[str]:
        v = self.dd_runs.value
        return v.split(" ", 1)[0] if v and v != "(none)" else None

    def _on_load_run(self, event) -> None:
        job = self._selected_job()
        if job is not None:
            self.load_run(job)

    def _poll_jobs(self) -> None:
        if self.jobs is None:
            return
        jobs = self.jobs.list(limit=50, kind="run")  # (studies: the Studies tab)
        rows = ["| run | status | progress | message |", "|---|---|---|---|"]
        for j in jobs:
            msg = _one_line(j.error)
            if j.status in ("completed", "stopped") and j.summary:
                msg = f"{j.summary.get('frames', '?')} frames, wall " \
                      f"{_fmt_s(j.summary.get('wall_s'))}"
            rows.append(f"| `{j.id}` {_md_escape(j.name)} | {j.status} | "
                        f"{100 * (j.progress or 0):.0f} % | {_md_escape(msg)} |")
        md = "\n".join(rows) if jobs else "No runs yet."
        if md != self._runs_md:
            self._runs_md = md
            self.md_runs.content = md
            options = tuple(f"{j.id} {j.name} ({j.status})" for j in jobs) or ("(none)",)
            current = getattr(self, "_select_run", None) or self._selected_job()
            self._select_run = None
            self.dd_runs.options = options
            for o in options:
                if current is not None and o.startswith(current):
                    self.dd_runs.value = o
            self._show_run_detail()
        job = self.active_job
        if job is None:
            return
        info = self.jobs.get(job)
        self.progress.value = 100.0 * float(info.progress or 0.0)
        if info.status == "queued":
            self.md_status.content = f"Job `{job}` queued (waiting for a worker)."
        elif info.status == "running":
            self.md_status.content = (
                f"Job `{job}` running: t = {info.sim_time or 0:.4g} / {info.until or 0:g} s, "
                f"{_fmt_rate(info.steps_per_s)} steps/s, ETA {_fmt_s(info.eta_s)}")
        else:
            self.active_job = None
            self.bt_cancel.disabled = True
            self.md_status.content = (f"Job `{job}` **{info.status}**" +
                                      (f": {_md_escape(info.error)}" if info.error else "."))
            if info.status == "completed":
                self.progress.value = 100.0
            if self.mode == "live":  # (a user editing the design keeps the design view)
                self.load_run(job)
            else:
                self.md_status.content += " Load it from the Runs list."

    def _show_run_detail(self) -> None:
        """The selected run's whole message under the Runs list (the list shows one line)."""
        job = self._selected_job()
        text = ""
        if job is not None and self.jobs is not None:
            try:
                info = self.jobs.get(job)
            except KeyError:
                info = None
            full = (info.error or "") if info is not None else ""
            if full and _one_line(full) != full.strip():
                text = f"**`{job}`**: " + _md_escape(full.strip()).replace("\n", "  \n")
        if self.md_run_detail.content != text:
            self.md_run_detail.content = text
        self.md_run_detail.visible = bool(text)

    def _stream_live(self) -> None:
        """Draw the latest frame of the running job (at most STREAM_HZ per second)."""
        import engine

        if self.mode != "live" or self.active_job is None:
            return
        with self.lock:
            try:
                if self.live is None:
                    path = self.jobs.result_path(self.active_job)
                    if not path.exists():
                        return
                    self.live = ResultFrames(path)
                else:
                    self.live.refresh()
            except (engine.BrushStudioError, OSError, KeyError):
                self.live = None
                return
            n = self.live.n_frames
            if n > 0:
                self._show_frame(n - 1, source=self.live)
                self.frame_index = n - 1
