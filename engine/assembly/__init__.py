"""Scene -> arrays: the built :class:`System` (``system``: ``build``), its parts (``bristles``,
``bodies``, ``contacts``, ``loads``; the tapered element ``element``), the automatic time step
(``timestep``), the cost estimate (``estimate``) and the build-time checks (``overlap``,
``mesh_limits``)."""
