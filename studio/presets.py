"""The preset scenes: the seed thesis's experiments as scene files in ``static_presets/``.

``PRESET_DIR`` is the folder (the environment variable ``BRUSH_STUDIO_PRESETS`` overrides
it); a preset's name is its file's stem (``wedge_60`` is ``static_presets/wedge_60.json``).

    from studio import presets
    presets.list_presets()            # [{"name": "gripper", "title": ..., "description": ...}, ...]
    presets.preset_path("wedge_60")   # PRESET_DIR / "wedge_60.json"
    scene = presets.load_preset("wedge_60")   # a validated engine.Scene

Only names of files that are in the folder are accepted: ``preset_path("../x")`` raises
``KeyError``, so a name from a URL or a form can be passed straight in.
"""
from __future__ import annotations

import json
import os
import re
from pathlib import Path

__all__ = ["PRESET_DIR", "list_presets", "preset_path", "load_preset", "demo_scene_text",
           "demo_scene", "load_preset_or_file", "preset_names"]

_DEFAULT_DIR = Path(__file__).resolve().parents[1] / "static_presets"
PRESET_DIR: Path = Path(os.environ.get("BRUSH_STUDIO_PRESETS") or _DEFAULT_DIR)

# a file stem that can only name a file directly inside the folder
_NAME = re.compile(r"[A-Za-z0-9][A-Za-z0-9_.-]*")
# a full stop that ends a sentence (not "fig. 4.2"): followed by a capital letter
_SENTENCE_END = re.compile(r"\.\s+(?=[A-Z][a-z ])")


def _folder() -> Path:
    return Path(PRESET_DIR)


def _names() -> list[str]:
    folder = _folder()
    if not folder.is_dir():
        return []
    return sorted(p.stem for p in folder.glob("*.json")
                  if p.is_file() and _NAME.fullmatch(p.stem))


def preset_path(name: str) -> Path:
    """Path of the preset ``name`` (a file stem from ``list_presets``). ``KeyError`` for
    anything else: an unknown name, a path (``../x``, ``a/b``), an empty string."""
    if not isinstance(name, str) or not _NAME.fullmatch(name) or name not in _names():
        raise KeyError(f"no preset named {name!r} in {_folder()} "
                       f"(available: {', '.join(_names()) or 'none'})")
    return _folder() / f"{name}.json"


def _summary(path: Path) -> dict:
    """name, title, description of a preset file, without validating the whole scene."""
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        data = {}
    if not isinstance(data, dict):
        data = {}
    description = data.get("description") if isinstance(data.get("description"), str) else ""
    title = path.stem.replace("_", " ")
    title = title[:1].upper() + title[1:]
    # the description starts with the thesis reference ("Seed 4.2 (figs...), ..."): the
    # title names the preset and what it reproduces in one line
    first = _SENTENCE_END.split(description, 1)[0].strip().rstrip(".")
    if first:
        title = f"{title}: {first}"
    return {"name": path.stem, "title": title, "description": description}


def list_presets() -> list[dict]:
    """Every preset as ``{"name", "title", "description"}``, sorted by name."""
    return [_summary(_folder() / f"{n}.json") for n in _names()]


def load_preset(name: str):
    """The preset ``name`` as a validated ``engine.Scene`` (``KeyError`` for an unknown
    name, ``engine.SceneError`` for a file that is not a valid scene)."""
    import engine

    return engine.load_scene(preset_path(name))


# ----------------------------------------------------------------------------- the demo
def demo_scene_text() -> str:
    """The JSON text of the embedded default scene (``studio/data/demo_scene.json``)."""
    from importlib.resources import files

    return (files("studio") / "data" / "demo_scene.json").read_text()


def demo_scene():
    """The embedded default scene (studio/data/demo_scene.json)."""
    import engine

    return engine.parse_scene(demo_scene_text())


def load_preset_or_file(ref: str):
    """A scene from a preset name (``studio.presets``), a JSON file path, or ``demo``."""
    import engine

    if ref in ("", "demo"):
        return demo_scene()
    path = Path(ref)
    if path.suffix.lower() == ".json" or path.exists():
        return engine.load_scene(path)
    try:
        return load_preset(ref)
    except KeyError:
        names = [p["name"] for p in list_presets()]
        raise engine.SceneError.single("(preset)", ref,
                                       f"no such file or preset; presets: {names}") from None


def preset_names() -> list[str]:
    """'demo' (the embedded scene) and the names of static_presets/."""
    names = ["demo"]
    try:
        names += [p["name"] for p in list_presets()]
    except Exception:
        pass
    return names
