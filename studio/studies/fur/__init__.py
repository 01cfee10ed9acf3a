"""``study fur``: space fur against impacts (seed 5.3.2, fig. 5.1). The options and the
command in :mod:`.study`, the scenes in :mod:`.scenes`, the run on a worker in :mod:`.task`."""
from .study import Options, add_parser, run

__all__ = ["Options", "add_parser", "run"]
