"""The design's history in a session (issue 29, items 2 and 7): undo/redo of design edits,
the "modified since ..." state shown at the top of the panel, and the draft that lets a tab
survive a reload.

Every change of the design goes through the ``scene`` property: the previous design is
pushed on the undo stack (successive keystrokes in one box count as one edit), the redo
stack is cleared, and the session's draft is written to ``DATA/drafts/ID.json``. The tab's
address is rewritten (``history.replaceState``) to ``?websocket=ws://HOST/draft/ID``, so that
a reload (F5) reconnects to ``/draft/ID`` and :meth:`studio.web.app.Studio.design_for` reopens the
same design, with its undo history and its "modified" state.

A mixin of :class:`studio.web.session.Session`.
"""
from __future__ import annotations

import copy
import json
import secrets
import time
from pathlib import Path
from typing import Optional

from studio.web.panels.common import _md_escape

#: edits kept for undo
MAX_UNDO = 100
#: successive edits of one field closer than this (s) are one undo step (a typed "0.8")
COALESCE_S = 2.0


def draft_path(data_dir: Optional[Path], draft_id: Optional[str]) -> Optional[Path]:
    """Where a session's draft lives (None without a data folder or with a bad id)."""
    if data_dir is None or not draft_id or not draft_id.isalnum():
        return None
    return Path(data_dir) / "drafts" / f"{draft_id}.json"


def new_draft_id() -> str:
    return secrets.token_hex(8)


class DesignHistory:
    """Undo/redo, the modified marker and the reload draft (mixin)."""

    # ----------------------------------------------------------------- the design
    @property
    def scene(self) -> dict:
        return self._scene

    @scene.setter
    def scene(self, value: dict) -> None:
        old = self.__dict__.get("_scene")
        self._scene = value
        if old is None or value == old:
            return
        if not self.__dict__.get("_restoring"):
            key, now = self.__dict__.get("_edit_key"), time.monotonic()
            last_key, last_t = self.__dict__.get("_last_edit", (None, -1e9))
            undo = self.__dict__.setdefault("undo_stack", [])
            if not (key is not None and key == last_key and now - last_t < COALESCE_S
                    and undo):
                undo.append(old)
                del undo[:-MAX_UNDO]
            self._last_edit = (key, now)
            self.redo_stack = []
        self._edit_key = None
        self._history_changed()

    def _history_changed(self) -> None:
        """Show the modified state and the undo/redo buttons; write the draft."""
        if "bt_undo" not in self.__dict__:  # (the GUI is not built yet)
            return
        self.bt_undo.disabled = not self.__dict__.get("undo_stack")
        self.bt_redo.disabled = not self.__dict__.get("redo_stack")
        self._update_modified()
        self.save_draft()

    def _update_modified(self) -> None:
        label = self.__dict__.get("loaded_label") or "it was opened"
        text = (f"<span style='color:#b60'>● modified since {_md_escape(label)}</span>"
                if self.has_edits() else f"unmodified since {_md_escape(label)}")
        if self.md_modified.content != text:
            self.md_modified.content = text

    def mark_loaded(self, label: str) -> None:
        """The design as it is now is the reference of "modified" (a preset or a file just
        loaded, a design just downloaded)."""
        self.loaded_scene = copy.deepcopy(self.scene)
        self.loaded_label = label
        self._history_changed()

    # ----------------------------------------------------------------- undo / redo
    def _build_history_gui(self, gui) -> None:
        self.md_modified = gui.add_markdown("")
        self.bt_undo = gui.add_button("Undo edit", disabled=True,
                                      hint="go back to the design before the last edit")
        self.bt_undo.on_click(lambda _e: self.undo())
        self.bt_redo = gui.add_button("Redo edit", disabled=True,
                                      hint="apply again the edit last undone")
        self.bt_redo.on_click(lambda _e: self.redo())
        self._history_changed()

    def undo(self) -> bool:
        return self._step(self.__dict__.setdefault("undo_stack", []),
                          self.__dict__.setdefault("redo_stack", []))

    def redo(self) -> bool:
        return self._step(self.__dict__.setdefault("redo_stack", []),
                          self.__dict__.setdefault("undo_stack", []))

    def _step(self, source: list, target: list) -> bool:
        with self.lock:
            if not source:
                return False
            target.append(self.scene)
            self._restoring = True
            try:
                self.scene = source.pop()
            finally:
                self._restoring = False
            self._last_edit = (None, -1e9)
            names = self._body_names()
            self.sel.body = min(self.sel.body, max(len(names) - 1, 0))
            self.sel.brush = min(self.sel.brush,
                                 max(len(self.scene.get("brushes") or []) - 1, 0))
            self._clear_errors()
            self.set_mode("design", redraw=False)
            self.redraw_design()
            self.refresh_fields()
            self._history_changed()
            return True

    # ----------------------------------------------------------------- draft (reload)
    def save_draft(self) -> None:
        path = draft_path(self.data_dir, self.__dict__.get("draft_id"))
        if path is None:
            return
        data = {"scene": self.scene, "loaded_scene": self.loaded_scene,
                "loaded_label": self.__dict__.get("loaded_label"),
                "undo": self.__dict__.get("undo_stack", [])[-MAX_UNDO:],
                "redo": self.__dict__.get("redo_stack", [])[-MAX_UNDO:],
                "playback_job": self.__dict__.get("playback_job")}
        try:
            path.parent.mkdir(parents=True, exist_ok=True)
            tmp = path.with_suffix(".tmp")
            tmp.write_text(json.dumps(data))
            tmp.replace(path)
        except OSError as exc:  # (a full disk must not stop the design)
            print(f"studio: draft not saved: {type(exc).__name__}: {exc}")

    def restore_draft(self, data: dict) -> None:
        """Take the undo history and the modified reference of a saved draft (the design
        itself was opened from it)."""
        with self.lock:
            self.loaded_scene = data.get("loaded_scene") or copy.deepcopy(self.scene)
            self.loaded_label = data.get("loaded_label") or "it was opened"
            self.undo_stack = list(data.get("undo") or [])
            self.redo_stack = list(data.get("redo") or [])
            self._history_changed()

    def attach_draft(self, draft_id: str) -> None:
        """Keep this session's design in draft ``draft_id`` and point the tab's address at it,
        so that a reload reopens it."""
        from viser import _messages

        self.draft_id = draft_id
        self.save_draft()
        source = (
            "const u = new URL(window.location.href);"
            "const cur = u.searchParams.get('websocket') || "
            "((location.protocol === 'https:' ? 'wss://' : 'ws://') + location.host);"
            "const w = new URL(cur); w.pathname = '/draft/" + draft_id + "'; w.search = '';"
            "u.searchParams.set('websocket', w.toString());"
            "window.history.replaceState(null, document.title, u.toString());")
        try:
            self.server.gui._websock_interface.queue_message(
                _messages.RunJavascriptMessage(source=source))
        except Exception as exc:  # (viser internals changed: reload then opens the default)
            print(f"studio: cannot point the tab at its draft: {type(exc).__name__}: {exc}")
