"""Studies: many simulations of one design, run on Dask distributed.

``runner`` runs independent simulations (one task and one HDF5 per run; restartable), whose
files and outcomes ``run_files`` writes and reads; ``cli`` adds ``brush-studio study <name>``
and ``study_command`` holds what every command shares. Each study builds its runs, collects
their small summaries and writes CSV, HDF5 and PNG plots into an output folder; a larger one
is split by its seams: ``wedge`` (the run task and its curves), ``wedge_scenes``,
``wedge_protocol`` and ``wedge_study`` (the command and its outputs); ``spin`` and ``rod``
(physics and run tasks), ``*_outputs`` and ``*_study``. See docs/studies.md.
"""
