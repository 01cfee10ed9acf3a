"""The Results tab's *Compare runs* folder and its window (issue 29, item 7): runs added one
by one (the run loaded for playback: *Add this run to the comparison*), a measured curve
uploaded as CSV, overlaid in a window of their own with the table of headline figures
(``studio.plots.compare`` draws them). A mixin of :class:`studio.web.session.Session`."""
from __future__ import annotations

from typing import Any, Optional

from studio.plots import compare as cmp
from studio.web.panels.common import PLOT_ASPECT, _md_escape

COMPARE_WINDOW = (980, 720)  # px, floating over the view while the user compares


class ComparePanel:
    """Compare runs (mixin)."""

    def _build_compare_gui(self, gui) -> None:
        self.compare_jobs: list[str] = []
        self.compare_measured: Optional[cmp.Measured] = None
        self.compare_rows: list[dict] = []
        self.compare_figs: dict[str, Any] = {}
        self.compare_plots: list[Any] = []
        self.compare_panel = None
        with gui.add_folder("Compare runs", expand_by_default=True):
            self.md_compare = gui.add_markdown("Add two or more runs: load each one, then "
                                               "*Add this run to the comparison*.")
            self.bt_compare_add = gui.add_button("Add this run to the comparison",
                                                 disabled=True)
            self.bt_compare_add.on_click(lambda _e: self.compare_add(self.playback_job))
            self.up_measured = gui.add_upload_button(
                "Upload measured curve (CSV)", mime_type="text/csv",
                hint="two columns with a header: time [s] or depth [mm], then force [N]")
            self.up_measured.on_upload(self._on_upload_measured)
            self.bt_compare_clear = gui.add_button("Clear comparison", disabled=True)
            self.bt_compare_clear.on_click(lambda _e: self.compare_clear())

    def compare_add(self, job: Optional[str]) -> None:
        if job is None or job in self.compare_jobs:
            return
        self.compare_jobs.append(job)
        self._refresh_compare()

    def compare_clear(self) -> None:
        self.compare_jobs, self.compare_measured = [], None
        self._refresh_compare()

    def _on_upload_measured(self, event) -> None:
        up = event.target.value
        try:
            self.compare_measured = cmp.parse_measured_csv(
                up.name, up.content.decode("utf-8", errors="replace"))
        except ValueError as exc:
            self.md_compare.content = f"<span style='color:#d00'>⚠ " \
                                      f"{_md_escape(str(exc))}</span>"
            return
        self._refresh_compare()

    def _refresh_compare(self) -> None:
        """Read the runs again, label them, redraw the window and the table."""
        import json

        runs, problems = [], []
        for job in self.compare_jobs:
            try:
                info = self.jobs.get(job)
                try:
                    scene = json.loads(self.jobs.scene_path(job).read_text())
                except OSError:
                    scene = None
                runs.append(cmp.read_run(job, info.name, self.jobs.result_path(job), scene))
            except Exception as exc:  # (a purged run, an unreadable file)
                problems.append(f"run {job}: {exc}")
        cmp.label_runs(runs)
        self.compare_rows = [cmp.headline(r) for r in runs]
        self.compare_figs = cmp.compare_figures(runs, self.compare_measured)
        n = len(runs)
        lines = [f"**{n} run{'s' if n != 1 else ''}**" +
                 (f" and the measured curve *{_md_escape(self.compare_measured.name)}*"
                  if self.compare_measured is not None else "") +
                 (" (add another to compare)" if n == 1 else "")]
        lines += [f"<span style='color:#d00'>⚠ {_md_escape(p)}</span>" for p in problems]
        self.md_compare.content = "\n\n".join(lines)
        self.bt_compare_clear.disabled = not (runs or self.compare_measured)
        self._draw_compare_window(runs)

    def _draw_compare_window(self, runs) -> None:
        gui = self.server.gui
        for h in self.compare_plots:
            h.remove()
        self.compare_plots = []
        if not runs and self.compare_measured is None:
            if self.compare_panel is not None:
                self.compare_panel.visible = False
            return
        if self.compare_panel is None:
            if not hasattr(gui, "add_panel"):  # (a viser before panels: the Results tab)
                self.compare_panel, self.compare_tab = None, self.tab_results
            else:
                self.compare_panel = gui.add_panel(visible=True)
                self.compare_tab = self.compare_panel.add_tab("Compare runs")
                self.compare_panel.float(x=40, y=40, width=COMPARE_WINDOW[0],
                                         height=COMPARE_WINDOW[1])
        if self.compare_panel is not None:
            self.compare_panel.visible = True
            self.compare_panel.expand()
        with self.compare_tab:
            self.compare_plots.append(gui.add_markdown(
                cmp.table_markdown(self.compare_rows) if self.compare_rows else
                "No run yet: only the measured curve."))
            for title, fig in self.compare_figs.items():
                self.compare_plots.append(gui.add_plotly(fig, aspect=PLOT_ASPECT))
            close = gui.add_button("Close the comparison window")
            close.on_click(lambda _e: setattr(self.compare_panel, "visible", False)
                           if self.compare_panel is not None else None)
            self.compare_plots.append(close)

    def compare_state(self) -> dict:
        """What the comparison shows (for scripts and tests)."""
        return {"runs": list(self.compare_jobs), "table": self.compare_rows,
                "plots": {t: [d.name for d in f.data] for t, f in self.compare_figs.items()},
                "measured": self.compare_measured.name if self.compare_measured else None,
                "window": bool(self.compare_panel is not None and self.compare_panel.visible)}
