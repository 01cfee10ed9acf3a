"""The Studies panel: the Studies tab (forms, plots, tables: :mod:`studio.web.panels.studies_tab`) on
the shared job pool. A mixin of :class:`studio.web.app.Studio`."""
from __future__ import annotations

from typing import Optional

from studio.presets import preset_names
from studio.web.panels.common import _md_escape


class StudiesPanel:
    """Studies tab of the studio (mixin)."""

    def study_design(self) -> tuple[Optional[str], str]:
        """The session's design as a study scene: stored (``Studio.share_design``, under
        its content id) and named ``design:<id>``; None without a data folder."""
        from studio.studies.registry import DESIGN_PREFIX

        with self.lock:
            text, name = self.design_json(), str(self.scene.get("name", "scene"))
        share = getattr(self, "share", None)
        design_id = share(text) if share is not None else None
        return (None if design_id is None else DESIGN_PREFIX + design_id), name

    def study_design_scene(self) -> dict:
        """The session's design as a scene dict (a copy): the design search's fields."""
        import copy

        with self.lock:
            return copy.deepcopy(self.scene)

    def load_study_design(self, scene: dict, label: str) -> Optional[str]:
        """Put a scene a study made (a search trial's design) into the design view, as a
        loaded file is; returns the engine's refusal, if any."""
        import engine

        try:
            parsed = engine.parse_scene(scene)
        except engine.SceneError as exc:
            return "; ".join(str(p) for p in exc.problems)
        self.set_design(parsed)
        self.mark_loaded(f"{label} was loaded")
        return None

    def _build_studies_gui(self, gui) -> None:
        self.studies = None
        if self.jobs is not None:
            from studio.web.panels.studies_tab import StudiesTab

            self.studies = StudiesTab(gui, self.tab_studies, self.jobs, preset_names(),
                                      _md_escape, current_design=self.study_design,
                                      design_scene=self.study_design_scene,
                                      load_design=self.load_study_design)
        else:
            with self.tab_studies:
                gui.add_markdown("No job pool: studies need the studio's workers.")
