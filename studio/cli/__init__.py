"""The ``brush-studio`` command line: the parser and dispatch (``main``), the ``run``,
``validate`` and ``info`` handlers (``commands``), ``demo``, ``export``, ``serve`` (the HTTP
service and the studio as a command) and the terminal's progress and summary
(``run_console``). ``python -m studio.cli`` is ``brush-studio``."""
