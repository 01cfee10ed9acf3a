"""Brush Studio's user-facing layer, talking to the engine only through its public API
(``import engine``) and to runs only through result files or in-memory observers. One
package per product: the command line (``cli``), the 3D web studio (``web``), the HTTP
service with its job layer and client (``service``), the studies (``studies``) and the plots
they all draw with (``plots``). The modules at this level are what all of them share: the
presets (``presets``), the exit codes (``exit_codes``), terminal messages (``console``) and
number formatting (``fmt``)."""
from __future__ import annotations

from importlib.metadata import PackageNotFoundError, version as _version

try:
    __version__ = _version("brush-studio")
except PackageNotFoundError:  # running from a source tree that was not pip-installed
    __version__ = "0.1.0"

__all__ = ["__version__"]
