"""The README's scripting example runs as written and does what `sim run` does: the same walk, the same figures."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np

from toddlerbot.runtime.log import RunLog

README = Path(__file__).resolve().parents[1] / "README.md"


def test_the_readme_script_walks_as_sim_run_does(tmp_path, monkeypatch, capsys):
    from cli_support import run_main

    (script,) = [b for b in re.findall(r"^```python\n(.*?)^```", README.read_text(), flags=re.S | re.M)
                 if "sim_session" in b]
    assert len(script.strip().splitlines()) <= 10
    monkeypatch.chdir(tmp_path)
    namespace: dict = {}
    exec(compile(script, "README.md scripting example", "exec"), namespace)
    summary, session = namespace["summary"], namespace["session"]
    assert not summary.fell and 0.85 < summary.displacement_m[0] < 1.05  # 10 s at 0.1 m/s: 0.95 m in the README
    assert (tmp_path / "walk.mp4").stat().st_size > 10_000 or session.render_skipped
    code, _, err = run_main(monkeypatch, capsys, "sim", "run", "--policy", "walk-zmp", "--command", "0:0.1,0,0",
                            "--seconds", "10", "--log", tmp_path / "cli.npz")
    assert code == 0, err
    cli = RunLog.load(tmp_path / "cli.npz")
    np.testing.assert_array_equal(cli.base_pos, namespace["result"].log.base_pos)  # the very same run
