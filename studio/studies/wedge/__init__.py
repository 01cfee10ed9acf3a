"""The wedge study (seed 4.2): force against penetration depth. ``study`` (options and
``run``), ``cycle`` (one run: the press-hold-release cycle, its task), ``protocol`` (the
hold-until-steady protocol the wedge-based studies share) and ``scenes`` (presets, angles,
resolution overrides)."""
