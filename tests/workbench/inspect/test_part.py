"""One part: images in light order, near-field reconstruction with the rig, verdict, result.json + overlay.png."""

from __future__ import annotations

import json
import shutil

import numpy as np
import pytest

from surfaces.io import write_png
from workbench.inspect.part import check_options, inspect_part, load_rig, part_images
from workbench.inspect.spec import parse_spec


def _copy_part(small_lot, name, tmp_path):
    dst = tmp_path / name
    shutil.copytree(small_lot["parts"] / name, dst)
    return dst


def test_part_images_follow_filenames_or_sorted_names(small_lot, tmp_path):
    part = _copy_part(small_lot, "clean", tmp_path)
    assert [p.name for p in part_images(part, 4)] == ["001.png", "002.png", "003.png", "004.png"]
    (part / "filenames.txt").write_text("004.png\n003.png\n002.png\n001.png\n")
    assert [p.name for p in part_images(part, 4)][0] == "004.png"
    (part / "filenames.txt").unlink()
    (part / "mask.png").write_bytes((part / "001.png").read_bytes())  # not an image of a light
    assert len(part_images(part, 4)) == 4


@pytest.mark.parametrize("change, error, message", [
    ("missing", ValueError, "3 image(s) for 4 lights of the rig (1 missing"),
    ("extra", ValueError, "5 image(s) for 4 lights of the rig (1 extra"),
    ("listed", FileNotFoundError, "image 009.png named in filenames.txt does not exist"),
])
def test_part_images_errors(small_lot, tmp_path, change, error, message):
    part = _copy_part(small_lot, "clean", tmp_path)
    if change == "missing":
        (part / "004.png").unlink()
        (part / "filenames.txt").unlink()
    elif change == "extra":
        shutil.copy(part / "001.png", part / "005.png")
        (part / "filenames.txt").unlink()
    else:
        (part / "filenames.txt").write_text("001.png\n009.png\n")
    with pytest.raises(error) as err:
        part_images(part, 4)
    assert message in str(err.value)
    with pytest.raises(FileNotFoundError, match="no such folder"):
        part_images(tmp_path / "none", 4)


def test_check_options():
    assert check_options({"background": "smooth", "integrator": "lsq"}) == {"background": "smooth",
                                                                              "integrator": "lsq"}
    with pytest.raises(ValueError, match="--option rig: set by the inspection itself"):
        check_options({"rig": "x"})
    with pytest.raises(ValueError, match="--option speed: not an option of photometric reconstruct"):
        check_options({"speed": 2})


def test_rig_is_read_once(small_lot):
    assert load_rig(small_lot["rig"]) is load_rig(str(small_lot["rig"]))
    with pytest.raises(FileNotFoundError, match="--rig"):
        load_rig(small_lot["root"] / "none.json")


def test_clean_and_defective_parts(small_lot, tmp_path):
    spec = parse_spec({"max_depth_mm": 0.10, "max_count": 1})
    clean = inspect_part(small_lot["parts"] / "clean", tmp_path / "clean", small_lot["rig"], spec)
    assert clean["verdict"] == "pass" and clean["n_imperfections"] == 0 and clean["max_depth_mm"] == 0.0
    over = inspect_part(small_lot["parts"] / "scratch_over", tmp_path / "over", small_lot["rig"], spec,
                        part_id="p-over")
    assert over["verdict"] == "fail" and over["n_fail"] == 1
    assert sorted(p.name for p in (tmp_path / "over").iterdir()) == ["overlay.png", "result.json"]
    result = json.loads((tmp_path / "over" / "result.json").read_text())
    assert result["format"] == "workbench-inspection" and result["part"] == "p-over"
    assert result["verdict"] == "fail" and result["decision_rule"] == "simple"
    assert result["decided_by"] == ["imperfection 0 max_depth_mm"]
    scratch = result["imperfections"][0]
    truth = next(p for p in small_lot["truth"]["parts"] if p["id"] == "scratch_over")
    assert scratch["values"]["max_depth_mm"]["value"] == pytest.approx(truth["depth_mm"], rel=0.1)
    assert scratch["values"]["length_mm"]["value"] == pytest.approx(truth["length_mm"], rel=0.1)
    assert scratch["values"]["max_depth_mm"]["U"] is None  # no uncertainty asked for: none stated
    assert scratch["checks"][0] == {"quantity": "max_depth_mm", "value": scratch["values"]["max_depth_mm"]["value"],
                                    "U": None, "limit": 0.1, "limit_kind": "max", "rule": "simple",
                                    "verdict": "fail"}
    # the scratch's centre (3, -2) mm and axis 25 deg, in the rig frame
    assert np.allclose(scratch["center_mm"], [3.0, -2.0], atol=0.3) and scratch["axis_deg"] == pytest.approx(25, abs=2)
    assert result["measurement"]["light_model"] == "point" and result["measurement"]["flat_field"] is True
    assert result["files"] == ["overlay.png", "result.json"]


