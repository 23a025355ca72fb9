"""What the console shows (issue 37 item 5): no empty progress bar, counted nouns, library warnings summed up."""

from __future__ import annotations

import json
import logging

import pytest

from datasets_synthetic.phantoms import make_phantom
from slices.summary import count_noun
from workbench.cli import main


@pytest.fixture(scope="module")
def one_body(tmp_path_factory):
    ph = make_phantom("ellipsoid", a=12.0, b=9.0, c=10.0)
    path = tmp_path_factory.mktemp("in") / "contours.json"
    path.write_text(json.dumps({"units": "mm", "contours": [
        {"z": c["z"], "points": c["points"].tolist()} for c in ph.contours(2.0, n_points=40)]}))
    return path


def test_slices_run_prints_one_body_and_no_empty_bar(one_body, tmp_path, capsys):
    assert main(["slices", "reconstruct", str(one_body), "--rays", "16", "--no-render",
                 "--out", str(tmp_path / "o")]) == 0
    captured = capsys.readouterr()
    assert ", 1 body (1 body chained" in captured.out, captured.out
    assert "bodies" not in captured.out and "(ies)" not in captured.out and "(s)" not in captured.out
    # the bar opens at the first finished body, already counting it: never an empty "bodies: 0%| 0/N" bar
    # (its rate, e.g. "262144.00body/s", may hold the characters "0body")
    assert " 0/" not in captured.err and "bodies: 0body" not in captured.err, captured.err


def test_slices_error_prints_only_the_error_line(one_body, tmp_path, capsys):
    assert main(["slices", "reconstruct", str(one_body), "--rays", "-3", "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert err.strip().count("\n") == 0 and err.startswith("workbench: error:"), err


@pytest.mark.parametrize(("n", "text"), [(0, "0 bodies"), (1, "1 body"), (2, "2 bodies")])
def test_count_noun(n, text):
    assert count_noun(n, "body", "bodies") == text


def test_reference_counts_fitpack_iteration_caps_instead_of_warning(shared_data, recwarn):
    from slices.io import read_rtstruct
    from slices.reference import compare
    from slices.structure import reconstruct_contours

    # one body of the breast set's Lt Lung (8 planes) makes FITPACK's across-slice spline hit its
    # 20-iteration limit: a RuntimeWarning from a batch worker before, a count in the result now
    stack = read_rtstruct(shared_data / "rtstruct_breast" / "rtss.dcm", "Lt Lung")
    ref = compare(reconstruct_contours(stack.contours, mesh=False, irregular=True, surface_path="coons"))
    assert ref["fitpack_iteration_limit_hits"] >= 1
    assert not [w for w in recwarn if "maximal number of iterations" in str(w.message)]


def test_batch_turns_dask_kill_lines_into_one_warning():
    from workbench.commands.batch import _quiet_shutdown

    with _quiet_shutdown() as killed:
        logging.getLogger("distributed.nanny").warning("Worker process still alive after 4.0 seconds, killing")
        logging.getLogger("distributed.nanny").warning("other")
    assert len(killed) == 1


def test_height_rmse_states_its_convention_and_the_plane_removed_figure(tmp_path, capsys):
    """A deviated light tilts the whole height field: the RMSE says so and is also given without the plane."""
    tri, out = tmp_path / "tri", tmp_path / "rec"
    assert main(["synth", "triad", "--scene", "plate", "--size", "128", "--pixel-size", "0.2", "--lights", "3",
                 "--deviate", "2,0,0", "--out", str(tri)]) == 0
    capsys.readouterr()
    assert main(["photometric", "reconstruct", str(tri), "--out", str(out)]) == 0
    line = next(t for t in capsys.readouterr().out.splitlines() if t.startswith("height RMSE"))
    assert "means removed" in line and "tilt" in line and "best plane removed" in line and "2 deg" in line
    summary = json.loads((out / "summary.json").read_text())
    assert summary["height_rmse_plane_removed_mm"] < 0.2 * summary["height_rmse_mm"]
    assert summary["height_error_tilt_deg"] > 0.3


def test_camera_options_that_contradict_the_folder_are_warned(tmp_path, capsys):
    """A rounded --pixel-size, and a perspective camera on an orthographic folder: one warning line each."""
    tri = tmp_path / "tri"
    assert main(["synth", "triad", "--scene", "plate", "--size", "64", "--pixel-size", "0.05859375",
                 "--out", str(tri)]) == 0
    capsys.readouterr()
    assert main(["photometric", "reconstruct", str(tri), "--pixel-size", "0.0586", "--out", str(tmp_path / "a")]) == 0
    warned = [t for t in capsys.readouterr().err.splitlines() if t.startswith("workbench: warning:")]
    assert len(warned) == 1 and "--pixel-size 0.0586 differs" in warned[0] and "0.05859375" in warned[0]
    assert main(["photometric", "reconstruct", str(tri), "--camera", "perspective", "--focal-length-px", "4000",
                 "--camera-height", "400", "--out", str(tmp_path / "b")]) == 0
    warned = [t for t in capsys.readouterr().err.splitlines() if t.startswith("workbench: warning:")]
    assert any("--camera perspective contradicts the orthographic camera" in t for t in warned), warned
    assert main(["photometric", "reconstruct", str(tri), "--pixel-size", "0.05859375",
                 "--out", str(tmp_path / "c")]) == 0
    assert "warning" not in capsys.readouterr().err


def test_worker_warnings_are_one_line(capsys):
    import warnings

    from workbench.commands.batch import one_line_warnings

    with warnings.catch_warnings():  # restores showwarning on exit
        warnings.simplefilter("always")
        one_line_warnings()
        warnings.warn("The maximal number of iterations (20) allowed\nfor finding smoothing spline", RuntimeWarning,
                      stacklevel=1)
    err = capsys.readouterr().err
    assert err == "workbench: warning: The maximal number of iterations (20) allowed\n"


@pytest.mark.parametrize("argv", [["photometric", "reconstruct", "nosuch_folder"],
                                  ["surfaces", "coons", "nosuch_grid.npy"],
                                  ["photometric", "errors", "--lights", "nosuch_lights.txt"]])
def test_a_quick_error_prints_no_progress_bar(argv, tmp_path, capsys):
    assert main([*argv, "--out", str(tmp_path / "o.ply" if argv[0] == "surfaces" else tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("workbench: error:"), err
