"""The scenes of the wedge-based studies (seed 4.2): presets or files as JSON dicts, the
wedge's angle, the ``--preset``/``--angles`` choice of a command, a resolution override, and
the parse of every scene before anything runs. :class:`StudyInputError` is these studies'
bad input (a scene without the wedge, a bad option value)."""
from __future__ import annotations

import copy
import json
import math
from pathlib import Path
from typing import Optional

from studio.studies.api import StudyInputError
from studio.studies.study_command import number_list

DEFAULT_PRESET = "wedge_60"


# ----------------------------------------------------------------------------- scenes
def load_scene_dict(ref: str) -> tuple[dict, str]:
    """A scene as a JSON dict from a file path or a preset name, and a label for it."""
    import engine

    path = Path(ref)
    if not path.exists():
        try:
            from studio.presets import preset_path

            path = preset_path(ref)
        except (ImportError, KeyError):
            raise StudyInputError(f"{ref}: no such scene file or preset") from None
    scene = engine.load_scene(path)  # SceneError names bad fields
    return json.loads(scene.to_json()), path.stem


def default_scene_dict() -> tuple[dict, str]:
    """The wedge_60 preset, or the embedded demo scene (same brush, 60 deg wedge) if the
    presets are not there."""
    try:
        return load_scene_dict(DEFAULT_PRESET)
    except StudyInputError:
        from importlib.resources import files

        return json.loads((files("studio") / "data" / "demo_scene.json").read_text()), "demo"


def find_body(scene: dict, body: str) -> dict:
    for b in scene.get("bodies", []):
        if b.get("name") == body:
            return b
    names = [b.get("name") for b in scene.get("bodies", [])]
    raise StudyInputError(f"the scene has no body {body!r} (bodies: {names})")


def wedge_angle_deg(scene: dict, body: str = "wedge") -> Optional[float]:
    shape = find_body(scene, body).get("shape", {})
    return math.degrees(shape["angle"]) if shape.get("type") == "wedge" else None


def set_wedge_angle(scene: dict, angle_deg: float, body: str = "wedge") -> dict:
    """A copy of ``scene`` with the wedge's included angle set (degrees at this edge)."""
    scene = copy.deepcopy(scene)
    shape = find_body(scene, body)["shape"]
    if shape.get("type") != "wedge":
        raise StudyInputError(f"body {body!r} is a {shape.get('type')}, not a wedge")
    shape["angle"] = math.radians(angle_deg)
    return scene


def _parse_angles(text) -> list[float]:
    if isinstance(text, (list, tuple)):
        text = ",".join(f"{float(a):g}" for a in text)
    try:
        angles = number_list(text, float, f"--angles {text!r}: expected degrees like 30,45,60,75")
    except ValueError as exc:
        raise StudyInputError(str(exc)) from None
    if not angles or any(not 0 < a < 180 for a in angles):
        raise StudyInputError(f"--angles {text!r}: each angle in (0, 180) degrees")
    return angles


def safe_id(text: str) -> str:
    s = "".join(c if c.isalnum() or c in "._-" else "_" for c in text).strip("._-")
    return s or "run"


def resolve_scenes(presets: list[str], angles, body: str = "wedge"
                   ) -> list[tuple[str, dict, str]]:
    """``[(run_id, scene dict, where it came from)]`` for the command's options: each
    ``--preset``; or for each of ``--angles`` (a list of degrees, or their text
    ``"30,45"``) the preset ``wedge_<angle>`` (or, with one
    ``--preset``, that scene with the angle changed); or the default preset."""
    out = []
    if angles:
        alist = _parse_angles(angles)
        if len(presets) > 1:
            raise StudyInputError("--angles takes at most one --preset (the base scene)")
        for a in alist:
            if presets:
                base, label = load_scene_dict(presets[0])
                out.append((f"{safe_id(label)}_at_{a:g}deg", set_wedge_angle(base, a, body),
                            f"{presets[0]} with the wedge angle set to {a:g} deg"))
            else:
                try:
                    scene, label = load_scene_dict(f"wedge_{a:g}")
                    out.append((safe_id(label), scene, f"preset wedge_{a:g}"))
                except StudyInputError:
                    base, label = default_scene_dict()
                    out.append((f"{safe_id(label)}_at_{a:g}deg",
                                set_wedge_angle(base, a, body),
                                f"{label} with the wedge angle set to {a:g} deg"))
    elif presets:
        for ref in presets:
            scene, label = load_scene_dict(ref)
            out.append((safe_id(label), scene, ref))
    else:
        scene, label = default_scene_dict()
        out.append((safe_id(label), scene, f"default ({label})"))
    seen: dict = {}
    unique = []
    for rid, scene, src in out:
        seen[rid] = seen.get(rid, 0) + 1
        unique.append((rid if seen[rid] == 1 else f"{rid}_{seen[rid]}", scene, src))
    return unique


def apply_resolution(scene: dict, n_nodes: Optional[int]) -> dict:
    if n_nodes is None:
        return scene
    scene = copy.deepcopy(scene)
    for b in scene.get("brushes", []):
        b["n_nodes"] = int(n_nodes)
    return scene


def validate_scenes(scenes: list[dict]) -> Optional[str]:
    """Parse every scene before anything runs: a message naming the bad fields, or None."""
    import engine

    for scene in scenes:
        try:
            engine.parse_scene(scene)
        except engine.SceneError as exc:
            return "invalid scene: " + "; ".join(str(p) for p in exc.problems)
    return None
