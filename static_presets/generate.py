"""Write the preset scene files of this folder from the seed thesis's numbers.

    python static_presets/generate.py          # rewrite every static_presets/*.json
    python static_presets/generate.py --check  # exit 1 if a file differs from what this writes

The JSON files are the presets (the studio, the server and the CLI read them); this script
is how they were made: every derived number (positions, masses, profiles) is computed here
from the thesis's values, so the arithmetic can be checked and a preset regenerated after a
change. Each scene's ``description`` says which section/figure of the thesis it reproduces
and every assumption it makes. SI units throughout.

One module per preset family, beside this file: ``seed_values.py`` (what they share: the
thesis's materials, friction angles and brush), ``rod_presets.py`` (seed 4.1),
``wedge_presets.py`` (4.2), ``spin_presets.py`` (4.3, appendix H), ``impact_presets.py``
(chapter 5: fur, plate, gripper), ``detumble_presets.py`` (the mission, issue 15) and
``docking_presets.py`` (brush-assisted docking, issue 27), ``capture_presets.py``
(capture with a gripper brush on orbit, issue 27) and ``trap_presets.py`` (the micro-object
trap, issue 27).
"""
from __future__ import annotations

import importlib.util
import json
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent


def _family(stem: str):
    """The module ``HERE/<stem>.py``. This folder is no package (the script runs on its own,
    the tests run it with ``runpy``), so each module is loaded from its file and registered
    under its stem: the families' ``from seed_values import ...`` then finds it."""
    if stem in sys.modules and getattr(sys.modules[stem], "__file__", None) == \
            str(HERE / f"{stem}.py"):
        return sys.modules[stem]
    spec = importlib.util.spec_from_file_location(stem, HERE / f"{stem}.py")
    module = importlib.util.module_from_spec(spec)
    sys.modules[stem] = module
    spec.loader.exec_module(module)
    return module


def _detumble_presets() -> list[dict]:
    """The mission presets of issue 15 (``detumble_presets.py``, beside this file)."""
    seed = _family("seed_values")
    return _family("detumble_presets").all_detumble(seed.SILICONE, seed.PHI_SIL_SIL,
                                                    seed.seed_brush(), seed.quat_axis_angle)


def _docking_presets() -> list[dict]:
    """Brush-assisted docking (issue 27; ``docking_presets.py``, beside this file)."""
    seed = _family("seed_values")
    return _family("docking_presets").presets(seed.SILICONE, seed.PHI_SIL_SIL,
                                              seed.seed_brush, seed.Q_Z_TO_PLUS_X)


def _capture_presets() -> list[dict]:
    """Capture with a gripper brush on orbit (issue 27; ``capture_presets.py``)."""
    seed = _family("seed_values")
    return _family("capture_presets").presets(seed.SILICONE, seed.PHI_SIL_SIL,
                                              seed.seed_brush, seed.Q_Z_TO_PLUS_X,
                                              seed.Q_Z_TO_MINUS_X)


def _trap_presets() -> list[dict]:
    """The micro-object trap (issue 27 item 4; ``trap_presets.py``, beside this file)."""
    seed = _family("seed_values")
    return _family("trap_presets").presets(seed.SILICONE, seed.PHI_SIL_SIL, seed.seed_brush)


def all_presets() -> dict[str, dict]:
    _family("seed_values")  # (first: the families import it)
    scenes = [*_family("rod_presets").presets(), *_family("wedge_presets").presets(),
              *_family("spin_presets").presets(), *_family("impact_presets").presets(),
              *_detumble_presets(), *_docking_presets(), *_capture_presets(),
              *_trap_presets()]
    return {s["name"]: s for s in scenes}


def render(scene: dict) -> str:
    return json.dumps(scene, indent=2) + "\n"


def main(argv: list[str]) -> int:
    check = "--check" in argv
    stale = []
    for name, scene in all_presets().items():
        path = HERE / f"{name}.json"
        text = render(scene)
        if check:
            if not path.exists() or path.read_text() != text:
                stale.append(path.name)
        else:
            path.write_text(text)
            print(f"wrote {path}")
    if stale:
        print("out of date (run python static_presets/generate.py): " + ", ".join(stale))
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
