"""Masks on the planning grid: orientation (RAS), the CT's grid (SimpleITK), and the contours' even-odd fill.

The reference fill is written here, independently of slices.mask: every ring filled with
skimage.draw.polygon at the pixel centres and the rings of a plane combined by XOR (even-odd).
"""

from __future__ import annotations

import numpy as np
import pytest

from slices.io import Contour, read_rtstruct, write_nifti_mask
from slices.mask import contour_mask, grid_on_contours, plan_grid
from surfaces.validate import InputError
from surfaces.voxelize import VoxelGrid, fill_polygons, grid_affine, lps_to_ras

nibabel = pytest.importorskip("nibabel")
draw = pytest.importorskip("skimage.draw")


def _raw_contours(path, name):
    """CLOSED_PLANAR contours of one ROI straight from pydicom (no cleaning, no checks)."""
    import pydicom

    ds = pydicom.dcmread(str(path))
    number = next(int(r.ROINumber) for r in ds.StructureSetROISequence if r.ROIName == name)
    out = []
    for rc in ds.ROIContourSequence:
        if int(rc.ReferencedROINumber) != number:
            continue
        for c in rc.get("ContourSequence", []):
            if str(c.get("ContourGeometricType", "")) == "CLOSED_PLANAR":
                xyz = np.asarray(c.ContourData, float).reshape(-1, 3)
                out.append((float(xyz[0, 2]), xyz[:, :2]))
    return out


def _reference_fill(raw, grid: VoxelGrid) -> np.ndarray:
    """Even-odd fill with skimage.draw.polygon on an axis-aligned grid (independent of slices.mask)."""
    sp, origin = np.diag(grid.affine)[:3], grid.affine[:3, 3]
    out = np.zeros(grid.shape, bool)
    for z, pts in raw:
        k = int(round((z - origin[2]) / sp[2]))
        if abs(origin[2] + k * sp[2] - z) > 0.1 * abs(sp[2]) or not 0 <= k < grid.shape[2]:
            continue
        i = (pts[:, 0] - origin[0]) / sp[0]
        j = (pts[:, 1] - origin[1]) / sp[1]
        ring = np.zeros(grid.shape[:2], bool)
        rr, cc = draw.polygon(i, j, shape=grid.shape[:2])
        ring[rr, cc] = True
        out[:, :, k] ^= ring
    return out


def _dice(a, b) -> float:
    a, b = np.asarray(a, bool), np.asarray(b, bool)
    return 2.0 * (a & b).sum() / (a.sum() + b.sum())


def test_fill_polygons_is_even_odd_at_pixel_centres():
    rng = np.random.default_rng(3)
    for _ in range(20):
        t = np.sort(rng.uniform(0, 2 * np.pi, 40))
        r = rng.uniform(5, 20, 40)
        ring = np.column_stack([25 + r * np.cos(t), 30 + r * np.sin(t)])
        hole = np.column_stack([25 + 3 * np.cos(t), 30 + 3 * np.sin(t)])
        ours = fill_polygons([ring, hole], (50, 60))
        ref = np.zeros((50, 60), bool)
        for p in (ring, hole):
            m = np.zeros((50, 60), bool)
            rr, cc = draw.polygon(p[:, 0], p[:, 1], shape=(50, 60))
            m[rr, cc] = True
            ref ^= m
        # the two differ only on centres that lie on an edge (measure zero here)
        assert (ours != ref).sum() <= 2, (ours != ref).sum()


def test_lps_affine_is_written_as_ras(tmp_path):
    affine = grid_affine([10.0, -20.0, 5.0], [0.5, 0.8, 2.0])
    mask = np.zeros((4, 5, 3), np.uint8)
    ras = write_nifti_mask(tmp_path / "m.nii.gz", mask, affine)
    img = nibabel.load(str(tmp_path / "m.nii.gz"))
    np.testing.assert_allclose(img.affine, ras)
    np.testing.assert_allclose(img.affine[:3, 3], [-10.0, 20.0, 5.0])  # LPS (10, -20, 5) is RAS (-10, 20, 5)
    assert nibabel.aff2axcodes(img.affine) == ("L", "P", "S")  # i runs to the patient's left, as in a CT
    assert int(img.header["qform_code"]) == 1 and int(img.header["sform_code"]) == 1
    np.testing.assert_allclose(lps_to_ras(ras), affine)


