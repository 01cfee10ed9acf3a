"""The quasi-static wedge study on one conical bristle against the elastica (issue 22).

The scenes of ``tests/studies/test_wedge_single_bristle.py``: the wedge_60 preset with a 1 x 1
brush, no friction, no gravity; the wedge's -y face on the tip (the preset's 0.5 mm apex
offset) or the apex right above the tip (symmetric; also run without the study's seeded tip
scatter). Prints per depth the study's force, the elastica's (tip sliding on the face,
``tests/engine/elastica_contact.py``) and their difference, where that reference holds.

    python benchmarks/wedge_single_bristle.py
"""
from __future__ import annotations

import math
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(ROOT), str(ROOT / "tests" / "studies")]

import numpy as np  # noqa: E402

import engine  # noqa: E402
from studio.studies.wedge.cycle import wedge_cycle  # noqa: E402
from studio.studies.wedge.protocol import make_protocol  # noqa: E402
from test_wedge_single_bristle import (_elastica, contact_stiffness, face_gap,  # noqa: E402
                                       single_bristle_scene)


def main() -> None:
    tmp = Path(tempfile.mkdtemp())
    ec = _elastica()
    for label, apex, over in [("face (apex 0.5 mm off)", None, {}),
                              ("symmetric (apex over the tip)", 0.0, {}),
                              ("symmetric, tip_scatter 0", 0.0, {"tip_scatter": 0.0})]:
        d = single_bristle_scene(apex_y=apex)
        p = make_protocol(d, depth=0.008, unload=False, threshold=1e-7, **over)
        try:
            r = wedge_cycle(engine.parse_scene(d), tmp / "r.h5", {"protocol": p})
        except engine.InstabilityError as exc:
            print(f"{label}: the run failed: {str(exc)[:160]}")
            continue
        depths, forces = np.array(r["depth_m"]), np.array(r["force_N"], float)
        gap, a = face_gap(d)
        br = d["brushes"][0]
        m = depths - gap > 1e-5
        ref = ec.sliding_tip_on_plane(
            np.concatenate([[1e-5], depths[m] - gap]), length=br["bristle_length"],
            root_radius=br["root_radius"], tip_radius=br["tip_radius"],
            youngs_modulus=d["materials"]["silicone"]["youngs_modulus"], normal_angle=a,
            friction_coefficient=0.0, slip_sign=1.0, contact_stiffness=contact_stiffness(d))[1:]
        print(f"{label}: dt {r['dt']:.4g} s, hold limit hits {r['hold_limit_hits']}")
        for dd, f, rr in zip(depths[m], forces[m], ref):
            ok = (rr.tip_x - br["tip_radius"] * math.sin(a) > 1e-4
                  and abs(rr.tip_angle) < math.radians(25))
            print(f"  {dd * 1e3:4.0f} mm  study {f * 1e3:9.5f} mN  elastica "
                  f"{-rr.force_z * 1e3:9.5f} mN  {(f / -rr.force_z - 1) * 100:+7.2f} %"
                  + ("" if ok else "  (reference not valid: contact at the apex edge)"))


if __name__ == "__main__":
    main()
