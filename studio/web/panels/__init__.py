"""The studio's panels, one module per tab of the page: ``design`` (the scene's fields,
presets, bodies, uploads), ``run`` (start, cancel, the shared Runs list, the live stream),
``results`` (playback, plots, downloads; ``studio.plots.result_frames.ResultFrames`` reads a result
file for display, ``studio.plots.result_plots`` draws its plots)
and ``studies`` (the Studies tab on the job pool). Each is a mixin of
:class:`studio.web.session.Session` (one browser tab's design, view and runs), which
:class:`studio.web.app.Studio` creates per client and polls; ``common`` holds formatting and
display constants."""
