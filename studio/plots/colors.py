"""The colour scale of bristle quantities (bending moment, deflection) in the studio's view and
its legend: viridis-like, numpy only."""
from __future__ import annotations

import numpy as np

_VIRIDIS = np.array([[68, 1, 84], [59, 82, 139], [33, 145, 140], [94, 201, 98],
                     [253, 231, 37]], float)


def colormap(values: np.ndarray, vmax: float) -> np.ndarray:
    """(S, 3) uint8 colours (viridis-like) of values in [0, vmax]."""
    t = np.clip(np.nan_to_num(np.asarray(values, float)) / (vmax if vmax > 0 else 1.0), 0, 1)
    x = t * (len(_VIRIDIS) - 1)
    i = np.minimum(x.astype(int), len(_VIRIDIS) - 2)
    f = (x - i)[:, None]
    return (_VIRIDIS[i] * (1 - f) + _VIRIDIS[i + 1] * f).astype(np.uint8)


def colormap_css() -> str:
    """The colour scale of :func:`colormap` as a CSS gradient, 0 on the left (for a legend)."""
    stops = ", ".join(f"rgb({r:.0f},{g:.0f},{b:.0f})" for r, g, b in _VIRIDIS)
    return f"linear-gradient(to right, {stops})"
