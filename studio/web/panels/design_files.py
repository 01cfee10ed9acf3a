"""The Design panel's files: presets (load, with a confirmation before edits are
discarded), JSON designs (upload, download, share by link) and mesh uploads. A mixin of
:class:`studio.web.panels.design.DesignPanel`."""
from __future__ import annotations

import copy
import re
from pathlib import Path

import numpy as np

from studio.web import scene as us
from studio.web import view as uv
from studio.presets import load_preset_or_file
from studio.web.panels.common import _md_escape, _safe_name


# a parser's own words at the end of a message ("...: IndexError: index 1 is out of bounds")
_TECHNICAL_TAIL = re.compile(r":\s*[A-Z]\w*(Error|Exception|Warning)\b.*$", re.S)


def mesh_refusal(filename: str, exc: Exception) -> str:
    """What the Body folder says when an uploaded mesh cannot be used: the store's reason
    (``studio.service.jobs.MeshError``: a format, a size, a count) without the parser's internals
    (a raw ``IndexError`` means nothing to the person uploading), and what to do."""
    reason = _TECHNICAL_TAIL.sub("", str(exc)).strip().rstrip(".")
    if not isinstance(exc, ValueError) or not reason:  # (MeshError is a ValueError)
        reason = "it cannot be read as a triangle mesh"
    unreadable = any(w in reason for w in ("read", "no triangle", "missing vertices"))
    return (f"mesh {filename!r} refused: {reason}." +
            (" Export it again as STL, OBJ or PLY, every triangle naming existing vertices."
             if unreadable else ""))


class DesignFiles:
    """Presets, design files and mesh uploads of the Design tab (mixin)."""

    def _on_upload_mesh(self, event) -> None:
        up = event.target.value
        with self.lock:
            if not (self.scene.get("bodies") or []):
                self.hold_design(us.validate(us.add_body(self.scene)).scene)
            try:
                if self.jobs is not None:
                    info = self.jobs.add_mesh(up.content, up.name)
                    path = self.jobs.mesh_path(info["id"])
                else:
                    folder = (self.data_dir or Path(".")) / "meshes"
                    folder.mkdir(parents=True, exist_ok=True)
                    path = folder / Path(up.name).name
                    path.write_bytes(up.content)
                mesh = uv.shape_mesh({"type": "mesh", "file": str(path)})
            except Exception as exc:  # (trimesh raises many kinds on a bad file)
                self._set_note(self.md_body, mesh_refusal(up.name, exc))
                return
            new = copy.deepcopy(self.scene)
            body = new["bodies"][self.sel.body]
            extent = float(np.max(mesh.extents)) if len(mesh.vertices) else 1.0
            # a file in millimetres is the usual case for CAD exports: scale it so the body
            # is at most 0.5 m across
            scale = 1.0 if extent <= 0.5 else 1e-3
            body["shape"] = {"type": "mesh", "file": str(path), "scale": scale}
            mp = body.get("mass_properties")
            if mp and not mesh.is_watertight:
                body["mass_properties"] = None
            v = us.validate(new)
            if not v.ok:
                self._set_note(self.md_body, "; ".join(p.message for p in v.problems))
                return
            self.hold_design(v.scene)
            self._set_note(self.md_body, f"mesh {up.name!r}: {len(mesh.faces):,} triangles, "
                           f"{'closed' if mesh.is_watertight else 'open (no density)'}, "
                           f"scale {scale:g}")
            self.set_mode("design", redraw=False)
            self.redraw_design()
            self.refresh_fields()

    def has_edits(self) -> bool:
        """Whether the design differs from what was last loaded (a preset, a file, a link)."""
        loaded = getattr(self, "loaded_scene", None)
        return loaded is not None and self.scene != loaded

    def _on_load_preset(self, event) -> None:
        name = self.dd_preset.value
        if not self.has_edits():
            self.load_preset(name)
            return
        # loading replaces the design: ask first, in a dialog on the tab that asked
        gui = event.client.gui if event.client is not None else self.server.gui
        with gui.add_modal("Discard your edits?") as modal:
            gui.add_markdown(f"The design *{_md_escape(self.scene.get('name', 'scene'))}* "
                             f"has edits since it was loaded. Loading preset "
                             f"**{_md_escape(name)}** replaces them (*Download design as "
                             f"JSON* keeps a copy).")
            keep = gui.add_button("Keep editing")  # (first: the button Enter presses)
            discard = gui.add_button(f"Discard edits and load {name}", color="red")

            def _discard(_event) -> None:
                modal.close()
                self.load_preset(name)

            discard.on_click(_discard)
            keep.on_click(lambda _event: modal.close())

    def load_preset(self, name: str) -> None:
        import engine

        try:
            scene = load_preset_or_file(name)
        except engine.SceneError as exc:
            self._set_note(self.md_preset, "; ".join(str(p) for p in exc.problems))
            return
        self.set_design(scene)
        self.mark_loaded(f"preset {name!r} was loaded")
        if name in self.dd_preset.options:
            self.dd_preset.value = name
        self._set_note(self.md_preset, f"loaded preset {name!r}")

    def _on_upload_json(self, event) -> None:
        import engine

        up = event.target.value
        try:
            scene = engine.parse_scene(up.content)
        except engine.SceneError as exc:
            self._set_note(self.md_preset, f"{up.name} refused: " +
                           "; ".join(str(p) for p in exc.problems))
            return
        self.set_design(scene)
        self.mark_loaded(f"{up.name} was loaded")
        self._set_note(self.md_preset, f"loaded {up.name}")

    def design_json(self) -> str:
        """The design as scene JSON (the held, validated Scene: no parse)."""
        return self.design.to_json(indent=2) + "\n"

    def _on_share(self, event) -> None:
        """Store the design and show a link that opens it in a new session (the receiver
        gets a copy: nobody else's design changes)."""
        share = getattr(self, "share", None)
        design_id = share(self.design_json()) if share is not None else None
        if design_id is None:
            self._set_note(self.md_preset, "sharing needs the studio's data folder")
            return
        self.shared_design_id = design_id
        host = getattr(self, "link_host", None) or "127.0.0.1"
        url = f"http://{host}/?websocket=ws://{host}/design/{design_id}"
        self.md_preset.content = f"Link to this design: [{_md_escape(url)}]({url})"
        self.md_preset.visible = True

    def _on_download_json(self, event) -> None:
        if event.client is None:
            return
        name = _safe_name(self.scene.get("name", "scene")) + ".json"
        event.client.send_file_download(name, self.design_json().encode(),
                                        save_immediately=True)
        self.mark_loaded(f"it was saved as {name}")

    def _on_download_stl(self, event) -> None:
        """The designed brush as STL (``studio.web.export.brush_stl``), named after the design."""
        if event.client is None:
            return
        from studio.web.export import brush_stl

        try:
            data = brush_stl(self.scene)
        except ValueError as exc:
            self._set_note(self.md_preset, str(exc))
            return
        event.client.send_file_download(_safe_name(self.scene.get("name", "scene")) + ".stl",
                                        data, save_immediately=True)
