"""``study trap``: the micro-object trap (issue 27 item 4). Options and command in
:mod:`.study` (with the scenes), the run on a worker in :mod:`.task`."""
from .study import Options, add_parser, run

__all__ = ["Options", "add_parser", "run"]
