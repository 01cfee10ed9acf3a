"""README's "Project layout" table matches the folders: every package of ``engine`` and
``studio`` (the studies' own sub-packages aside: the ``studio/studies/`` row owns them) has a
row, and every row names a path that exists."""
from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def _layout_rows() -> list[str]:
    text = (ROOT / "README.md").read_text()
    section = text.split("## Project layout", 1)[1].split("\n## ", 1)[0]
    return re.findall(r"^\| `([^`]+)` \|", section, flags=re.M)


def test_every_package_has_a_row_and_every_row_exists():
    rows = {r.rstrip("/") for r in _layout_rows()}
    assert rows, "README has no Project layout table"
    packages = {str(p.parent.relative_to(ROOT)) for top in ("engine", "studio")
                for p in (ROOT / top).rglob("__init__.py")
                if "studies" not in p.parent.relative_to(ROOT).parts[1:]
                or p.parent.relative_to(ROOT).parts[1:] == ("studies",)}
    missing = sorted(packages - rows)
    assert not missing, f"packages without a README layout row: {missing}"
    absent = sorted(r for r in rows if not (ROOT / r).exists())
    assert not absent, f"README layout rows naming no path: {absent}"
