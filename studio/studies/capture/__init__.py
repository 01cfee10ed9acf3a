"""``study capture``: capture of a tumbling target by a gripper brush on orbit (issue 27
item 2). Options and command in :mod:`.study`, the run on a worker in :mod:`.task`, the
capture criterion in :mod:`.criterion`."""
from .study import Options, add_parser, run

__all__ = ["Options", "add_parser", "run"]