def test_keep_arrays_writes_the_heavy_files(small_lot, tmp_path):
    inspect_part(small_lot["parts"] / "dent_under", tmp_path / "d", small_lot["rig"], small_lot["spec"],
                 keep_arrays=True)
    names = {p.name for p in (tmp_path / "d").iterdir()}
    assert {"height.npy", "albedo.npy", "surface.ply", "defects.json", "result.json", "overlay.png"} <= names
    result = json.loads((tmp_path / "d" / "result.json").read_text())
    assert set(result["files"]) == names and result["verdict"] == "pass"


def test_without_arrays_the_coarse_surface_leaves_the_figures_unchanged(small_lot, tmp_path):
    """Without --keep-arrays the part composes the library stages itself and builds no surface model
    (a pipeline-only option such as ``surface`` runs photometric.pipeline.reconstruct): the
    imperfections and the verdict are those of the run with the adaptive fit, exactly."""
    spec = parse_spec({"max_depth_mm": 0.10})
    fast = inspect_part(small_lot["parts"] / "scratch_over", tmp_path / "fast", small_lot["rig"], spec)
    fitted = inspect_part(small_lot["parts"] / "scratch_over", tmp_path / "fit", small_lot["rig"], spec,
                          surface="fit")
    a, b = (json.loads((tmp_path / name / "result.json").read_text()) for name in ("fast", "fit"))
    assert a["imperfections"] and a["imperfections"] == b["imperfections"]
    assert {k: v for k, v in fast.items() if k != "timings_s"} == {k: v for k, v in fitted.items()
                                                                   if k != "timings_s"}
    assert "surface" not in fast["timings_s"]["stages"] and "surface" in fitted["timings_s"]["stages"]
    assert {"read", "nearfield", "defects"} <= set(fast["timings_s"]["stages"])
    assert a["measurement"] == b["measurement"]


def test_uncertainty_composes_the_stages_without_a_surface(small_lot, tmp_path):
    """guard_band with stated uncertainties: the part's stages (no surface, no mesh) give the imperfections,
    their U and the verdict of photometric.pipeline.reconstruct (a pipeline-only option sends it there)."""
    spec = parse_spec({"max_depth_mm": 0.10, "decision_rule": "guard_band"})
    unc = {"method": "linear", "light_position_tolerance_mm": 0.2}
    fast = inspect_part(small_lot["parts"] / "scratch_over", tmp_path / "fast", small_lot["rig"], spec,
                        uncertainty=unc)
    full = inspect_part(small_lot["parts"] / "scratch_over", tmp_path / "full", small_lot["rig"], spec,
                        uncertainty=unc, surface="coons")
    a, b = (json.loads((tmp_path / name / "result.json").read_text()) for name in ("fast", "full"))
    assert a["imperfections"] and a["max_depth_U_mm"] > 0
    for ra, rb in zip(a["imperfections"], b["imperfections"], strict=True):
        assert ra["verdict"] == rb["verdict"]
        for key, value in ra["values"].items():
            assert value["value"] == pytest.approx(rb["values"][key]["value"], rel=1e-9, abs=1e-12)
            assert value["U"] == (None if rb["values"][key]["U"] is None else pytest.approx(rb["values"][key]["U"],
                                                                                          rel=1e-6))
    assert a["verdict"] == b["verdict"] and a["measurement"]["uncertainty"] is not None
    assert "surface" not in fast["timings_s"]["stages"] and "surface" in full["timings_s"]["stages"]
    assert "uncertainty" in fast["timings_s"]["stages"]


