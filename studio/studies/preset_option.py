"""``--preset`` for the studies that run the seed's own experiments (``rod``, ``spin``).

In every study ``--preset`` names the preset scenes the study's runs start from (repeat it for
several). ``wedge``, ``refinement`` and ``sensitivity`` take any scene, a file or a preset
name; ``rod`` and ``spin`` build their runs from their own presets (the rod excitations, the
cube sizes), so there ``--preset`` chooses among those, as ``--cases`` / ``--cubes`` do.
"""
from __future__ import annotations

from typing import Mapping, Sequence


class PresetChoiceError(ValueError):
    """A ``--preset`` the study cannot run (its message is the command's error)."""


def add_preset_option(parser, study: str, own: Sequence[str], instead_of: str) -> None:
    parser.add_argument(
        "--preset", action="append", default=[], metavar="NAME",
        help=f"a preset the study's runs start from (repeat for several; default all): "
             f"{', '.join(own)}; another way to give {instead_of}")


def _name_of(preset: str, own: Mapping[str, object]) -> str:
    """``preset`` itself, or the name of the study's preset whose file it is (the HTTP API
    passes presets as their files)."""
    from pathlib import Path

    if preset in own:
        return preset
    try:
        from studio.presets import preset_path

        path = Path(preset).resolve()
        return next((n for n in own if preset_path(n).resolve() == path), preset)
    except (ImportError, KeyError, OSError):
        return preset


def chosen(study: str, presets: Sequence[str], own: Mapping[str, object],
           other_value: str, other_default: str, other_option: str) -> list:
    """The study's choices (``own``: preset name -> choice) named by ``presets``, in their
    order; empty when no ``--preset`` was given. Refuses a name outside ``own`` (a scene file
    included) and ``--preset`` together with ``other_option`` changed from its default, since
    both choose the same runs."""
    if not presets:
        return []
    presets = [_name_of(p, own) for p in presets]
    bad = [p for p in presets if p not in own]
    if bad:
        raise PresetChoiceError(
            f"--preset {bad[0]!r}: study {study} builds its runs from its own presets, one of "
            f"{', '.join(own)}; run another scene with `brush-studio run` or study it with "
            f"`brush-studio convergence --preset FILE`")
    if other_value != other_default:
        raise PresetChoiceError(f"--preset and {other_option} both choose the runs: give one")
    return list(dict.fromkeys(own[p] for p in presets))
