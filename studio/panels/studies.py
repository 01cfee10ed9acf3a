"""The Studies panel: the Studies tab (forms, plots, tables: :mod:`studio.ui_studies`) on
the shared job pool. A mixin of :class:`studio.app.Studio`."""
from __future__ import annotations

from ..presets import preset_names
from .common import _md_escape


class StudiesPanel:
    """Studies tab of the studio (mixin)."""

    def _build_studies_gui(self, gui) -> None:
        self.studies = None
        if self.jobs is not None:
            from ..ui_studies import StudiesTab

            self.studies = StudiesTab(gui, self.tab_studies, self.jobs, preset_names(),
                                      _md_escape)
        else:
            with self.tab_studies:
                gui.add_markdown("No job pool: studies need the studio's workers.")
