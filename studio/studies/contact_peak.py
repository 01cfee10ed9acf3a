"""The largest single bristle contact force a body feels over a run, and the pressures a
designer quotes from it (issue 25 item 6; the design search's ``peak_contact_pressure``).

No channel records single contacts: :class:`ContactForcePeak` is an ``engine.run`` observer
that reads the engine's own contact list at each recorded frame (so the peak is the largest
at those frames, not between them).
"""
from __future__ import annotations

import math

import numpy as np


class ContactForcePeak:
    """``observer`` for ``engine.run``: the largest single bristle-body contact force on body
    ``body_index`` over the recorded frames (N), read at each frame from the engine's own
    contact list (``System.body_pairs``: each active contact's force ``fc``), which no
    channel records."""

    def __init__(self, system, body_index: int):
        self.system, self.k = system, body_index
        self.peak = 0.0

    def __call__(self, frame) -> None:
        from engine.kernels.body_contacts import BSLOT

        bl = self.system.body_pairs  # read each time: a growing list is replaced
        n = int(bl.n[0])
        on = (bl.active[:n * BSLOT] != 0) & (np.repeat(bl.b[:n], BSLOT) == self.k)
        if on.any():
            self.peak = max(self.peak,
                            float(np.linalg.norm(bl.fc[:n * BSLOT][on], axis=1).max()))


def nominal_pressure(force: float, tip_radius: float) -> float:
    """A single bristle contact's force over its tip's cross-section pi r_tip^2, Pa: a nominal
    pressure (the true Hertzian patch is smaller and its pressure higher)."""
    return float(force / (math.pi * tip_radius ** 2))


def footprint_pressure(force: float, area: float) -> float:
    """A brush's whole push spread over its footprint area, Pa (the mean pressure under it;
    single tips press far harder: :func:`nominal_pressure`)."""
    if area <= 0:
        raise ValueError(f"footprint area = {area} m^2: must be > 0")
    return float(force / area)