def test_lights_are_validated_once_per_part(small_lot, tmp_path, monkeypatch):
    import photometric.lights

    calls = []
    original = photometric.lights.validate_lights

    def counted(*args, **kwargs):
        calls.append(1)
        return original(*args, **kwargs)

    load_rig(small_lot["rig"])  # the rig's own check happens when it is read, once per process
    for module in ("photometric.lights", "photometric.stereo", "photometric.stages", "photometric.nearfield"):
        mod = __import__(module, fromlist=["x"])
        if hasattr(mod, "validate_lights"):
            monkeypatch.setattr(mod, "validate_lights", counted)
    guard = parse_spec({"max_depth_mm": 0.10, "decision_rule": "guard_band"})
    inspect_part(small_lot["parts"] / "scratch_over", tmp_path / "o", small_lot["rig"], guard,
                 uncertainty={"light_position_tolerance_mm": 0.2})
    assert len(calls) <= 1


def test_bad_parts_write_nothing(small_lot, tmp_path):
    small = tmp_path / "small"
    for k in range(4):
        write_png(small / f"{k + 1:03d}.png", np.full((100, 120), 30000, np.uint16))
    with pytest.raises(ValueError, match="rig: calibrated for 224 x 224 px images, the images are 100 x 120 px"):
        inspect_part(small, tmp_path / "out_small", small_lot["rig"], small_lot["spec"])
    mixed = _copy_part(small_lot, "clean", tmp_path)
    write_png(mixed / "002.png", np.full((100, 120), 30000, np.uint16))
    with pytest.raises(ValueError, match=r"'002.png' is 100 x 120 px, the rig's images are 224 x 224 px"):
        inspect_part(mixed, tmp_path / "out_mixed", small_lot["rig"], small_lot["spec"])
    guard = parse_spec({"max_depth_mm": 0.1, "decision_rule": "guard_band"})
    with pytest.raises(ValueError, match="guard_band: imperfection 0 max_depth_mm has no expanded uncertainty"):
        inspect_part(small_lot["parts"] / "scratch_over", tmp_path / "out_guard", small_lot["rig"], guard)
    assert not any((tmp_path / n).exists() for n in ("out_small", "out_mixed", "out_guard"))


def test_uncompressed_16_bit_tiff_parts_measure_as_png(small_lot, tmp_path):
    """Industrial cameras write uncompressed 16-bit TIFF: the same pixels give the same result.json figures."""
    import cv2

    tif = tmp_path / "tif"
    tif.mkdir()
    names = []
    for png in sorted((small_lot["parts"] / "scratch_over").glob("[0-9]*.png")):
        img = cv2.imread(str(png), cv2.IMREAD_UNCHANGED)
        assert img.dtype == np.uint16
        cv2.imwrite(str(tif / png.with_suffix(".tif").name), img, [cv2.IMWRITE_TIFF_COMPRESSION, 1])
        names.append(png.with_suffix(".tif").name)
    (tif / "filenames.txt").write_text("\n".join(names) + "\n")
    spec = parse_spec({"max_depth_mm": 0.10})
    a = inspect_part(small_lot["parts"] / "scratch_over", tmp_path / "png_out", small_lot["rig"], spec)
    b = inspect_part(tif, tmp_path / "tif_out", small_lot["rig"], spec)
    assert {k: v for k, v in a.items() if k != "timings_s"} == {k: v for k, v in b.items() if k != "timings_s"}
    ra, rb = (json.loads((tmp_path / n / "result.json").read_text()) for n in ("png_out", "tif_out"))
    assert ra["imperfections"] == rb["imperfections"] and rb["input"][0].endswith("001.tif")
