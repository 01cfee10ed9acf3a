"""The ``brush-studio`` command line: the parser and dispatch (``main``), the ``run``,
``validate`` and ``info`` handlers (``commands``), ``demo``, ``serve`` (the HTTP service as a
command; ``export`` and ``studio`` are the web package's commands) and the terminal's
progress and summary (``run_console``). ``python -m studio.cli`` is ``brush-studio``."""