def test_a_left_sided_structure_lands_on_the_patients_left(tmp_path):
    # a disc at LPS x = +40 mm (patient's left), planes 0..6 mm
    t = np.linspace(0, 2 * np.pi, 64, endpoint=False)
    disc = np.column_stack([40 + 8 * np.cos(t), -5 + 8 * np.sin(t)])
    contours = [Contour(float(z), disc) for z in (0.0, 2.0, 4.0, 6.0)]
    grid = grid_on_contours(contours)
    mask, info = contour_mask(contours, grid)
    assert info["n_planes_on_contours"] == 4
    np.testing.assert_allclose(grid.planes[1:5], [0, 2, 4, 6])  # the planes are the contour planes
    ras = write_nifti_mask(tmp_path / "left.nii", mask, grid.affine)
    idx = np.argwhere(np.asarray(nibabel.load(str(tmp_path / "left.nii")).dataobj) > 0)
    world = np.column_stack([idx, np.ones(len(idx))]) @ ras[:3].T
    # RAS: +x is the patient's right, so the left lies at x < 0; +y anterior: LPS y = -5 is RAS y = +5
    assert world[:, 0].mean() == pytest.approx(-40.0, abs=0.3)
    assert world[:, 1].mean() == pytest.approx(5.0, abs=0.3)
    assert mask.sum() * np.prod(grid.spacing) == pytest.approx(np.pi * 64 * 2 * 4, rel=0.05)  # 1 mm pixels


def test_planes_between_contours_are_interpolated_and_end_slabs_are_half_a_spacing():
    # a cone: radius 10 at z = 0, 6 at z = 4 (planes 4 mm apart), on a 1 mm grid in z
    t = np.linspace(0, 2 * np.pi, 128, endpoint=False)
    ring = np.column_stack([np.cos(t), np.sin(t)])
    contours = [Contour(0.0, 10 * ring), Contour(4.0, 6 * ring)]
    grid = VoxelGrid(grid_affine([-12, -12, -3], [0.25, 0.25, 1.0]), (97, 97, 10))
    mask, info = contour_mask(contours, grid)
    assert info == {**info, "n_planes_on_contours": 2, "n_planes_interpolated": 3, "n_planes_end_slab": 2}
    area = mask.sum(axis=(0, 1)) * 0.0625
    z = grid.planes
    for k in np.flatnonzero((z > 0) & (z < 4)):
        r = 10 - z[k]  # the signed distances blend linearly: the radius does too
        assert area[k] == pytest.approx(np.pi * r * r, rel=0.03)
    # z = -1 and 5 are within half a spacing (2 mm) of an end plane; -2, -3 and 6 are not
    assert area[list(z).index(-1.0)] == area[list(z).index(0.0)] and area[list(z).index(-2.0)] == 0
    assert area[list(z).index(5.0)] == area[list(z).index(4.0)] and area[list(z).index(6.0)] == 0


