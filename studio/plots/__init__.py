"""Plots without a UI toolkit (numpy, plotly, matplotlib): a run's result figures
(``result_plots``), a study's charts (``study_charts``) and runs side by side (``compare``).
The web studio, the command line and the studies draw with them."""
