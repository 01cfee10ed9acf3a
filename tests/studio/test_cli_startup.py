"""``brush-studio --help`` and a study's parser do not import numba, the kernels or Dask."""
from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]

_CODE = """
import contextlib, io, json, sys
from studio.cli.main import main
with contextlib.redirect_stdout(io.StringIO()):
    codes = [main(["--help"]), main(["study", "wedge", "--help"])]
heavy = ("numba", "distributed", "dask", "trimesh", "scipy", "engine.kernels.stepper", "matplotlib")
print(json.dumps([codes, sorted(m for m in heavy if m in sys.modules)]))
"""


def test_help_imports_no_kernels_and_no_dask():
    p = subprocess.run([sys.executable, "-c", _CODE], cwd=ROOT, capture_output=True,
                       text=True, check=True)
    codes, heavy = json.loads(p.stdout.splitlines()[-1])
    assert codes == [0, 0] and heavy == []
