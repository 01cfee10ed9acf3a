"""Brush Studio's user-facing layer, talking to the engine only through its public API
(``import engine``) and to runs only through result files or in-memory observers: the command
line (``studio.cli`` and ``commands``), the 3D web studio (``app``, ``session``, ``panels``,
``ui_*``), the job layer (``jobs``) and HTTP service (``server``, ``client``), the studies
(``studies``) and the plots (``result_plots``, ``study_charts``)."""
from __future__ import annotations

from importlib.metadata import PackageNotFoundError, version as _version

try:
    __version__ = _version("brush-studio")
except PackageNotFoundError:  # running from a source tree that was not pip-installed
    __version__ = "0.1.0"

__all__ = ["__version__"]
