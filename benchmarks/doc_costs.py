"""The CPU seconds of docs/studies.md's "One small run of each" commands, as written there.

The commands are read from the doc itself: under each ``### NAME`` heading of that section,
every ``bash`` block is one measured command (``brush-studio`` run as
``python -m studio.cli`` from this checkout); a ``python`` block before it (a file the
command reads) runs first, in the same folder, and is not counted. Each command runs in a
fresh folder, empty but for a link ``static_presets`` to the repository's (as
``tests/docs/test_docs_run.py`` runs the docs' blocks), in a fresh child process; its CPU is user + system of the child and
everything it waited for (``resource.getrusage(RUSAGE_CHILDREN)``). A warm-up command fills
the numba cache first and is not counted. One thread (``NUMBA_NUM_THREADS=1``).

Usage (from the repository root)::

    python benchmarks/doc_costs.py            # every command of the section (about 2 CPU-min)
    python benchmarks/doc_costs.py wedge rod  # those headings only
"""
from __future__ import annotations

import argparse
import os
import re
import resource
import shlex
import subprocess
import sys
import tempfile
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
DOC = ROOT / "docs" / "studies.md"
SECTION = "## One small run of each"


def commands(text: str) -> list[tuple[str, list[str], str]]:
    """``[(heading, python setup blocks before it, bash command)]`` of the section."""
    body = text.split(SECTION, 1)[1]
    body = re.split(r"\n## ", body, maxsplit=1)[0]
    out = []
    for part in re.split(r"\n### ", body)[1:]:
        name = part.splitlines()[0].strip()
        setup: list[str] = []
        for lang, code in re.findall(r"```(python|bash)\n(.*?)```", part, re.S):
            if lang == "python":
                setup.append(code)
            else:
                out.append((name, list(setup), code.strip()))
    return out


def _env() -> dict:
    env = dict(os.environ, NUMBA_NUM_THREADS="1")
    env["PYTHONPATH"] = os.pathsep.join(p for p in (str(ROOT), env.get("PYTHONPATH")) if p)
    return env


def run_cpu(args: list[str], cwd: str) -> float:
    """CPU seconds of ``args`` and its descendants; it must succeed."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    p = subprocess.run(args, cwd=cwd, env=_env(), capture_output=True, text=True)
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if p.returncode != 0:
        sys.exit(f"failed ({p.returncode}): {' '.join(args)}\n{p.stderr[-3000:]}")
    return (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)


def as_args(command: str) -> list[str]:
    words = shlex.split(command)
    if words[0] != "brush-studio":
        sys.exit(f"not a brush-studio command: {command}")
    return [sys.executable, "-m", "studio.cli", *words[1:]]


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("names", nargs="*", help="headings to measure (default: all)")
    args = ap.parse_args(argv)
    todo = [c for c in commands(DOC.read_text()) if not args.names or c[0] in args.names]
    commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=ROOT,
                            capture_output=True, text=True).stdout.strip()
    print(f"docs/studies.md, '{SECTION[3:]}', at commit {commit or '?'}: CPU-s of each "
          f"command (whole process and descendants), fresh folder, one thread", flush=True)
    with tempfile.TemporaryDirectory(prefix="doc-costs-") as tmp:
        run_cpu(as_args("brush-studio study wedge --preset wedge_60 --depth-mm 1 --nodes 3 "
                        "--no-unload --workers 1 -o warm"), tmp)  # fills the cache
        for name, setup, command in todo:
            folder = tempfile.mkdtemp(dir=tmp)
            # as the docs test runs them: an empty folder with a link to the presets
            (Path(folder) / "static_presets").symlink_to(ROOT / "static_presets")
            for code in setup:
                run_cpu([sys.executable, "-c", code], folder)
            cpu = run_cpu(as_args(command), folder)
            print(f"{name:<16} {cpu:6.1f}  {command}", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
