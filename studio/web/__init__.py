"""The 3D web studio on viser: the application (``app``), one browser tab's state
(``session``), the design's fields, scene and view (``fields``, ``scene``, ``view``,
``brushes``, ``guides``, ``design_warnings``), the Studies tab's design search
(``design_search``), the result frames it plays back (``result_frames``) and the tabs
(``panels``)."""
