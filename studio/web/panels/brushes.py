"""The brush selector of the Design panel (issue 14, item 7): which brush the Brush layout
and Material fields edit, and Add / Remove brush. A mixin of :class:`studio.web.panels.design.
DesignPanel`: it sets ``self.sel.brush`` and changes ``self.scene`` through
:mod:`studio.web.brushes`, validated with the engine like every other edit."""
from __future__ import annotations

from studio.web import brushes as ub
from studio.web import scene as us


class BrushSelector:
    """Brush selector of the studio's Design tab (mixin)."""

    def _build_brush_selector(self, gui) -> None:
        """The selector and its buttons (called inside the Brush layout folder)."""
        names = ub.brush_names(self.scene)
        self.dd_brush = gui.add_dropdown("edit brush", names or ("(none)",),
                                         hint="the brush the fields below edit")
        self.dd_brush.on_update(self._on_select_brush)
        self.bt_add_brush = gui.add_button("Add brush",
                                           hint="a copy of the selected brush beside it")
        self.bt_add_brush.on_click(self._on_add_brush)
        self.bt_remove_brush = gui.add_button("Remove brush", color="red")
        self.bt_remove_brush.on_click(self._on_remove_brush)
        self.md_brush = gui.add_markdown("", visible=False)

    def _refresh_brush_selector(self) -> None:
        """Show the design's brushes with the selected one (called by refresh_fields)."""
        names = ub.brush_names(self.scene)
        if tuple(self.dd_brush.options) != (names or ("(none)",)):
            self.dd_brush.options = names or ("(none)",)
        if names:
            self.sel.brush = min(max(self.sel.brush, 0), len(names) - 1)
            self.dd_brush.value = names[self.sel.brush]
        self.bt_remove_brush.disabled = not names

    def _on_select_brush(self, event) -> None:
        if event.client is None:  # set by the server (refresh): not a choice
            return
        self.select_brush(event.target.value)

    def select_brush(self, name: str) -> bool:
        """Edit the brush named ``name`` (False if the design has none of that name)."""
        with self.lock:
            names = ub.brush_names(self.scene)
            if name not in names:
                return False
            self.sel.brush = names.index(name)
            self._clear_errors()
            self._set_note(self.md_brush, "")
            if self.mode == "design":
                self.redraw_design()  # (the selected brush in colour, the others grey)
            self.refresh_fields()
            return True

    def _on_add_brush(self, event) -> None:
        self.add_brush()

    def add_brush(self) -> bool:
        """Add a copy of the selected brush beside it and select it."""
        with self.lock:
            try:
                new = ub.add_brush(self.scene, self.sel.brush)
            except ValueError as exc:
                self._set_note(self.md_brush, str(exc))
                return False
            return self._apply_brush_edit(new, len(new["brushes"]) - 1,
                                          f"added brush {new['brushes'][-1]['name']!r}")

    def _on_remove_brush(self, event) -> None:
        self.remove_brush()

    def remove_brush(self) -> bool:
        """Remove the selected brush (and the loads on it)."""
        with self.lock:
            names = ub.brush_names(self.scene)
            try:
                new, notes = ub.remove_brush(self.scene, self.sel.brush)
            except ValueError as exc:
                self._set_note(self.md_brush, str(exc))
                return False
            note = "; ".join([f"removed brush {names[self.sel.brush]!r}"] + notes)
            return self._apply_brush_edit(new, max(self.sel.brush - 1, 0), note)

    def _apply_brush_edit(self, new: dict, selected: int, note: str) -> bool:
        v = us.validate(new)
        if not v.ok:
            self._set_note(self.md_brush, "refused: " + "; ".join(p.message
                                                                 for p in v.problems))
            return False
        self.hold_design(v.scene)
        self.sel.brush = selected
        self._clear_errors()
        self.set_mode("design", redraw=False)
        self.redraw_design()
        self.refresh_fields()
        self._set_note(self.md_brush, note)
        return True
