"""The spin study (seed 4.3, the brush dynamic test): ``study`` (options and ``run``),
``runs`` (the scenes, a run's analysis and task) and ``outputs`` (per-run and per-contact
tables)."""
