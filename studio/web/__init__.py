"""The 3D web studio on viser: the application (``app``), one browser tab's state
(``session``), the design's fields, scene and view (``fields``, ``scene``, ``view``,
``brushes``, ``guides``, ``design_warnings``), the Studies tab's design search
(``design_search``), the exports for other tools (``export``: a run for ParaView, the brush
as STL, plotted series as CSV; also the ``brush-studio export`` command) and the tabs
(``panels``)."""