def test_ibsi_mask_on_the_ct_grid_overlays_the_ct_and_matches_the_contours(shared_data, tmp_path):
    sitk = pytest.importorskip("SimpleITK")
    ct_dir, rs = shared_data / "ibsi_ct_phantom" / "ct", shared_data / "ibsi_ct_phantom" / "RS.dcm"
    grid, source, info = plan_grid(None, input_path=rs)
    assert source == "ct_series" and info["shape"] == [204, 201, 60]
    reader = sitk.ImageSeriesReader()
    reader.SetFileNames(reader.GetGDCMSeriesFileNames(str(ct_dir)))
    ct = reader.Execute()
    raw = _raw_contours(rs, "GTV-1")  # 8 of its contours pinch: read raw, the fill is even-odd anyway
    mask, counts = contour_mask([Contour(z, p) for z, p in raw], grid)
    assert counts["n_planes_on_contours"] == 26
    write_nifti_mask(tmp_path / "gtv.nii.gz", mask, grid.affine)
    m = sitk.ReadImage(str(tmp_path / "gtv.nii.gz"))
    assert m.GetSize() == ct.GetSize()
    np.testing.assert_allclose(m.GetOrigin(), ct.GetOrigin(), atol=1e-3)
    np.testing.assert_allclose(m.GetSpacing(), ct.GetSpacing(), atol=1e-4)
    np.testing.assert_allclose(m.GetDirection(), ct.GetDirection(), atol=1e-6)
    corner = (203, 200, 59)
    np.testing.assert_allclose(m.TransformIndexToPhysicalPoint(corner), ct.TransformIndexToPhysicalPoint(corner),
                               atol=1e-3)
    # the same voxels as an even-odd rasterisation of the contours; the GTV's voxels are soft tissue on the CT
    ref = _reference_fill(raw, grid)
    assert _dice(mask, ref) >= 0.99
    hu = sitk.GetArrayFromImage(ct).transpose(2, 1, 0)  # (z, y, x) -> (i, j, k)
    assert -200 < np.median(hu[mask > 0]) < 200
    assert mask.sum() * np.prod(grid.spacing) / 1000 == pytest.approx(358.7, rel=0.02)  # plastimatch, CT grid


@pytest.mark.slow
def test_every_breast_roi_matches_the_even_odd_fill(shared_data):
    rs = shared_data / "rtstruct_breast" / "rtss.dcm"
    grid_info = None
    for name in ("BODY", "Breast", "Heart", "Lt Lung", "Nodes", "Scar", "Tumor Bed", "Tumor Bed Block"):
        stack = read_rtstruct(rs, name)
        grid, source, grid_info = plan_grid(stack.contours, input_path=rs)
        assert source == "ct_series"
        mask, _ = contour_mask(stack.contours, grid)
        ref = _reference_fill(_raw_contours(rs, name), grid)
        assert _dice(mask, ref) >= 0.99, name
        if name == "Lt Lung":  # on the patient's left: LPS x > 0 (RAS x < 0)
            idx = np.argwhere(mask)
            assert (np.column_stack([idx, np.ones(len(idx))]) @ grid.affine[0]).mean() > 0
            # the slab count of the contour areas: 1995.18 cc by dicompyler-core (end planes half; ours whole)
            assert mask.sum() * np.prod(grid.spacing) / 1000 == pytest.approx(1995.18, rel=0.01)
    assert "one slice only" in grid_info["grid"]


def test_a_nifti_reference_image_gives_its_grid(shared_data, tmp_path):
    sitk = pytest.importorskip("SimpleITK")
    ct_dir, rs = shared_data / "ibsi_ct_phantom" / "ct", shared_data / "ibsi_ct_phantom" / "RS.dcm"
    reader = sitk.ImageSeriesReader()
    reader.SetFileNames(reader.GetGDCMSeriesFileNames(str(ct_dir)))
    sitk.WriteImage(reader.Execute(), str(tmp_path / "ct.nii.gz"))  # SimpleITK writes the RAS affine
    from_nifti, source, _ = plan_grid(None, reference_image=tmp_path / "ct.nii.gz")
    from_ct, _, _ = plan_grid(None, reference_image=ct_dir)
    assert source == "reference_image" and from_nifti.shape == from_ct.shape
    np.testing.assert_allclose(from_nifti.affine, from_ct.affine, atol=1e-4)
    with pytest.raises(InputError, match="give one grid"):
        plan_grid(None, reference_image=ct_dir, spacing="1,1,1")
    with pytest.raises(FileNotFoundError):
        plan_grid(None, reference_image=tmp_path / "missing.nii")
    assert plan_grid(None, input_path=rs)[1] == "ct_series"
