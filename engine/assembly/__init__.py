"""Scene -> arrays: the built :class:`System` (``system``: ``build``), its parts (``bristles``,
``bodies``, ``contacts``, ``loads``, the reduced brushes' ``patches``; the tapered element
``element``; the neighbour lists' skin, allocation and growth ``neighbours``), the automatic
time step (``timestep``), the cost estimate (``estimate``) and the
build-time overlap check (``overlap``)."""
