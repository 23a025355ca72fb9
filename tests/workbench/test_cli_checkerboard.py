"""Checkerboard calibration from the command line.

Moved from tests/photometric/test_checkerboard.py: the library's tests do not run the workbench.
"""

import numpy as np
import pytest

from tests.photometric.test_checkerboard import COLS, POSES, ROWS, SQ, H, K, W, _view


@pytest.mark.slow
def test_cli_calibrate_writes_the_camera_with_its_rms(tmp_path, capsys):
    import json

    from surfaces.io import write_png
    from workbench.cli import main

    paths = []
    for k, (r, t) in enumerate(POSES):
        paths.append(tmp_path / f"board_{k}.png")
        write_png(paths[-1], np.round(_view(r, t) * 65535).astype(np.uint16))
    np.savetxt(tmp_path / "P.txt", [[60.0, 0.0, 150.0], [-30.0, 52.0, 150.0], [-30.0, -52.0, 150.0]])
    flats = []
    for k in range(3):
        flats.append(str(tmp_path / f"flat_{k}.png"))
        write_png(flats[-1], np.full((H, W), 30000, np.uint16))
    out = tmp_path / "rig.json"
    assert main(["photometric", "calibrate", "--light-positions", str(tmp_path / "P.txt"), "--flat-field", *flats,
                 "--checkerboard", *map(str, paths), "--board", f"{COLS}x{ROWS}", "--square-mm", str(SQ),
                 "--out", str(out)]) == 0
    doc = json.loads(out.read_text())
    assert doc["camera"]["model"] == "perspective" and len(doc["camera"]["distortion"]) == 5
    assert doc["calibration"]["camera_calibration"]["rms_reprojection_px"] < 0.2
    assert doc["camera"]["focal_length_px"] == pytest.approx(K[0, 0], rel=0.01)
    assert "RMS reprojection error" in capsys.readouterr().out
    assert main(["photometric", "calibrate", "--light-positions", str(tmp_path / "P.txt"), "--flat-field", *flats,
                 "--checkerboard", *map(str, paths), "--board", "8by5", "--square-mm", "12", "--out", str(out)]) == 2
