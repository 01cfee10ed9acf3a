"""Studies: many simulations of one design, run on Dask distributed.

``runner`` runs independent simulations (one task and one HDF5 per run; restartable);
``cli`` adds ``brush-studio study <name>``; each study module (``wedge``, ``refinement``,
``sensitivity``, ...) builds its runs, collects their small summaries and writes CSV, HDF5
and PNG plots into an output folder. See docs/studies.md.
"""
