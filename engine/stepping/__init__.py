"""Running a built system: the loop around the compiled step (``loop``: ``run``), what it
records (``channels``, ``observables``, ``observe``), how it explains a failure
(``diagnosis``), compile timing (``compile_clock``), quasi-static increments
(``quasistatic``) and prescribed motions of kinematic bodies (``motion``)."""
