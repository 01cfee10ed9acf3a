"""Bristle fatigue from a run's bending stresses (issue 25 item 6): per bristle, the stress
cycles (rainflow counting, ASTM E1049-85, by the ``rainflow`` package) and, against an S–N
curve the user gives, Miner's damage sum.

* The stress history of a bristle is, per frame, the largest outer-fibre bending stress
  over its bonds, ``4 |M| / (pi r^3)`` (``detumble_analysis.bending_stress``). It is built
  from the bending moment's magnitude: a bending that reverses direction is counted as two
  pulses from zero, not one cycle of twice the range (the channel has no sign per fibre).
* ``cycles``: the rainflow cycles (half cycles count 1/2) whose amplitude is at least
  ``CYCLE_FLOOR`` of the largest amplitude of the run, so that round-off ripples are not
  counted; the damage sums every cycle.
* The S–N curve is points ``(stress amplitude, cycles to failure)`` of the bristle material,
  joined by straight lines in log-log axes (Basquin's law between two points) and extended
  beyond the end points along the end segments (then ``sn_extrapolated`` is true). No
  endurance limit and no mean-stress correction are applied unless the points give them:
  the product invents no material data.
* Miner's rule: ``D = sum(n_i / N(S_i))``; ``1 / D`` is how many such runs the worst bristle
  survives (``None``: no damage at all).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

CYCLE_FLOOR = 0.01  # counted cycles: amplitude >= 1 % of the run's largest amplitude


@dataclass(frozen=True)
class SNCurve:
    """S–N points: stress amplitudes (Pa, decreasing) and cycles to failure (increasing)."""

    stress: np.ndarray
    cycles: np.ndarray

    def cycles_to_failure(self, amplitude) -> tuple[np.ndarray, np.ndarray]:
        """N(S) for stress amplitudes S (Pa) by log-log interpolation, and whether each was
        extrapolated beyond the given points. S <= 0 never fails (N = inf)."""
        s = np.asarray(amplitude, float)
        ls, ln = np.log(self.stress[::-1]), np.log(self.cycles[::-1])  # increasing stress
        out = np.full(s.shape, np.inf)
        pos = s > 0
        x = np.log(s[pos])
        # segment per point: inside the range, the bracketing one; outside, the end one
        k = np.clip(np.searchsorted(ls, x) - 1, 0, len(ls) - 2)
        slope = (ln[k + 1] - ln[k]) / (ls[k + 1] - ls[k])
        out[pos] = np.exp(ln[k] + slope * (x - ls[k]))
        extrapolated = np.zeros(s.shape, bool)
        extrapolated[pos] = (x < ls[0]) | (x > ls[-1])
        return out, extrapolated


def parse_sn_curve(text: str) -> SNCurve:
    """``"STRESS_MPA:CYCLES,..."`` (at least two points) as an :class:`SNCurve`;
    ValueError naming what is wrong."""
    points = []
    for item in str(text).replace(" ", "").split(","):
        if not item:
            continue
        try:
            s, n = item.split(":")
            points.append((float(s) * 1e6, float(n)))
        except ValueError:
            raise ValueError(f"--sn-curve {text!r}: {item!r} is not STRESS_MPA:CYCLES "
                             f"(e.g. 5:1e4,2:1e6)") from None
    if len(points) < 2:
        raise ValueError(f"--sn-curve {text!r}: give at least two STRESS_MPA:CYCLES points")
    points.sort(key=lambda p: -p[0])
    stress = np.array([p[0] for p in points])
    cycles = np.array([p[1] for p in points])
    if not (np.all(np.isfinite(stress)) and np.all(np.isfinite(cycles))
            and stress.min() > 0 and cycles.min() >= 1):
        raise ValueError(f"--sn-curve {text!r}: stresses must be > 0 MPa and cycles >= 1")
    if np.any(np.diff(stress) >= 0) or np.any(np.diff(cycles) <= 0):
        raise ValueError(f"--sn-curve {text!r}: a lower stress must give more cycles, each "
                         f"stress once")
    return SNCurve(stress, cycles)


def bristle_series(bond_stress: np.ndarray, bond_bristle: np.ndarray,
                   n_bristles: int) -> np.ndarray:
    """(frames, bristles): per frame, the largest stress over each bristle's bonds."""
    bond_stress = np.asarray(bond_stress, float)
    bond_bristle = np.asarray(bond_bristle)
    out = np.zeros((bond_stress.shape[0], n_bristles))
    if bond_bristle.size == 0:
        return out
    order = np.argsort(bond_bristle, kind="stable")   # bonds grouped by bristle
    owner = bond_bristle[order]
    starts = np.flatnonzero(np.r_[True, owner[1:] != owner[:-1]])
    out[:, owner[starts]] = np.maximum.reduceat(bond_stress[:, order], starts, axis=1)
    return out


def bond_bristles(bond_first_node: np.ndarray, bristle_first_node: np.ndarray) -> np.ndarray:
    """The bristle of each bond, from the bond's first node and each bristle's first node
    (bristles are numbered in node order; without the offsets' closing entry)."""
    return np.searchsorted(np.asarray(bristle_first_node), np.asarray(bond_first_node),
                           side="right") - 1


def rainflow_cycles(series: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Amplitudes (half ranges) and counts (1 or 1/2) of a series' rainflow cycles."""
    import rainflow

    cycles = list(rainflow.extract_cycles(np.asarray(series, float)))
    if not cycles:
        return np.zeros(0), np.zeros(0)
    arr = np.array([(c[0], c[2]) for c in cycles], float)
    return 0.5 * arr[:, 0], arr[:, 1]


def fatigue(stress: np.ndarray, curve: SNCurve | None = None) -> dict:
    """Per bristle (columns of ``stress``, Pa, frames x bristles): counted cycles, the
    largest amplitude and, with ``curve``, Miner's damage; and the run's figures (the worst
    bristle's). JSON-able."""
    stress = np.asarray(stress, float)
    per = [rainflow_cycles(stress[:, b]) for b in range(stress.shape[1])]
    biggest = max((float(a.max()) for a, _ in per if a.size), default=0.0)
    floor = CYCLE_FLOOR * biggest
    counted = [float(c[a >= floor].sum()) if biggest > 0 else 0.0 for a, c in per]
    amp = [float(a.max()) if a.size else 0.0 for a, _ in per]
    out = {"bristle_cycles": counted, "bristle_amplitude": amp,
           "fatigue_cycles_max": max(counted, default=0.0),
           "fatigue_amplitude_max": max(amp, default=0.0),
           "fatigue_damage_max": None, "runs_to_failure": None, "sn_extrapolated": None}
    if curve is not None:
        damage, extrapolated = [], False
        for a, c in per:
            n_fail, ext = curve.cycles_to_failure(a)
            damage.append(float(np.sum(c / n_fail)))
            extrapolated |= bool(np.any(ext & (a >= floor)))
        worst = max(damage, default=0.0)
        out.update(bristle_damage=damage, fatigue_damage_max=worst,
                   runs_to_failure=(1.0 / worst) if worst > 0 else None,
                   sn_extrapolated=extrapolated)
    return out
