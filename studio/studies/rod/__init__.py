"""The rod study (seed 4.1): one bristle's dynamics and the friction-damped frequency
response of seed fig. 4.6. ``study`` (options and ``run``), ``runs`` (the rod, its scenes and
run tasks) and ``outputs`` (peaks, tip tracks, spectra)."""
