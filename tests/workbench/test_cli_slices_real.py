"""``workbench slices reconstruct`` on real-structure inputs (moved from tests/slices/test_real_structures.py:
the library's tests do not run the command line)."""

from __future__ import annotations

import json

from tests.slices.test_real_structures import _cylinder, _rtstruct


def test_cli_roi_number(tmp_path, capsys):
    from workbench.cli import main

    path = _rtstruct(tmp_path / "rs.dcm", [(3, "GTV", _cylinder([0.0, 2.0, 4.0])),
                                           (7, "GTV", _cylinder([0.0, 2.0, 4.0, 6.0]))])
    assert main(["slices", "reconstruct", str(path), "--roi", "GTV", "--out", str(tmp_path / "a")]) == 2
    assert "ROI numbers 3, 7" in capsys.readouterr().err
    assert main(["slices", "reconstruct", str(path), "--roi-number", "7", "--no-render",
                 "--out", str(tmp_path / "b")]) == 0
    summary = json.loads((tmp_path / "b" / "summary.json").read_text())
    assert summary["n_slices"] == 4
