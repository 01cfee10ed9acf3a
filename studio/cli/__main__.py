"""``python -m studio.cli ...``: the same as ``brush-studio ...``."""
import sys

from studio.cli.main import main

sys.exit(main())
