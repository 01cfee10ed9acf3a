"""``benchmarks/doc_costs.py`` measures the commands docs/studies.md's "One small run of each"
shows: every study its cost table links to has a command the script finds and would run."""
from __future__ import annotations

import re
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "benchmarks"))
import doc_costs  # noqa: E402


def test_every_row_of_the_cost_table_has_a_measured_command():
    text = doc_costs.DOC.read_text()
    section = text.split(doc_costs.SECTION, 1)[1].split("\n## ", 1)[0]
    rows = re.findall(r"^\| \[`[^`]+`\]\(#([\w-]+)\) \|", section, flags=re.M)
    found = doc_costs.commands(text)
    assert len(rows) >= 8   # wedge ... fit-dissipation: the table itself was found
    assert sorted(set(rows)) == sorted({name for name, _, _ in found})
    for name, setup, command in found:
        assert doc_costs.as_args(command)[1:3] == ["-m", "studio.cli"]
    # the command that reads a file gets the block that writes it
    assert [len(s) for n, s, _ in found if n == "fit-dissipation"] == [1]
