"""Brush Studio's user-facing layer: the command line (``studio.cli``), and, to come, the 3D
studio, the worker/job layer and the HTTP server. It talks to the engine only through the
engine's public API (``import engine``) and to runs only through result files."""
from __future__ import annotations

from importlib.metadata import PackageNotFoundError, version as _version

try:
    __version__ = _version("brush-studio")
except PackageNotFoundError:  # running from a source tree that was not pip-installed
    __version__ = "0.1.0"

__all__ = ["__version__"]
