"""docs/extending.md stays correct: its Python blocks run, in order, in one namespace (they assert their own
figures: the catalogue entry loads, a fitted params.json reaches the description, the example policy nods the
head by the commanded amount, the example variant adds exactly its mass)."""

import re
from pathlib import Path

DOC = Path(__file__).resolve().parents[1] / "docs" / "extending.md"


def test_every_python_block_of_the_extending_guide_runs(tmp_path, monkeypatch):
    blocks = re.findall(r"^```python\n(.*?)^```", DOC.read_text(), flags=re.S | re.M)
    assert len(blocks) == 6
    monkeypatch.chdir(tmp_path)  # the blocks write their example files to the current folder
    namespace: dict = {"__name__": "extending_guide"}
    for number, block in enumerate(blocks, 1):
        exec(compile(block, f"{DOC.name} python block {number}", "exec"), namespace)
    assert namespace["swing"] > 0.4 and namespace["extra_kg"] > 0.19
