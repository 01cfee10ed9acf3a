"""Plots without a UI toolkit (numpy, plotly, matplotlib): a result file read for display
(``result_frames``) with its colour scale (``colors``), a run's result figures
(``result_plots``), a study's charts (``study_charts``) and runs side by side (``compare``).
The web studio, the command line and the studies draw with them."""
