"""Every script in ``examples/`` runs, prints its figures and writes a PNG (the way scikit-image runs its gallery).

The scripts are found by glob, so a new example joins without editing this file.
Each runs in its own process with a temporary folder as its only argument; it must
exit with 0 (the scripts assert their own closed-form checks) and leave at least
one PNG there.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
EXAMPLES = sorted(p for p in (REPO / "examples").glob("*.py") if not p.name.startswith("_"))


def test_there_are_examples():
    assert len(EXAMPLES) >= 5, [p.name for p in EXAMPLES]


@pytest.mark.parametrize("script", EXAMPLES, ids=[p.stem for p in EXAMPLES])
def test_example_runs_and_writes_a_figure(script, tmp_path):
    out = tmp_path / "out"
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(REPO), os.environ.get("PYTHONPATH", "")]),
           "MPLBACKEND": "Agg"}
    done = subprocess.run([sys.executable, str(script), str(out)], capture_output=True, text=True, cwd=tmp_path,
                          env=env, timeout=600)
    assert done.returncode == 0, f"{script.name} failed:\n{done.stdout[-2000:]}\n{done.stderr[-4000:]}"
    assert done.stdout.strip(), f"{script.name} printed nothing"
    pngs = list(out.rglob("*.png"))
    assert pngs, f"{script.name} wrote no PNG into {out}"
    assert all(p.stat().st_size > 1000 for p in pngs)
    assert {p.name for p in tmp_path.iterdir()} == {"out"}, "an example wrote outside its folder"
