"""The Run panel: Start and Cancel, the progress of the running job, the shared Runs list
(every tab sees every run: runs live in the job pool), and the live stream of the running
job's latest frames into the view. A mixin of :class:`studio.web.app.Studio`."""
from __future__ import annotations

import copy
from typing import Optional

from studio.web.panels import run_cost as rcost
from studio.web.panels.common import (NO_JOBS, _fmt_rate, _fmt_s, _md_escape, follow_job, job_of,
                     set_job_choices)
from studio.web.panels.common import _one_line  # (the Runs list's rows)
from studio.plots.result_frames import ResultFrames


def _running_text(info) -> str:
    """A running job's status after "running: ": simulated time, speed, ETA."""
    return (f"t = {info.sim_time or 0:.4g} / {info.until or 0:g} s, "
            f"{_fmt_rate(info.steps_per_s)} steps/s, ETA {_fmt_s(info.eta_s)}")


class RunPanel:
    """Run tab of the studio (mixin), and the extras of Design → Run settings: the
    recorded channels and the warning under dt."""

    def _build_run_gui(self, gui) -> None:
        self._cost_key = None  # the Scene the cost line was made for
        self.run_cost: Optional[rcost.RunCost] = None
        self._build_run_settings_gui(gui)
        with self.tab_run:
            self.md_cost = gui.add_markdown("")
            self.bt_start = gui.add_button("Start run", color="green")
            self.bt_start.on_click(self._on_start)
            self.bt_cancel = gui.add_button("Cancel run", color="red", disabled=True)
            self.bt_cancel.on_click(self._on_cancel)
            self.progress = gui.add_progress_bar(0.0, animated=False)
            self.md_status = gui.add_markdown("No run started yet.")
            self.cb_follow = gui.add_checkbox("show the running job live", True)
            with gui.add_folder("Runs"):
                self.md_runs = gui.add_markdown("No runs yet.")
                self.dd_runs = gui.add_dropdown("run", (NO_JOBS,))
                self.dd_runs.on_update(lambda e: self._show_run_detail())
                self.md_run_detail = gui.add_markdown("", visible=False)
                self.bt_load_run = gui.add_button("Load run for playback")
                self.bt_load_run.on_click(self._on_load_run)
                self.bt_cancel_selected = gui.add_button("Cancel selected run")
                self.bt_cancel_selected.on_click(self._on_cancel_selected)
        self._update_run_cost()

    def _build_run_settings_gui(self, gui) -> None:
        """Below the dt field (the last field of Design → Run settings): the warning when
        dt exceeds the stability limit, then one checkbox per recorded channel."""
        self.cb_channels = {}
        with self.design_folders["run"]:
            self.md_dt_warning = gui.add_markdown("", visible=False)
            gui.add_markdown("Recorded channels (every record interval):")
            chosen = set(self.scene["run"].get("channels") or ())
            for channel, hint in rcost.CHANNEL_HINTS.items():
                cb = gui.add_checkbox(f"record {channel}", channel in chosen, hint=hint)
                cb.on_update(lambda event: self._on_channel(event))
                self.cb_channels[channel] = cb

    def _on_channel(self, event) -> None:
        from studio.web import scene as us

        if event.client is None:  # set by the server (a preset load): not an edit
            return
        with self.lock:
            new = copy.deepcopy(self.scene)
            new["run"]["channels"] = [c for c, cb in self.cb_channels.items() if cb.value]
            v = us.validate(new)
            if v.ok:
                self.hold_design(v.scene)
            self._cost_key = None  # (refused: the boxes go back to the design's channels)
        self._update_run_cost()

    def _update_run_cost(self) -> None:
        """Recompute the cost line, the dt warning and the channel boxes when the design
        changed (called by the poller and after an edit here)."""
        with self.lock:
            design = self.design  # the validated Scene of the last edit: not parsed again
            if design is self._cost_key:
                return
            self._cost_key = design
        chosen = set(design.run.channels or ())
        for channel, cb in self.cb_channels.items():
            if cb.value != (channel in chosen):
                cb.value = channel in chosen
        try:
            rc = rcost.run_cost(design, rcost.measured_rate(self.jobs))
        except Exception as exc:  # (an invalid design: its fields say why)
            self.run_cost = None
            self.md_cost.content = f"No estimate: {_md_escape(str(exc).splitlines()[0])}"
            self.md_dt_warning.visible = False
            return
        self.run_cost = rc
        self.md_cost.content = rcost.cost_line(rc)
        warning = rcost.dt_warning(rc)
        self.md_dt_warning.content = f"<span style='color:#d00'>{warning}</span>"
        self.md_dt_warning.visible = bool(warning)

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
            self.md_status.content = "<span style='color:#d00'>Refused: " + "; ".join(
                _md_escape(str(o)) for o in refused) + "</span>"
            return None
        try:
            job_id = self.jobs.submit(scene, name=scene.get("name"))
        except engine.SceneError as exc:
            self.md_status.content = "<span style='color:#d00'>Refused: " + "; ".join(
                _md_escape(str(p)) for p in exc.problems) + "</span>"
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
        """Start, or first ask when the estimate is long (``run_cost.CONFIRM_ABOVE_S``)."""
        self._update_run_cost()
        rc = self.run_cost
        with self.lock:
            refused = any(o.kind != "bristle-bristle" for o in self.overlaps)
        # (a design Start refuses is refused at once: no "long run?" question first)
        if rc is None or not rc.needs_confirmation or event.client is None or refused:
            self.start_run()
            return
        with event.client.gui.add_modal("Start a long run?") as modal:
            event.client.gui.add_markdown(
                f"This run is estimated to take **{_fmt_s(rc.wall_s)}** of wall time "
                f"({rc.cost.steps:,.0f} steps × {rc.cost.n_nodes:,} nodes at "
                f"{_fmt_rate(rc.rate)} node-steps/s) and to write "
                f"~{rc.cost.result_bytes / 2**20:,.0f} MiB.")
            # "Don't start" first: the dialog focuses its first button, so Enter keeps
            # the user out of a long run rather than starting it (issue 29, item 8)
            stop = event.client.gui.add_button("Don't start")
            go = event.client.gui.add_button("Start anyway", color="orange")

            def start(_):
                modal.close()
                self.start_run()
            go.on_click(start)
            stop.on_click(lambda _: modal.close())

    def _on_cancel(self, event) -> None:
        if self.jobs is not None and self.active_job is not None:
            self.jobs.cancel(self.active_job, wait=0.0)

    def _on_cancel_selected(self, event) -> None:
        job = self._selected_job()
        if self.jobs is not None and job is not None:
            self.jobs.cancel(job, wait=0.0)

    def _selected_job(self) -> Optional[str]:
        return job_of(self.dd_runs.value)

    def _on_load_run(self, event) -> None:
        job = self._selected_job()
        if job is not None:
            self.load_run(job)

    def _poll_jobs(self) -> None:
        self._update_run_cost()
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
            current = getattr(self, "_select_run", None) or self._selected_job()
            self._select_run = None
            set_job_choices(self.dd_runs, jobs, current)
            self._show_run_detail()
        job = self.active_job
        if job is None:
            return
        info = follow_job(self.jobs, job, self.progress, self.md_status, "Job", _running_text)
        if info is not None:  # it ended
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
