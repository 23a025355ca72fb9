"""DICOM writers for CT phantoms: a CT image series and an RT Structure Set referencing it.

Both follow the layout of real planning-system exports (the structure set
mirrors ``shared/data/rtstruct_breast/rtss.dcm``) and carry proper file meta
information, so ``pydicom.dcmread`` and other DICOM tools read them without
``force=True``. Patient coordinates equal the phantom's millimetre coordinates;
image rows run along +y and columns along +x (ImageOrientationPatient
``1\\0\\0\\0\\1\\0``), ImagePositionPatient is the centre of the first pixel.
UIDs are derived from the seed, so a rerun gives identical files.
"""

from __future__ import annotations

import io
import os
from pathlib import Path

import numpy as np

from datasets_synthetic.io import ensure_dir
from surfaces.io import atomic_write_bytes
from surfaces.validate import as_array, InputError, positive

CT_IMAGE_STORAGE = "1.2.840.10008.5.1.4.1.1.2"
RT_STRUCTURE_SET_STORAGE = "1.2.840.10008.5.1.4.1.1.481.3"
# what the reference structure set cites as its study's SOP class
DETACHED_STUDY_MANAGEMENT = "1.2.840.10008.3.1.2.3.2"


def _ds(value: float) -> str:
    """Most precise DICOM decimal string (16 characters at most) for a number."""
    from pydicom.valuerep import format_number_as_ds

    short = repr(float(value))
    return short if len(short) <= 16 and "e" not in short else format_number_as_ds(float(value))


def _uid(*parts) -> str:
    from pydicom.uid import generate_uid

    return generate_uid(entropy_srcs=[str(p) for p in parts])


def _common(ds, modality: str, study_uid: str, seed: int) -> None:
    ds.SpecificCharacterSet = "ISO_IR 100"
    ds.InstanceCreationDate = "20260101"
    ds.InstanceCreationTime = "000000"
    ds.StudyDate = "20260101"
    ds.StudyTime = "000000"
    ds.AccessionNumber = ""
    ds.Modality = modality
    ds.Manufacturer = "surface-workbench datasets_synthetic"
    ds.ReferringPhysicianName = ""
    ds.PatientName = "Synthetic^Phantom"
    ds.PatientID = f"SYNTH{int(seed)}"
    ds.PatientBirthDate = ""
    ds.PatientSex = "O"
    ds.StudyInstanceUID = study_uid
    ds.StudyID = "1"


def _save(path: Path, ds, sop_class: str) -> None:
    from pydicom import dcmwrite
    from pydicom.dataset import FileMetaDataset
    from pydicom.uid import PYDICOM_IMPLEMENTATION_UID, ExplicitVRLittleEndian

    meta = FileMetaDataset()
    meta.MediaStorageSOPClassUID = sop_class
    meta.MediaStorageSOPInstanceUID = ds.SOPInstanceUID
    meta.TransferSyntaxUID = ExplicitVRLittleEndian
    meta.ImplementationClassUID = PYDICOM_IMPLEMENTATION_UID
    ds.file_meta = meta
    buf = io.BytesIO()
    dcmwrite(buf, ds, enforce_file_format=True)
    atomic_write_bytes(path, buf.getvalue())


def write_ct_series(
    out_dir: str | os.PathLike,
    phantom,
    spacing: float,
    pixel: float,
    offset_mm: float = 0.0,
    seed: int = 0,
    margin_mm: float = 5.0,
    extra_slices: int = 2,
    hu_inside: float = 40.0,
    hu_outside: float = -1000.0,
    noise_hu: float = 0.0,
    supersample: int = 3,
    progress: bool = False,
) -> dict:
    """Write a CT series of a phantom, one file per slice (``slice_0001.dcm``, ...).

    Slices lie on the phantom's contour planes (:meth:`Phantom.plane_positions`)
    plus ``extra_slices`` empty planes at each end. A pixel's value is
    ``hu_outside + f (hu_inside - hu_outside)`` with ``f`` the fraction of its
    ``supersample^2`` in-plane sub-samples inside the solid (partial volume in
    the slice plane), plus optional Gaussian noise; stored as unsigned 16-bit
    ``HU + 1024`` with RescaleSlope 1 and RescaleIntercept -1024.

    Parameters
    ----------
    out_dir : str or path-like
        Output folder (created when missing).
    phantom : Phantom
        The solid (:mod:`datasets_synthetic.phantoms`).
    spacing : float
        Slice spacing = SliceThickness, mm.
    pixel : float
        Pixel size (both directions), mm.
    offset_mm : float
        Shift of the slice grid (as for the contours).
    seed : int
        Seed of the UIDs and the noise.
    margin_mm : float
        Empty border around the solid's bounding box, mm.
    extra_slices : int
        Empty slices added beyond each end.
    hu_inside, hu_outside : float
        Hounsfield units inside and outside.
    noise_hu : float
        Standard deviation of Gaussian noise, HU.
    supersample : int
        In-plane sub-samples per pixel side.
    progress : bool
        Show a tqdm progress bar (command line only).

    Returns
    -------
    dict
        ``study_uid, series_uid, frame_of_reference_uid, rows, columns, pixel_mm,
        spacing_mm, origin_mm`` (x, y of the first pixel's centre), ``n_slices``,
        ``rescale_intercept``, ``rescale_slope`` and ``slices``: a list of
        ``{"z", "sop_instance_uid", "file"}`` in increasing z.
    """
    from pydicom.dataset import Dataset
    from tqdm import tqdm

    out = ensure_dir(out_dir)
    spacing = positive(spacing, "spacing")
    pixel = positive(pixel, "pixel")
    margin = positive(margin_mm, "margin_mm", allow_zero=True)
    noise_hu = positive(noise_hu, "noise_hu", allow_zero=True)
    if int(supersample) != supersample or supersample < 1:
        raise InputError(f"supersample: expected a whole number >= 1, got {supersample!r}")
    if int(extra_slices) != extra_slices or extra_slices < 0:
        raise InputError(f"extra_slices: expected a whole number >= 0, got {extra_slices!r}")
    if not (-1024.0 <= hu_outside <= 64000.0 and -1024.0 <= hu_inside <= 64000.0):
        raise InputError("hu_inside, hu_outside: must lie in [-1024, 64000] to fit the stored range")
    planes = phantom.plane_positions(spacing, offset_mm)
    k = int(extra_slices)
    zs = np.concatenate([planes[0] - spacing * np.arange(k, 0, -1), planes,
                         planes[-1] + spacing * np.arange(1, k + 1)])
    lower, upper = phantom.bounds
    # whole multiples of the pixel size, rounded so that the decimal strings stay short
    x0 = round(float(np.floor((lower[0] - margin) / pixel) * pixel), 9)
    y0 = round(float(np.floor((lower[1] - margin) / pixel) * pixel), 9)
    cols = int(np.ceil((upper[0] + margin - x0) / pixel)) + 1
    rows = int(np.ceil((upper[1] + margin - y0) / pixel)) + 1
    ss = int(supersample)
    sub = (np.arange(ss) + 0.5) / ss - 0.5
    gx = (x0 + (np.arange(cols)[:, None] + sub[None, :]) * pixel).ravel()
    gy = (y0 + (np.arange(rows)[:, None] + sub[None, :]) * pixel).ravel()
    yy, xx = np.meshgrid(gy, gx, indexing="ij")
    rng = np.random.default_rng(seed)
    study = _uid("study", seed, phantom.name)
    series = _uid("series", seed, phantom.name, spacing, pixel)
    frame = _uid("frame", seed, phantom.name)
    slices = []
    for i, z in enumerate(tqdm(zs, desc="CT slices", unit="slice", disable=not progress)):
        pts = np.column_stack([xx.ravel(), yy.ravel(), np.full(xx.size, z)])
        frac = phantom.inside(pts).reshape(rows, ss, cols, ss).mean(axis=(1, 3))
        hu = hu_outside + frac * (hu_inside - hu_outside)
        if noise_hu > 0:
            hu = hu + rng.normal(0.0, noise_hu, hu.shape)
        stored = np.clip(np.round(hu + 1024.0), 0, 65535).astype(np.uint16)
        sop = _uid("ct", seed, phantom.name, spacing, pixel, i)
        ds = Dataset()
        _common(ds, "CT", study, seed)
        ds.ImageType = ["ORIGINAL", "PRIMARY", "AXIAL"]
        ds.SOPClassUID = CT_IMAGE_STORAGE
        ds.SOPInstanceUID = sop
        ds.SeriesDate = ds.ContentDate = "20260101"
        ds.SeriesTime = ds.ContentTime = "000000"
        ds.SeriesDescription = f"synthetic {phantom.name} phantom"
        ds.SliceThickness = _ds(spacing)
        ds.SpacingBetweenSlices = _ds(spacing)
        ds.KVP = "120"
        ds.PatientPosition = "HFS"
        ds.SeriesInstanceUID = series
        ds.SeriesNumber = "1"
        ds.AcquisitionNumber = "1"
        ds.InstanceNumber = str(i + 1)
        ds.ImagePositionPatient = [_ds(x0), _ds(y0), _ds(z)]
        ds.ImageOrientationPatient = ["1", "0", "0", "0", "1", "0"]
        ds.FrameOfReferenceUID = frame
        ds.PositionReferenceIndicator = ""
        ds.SliceLocation = _ds(z)
        ds.SamplesPerPixel = 1
        ds.PhotometricInterpretation = "MONOCHROME2"
        ds.Rows = rows
        ds.Columns = cols
        ds.PixelSpacing = [_ds(pixel), _ds(pixel)]
        ds.BitsAllocated = 16
        ds.BitsStored = 16
        ds.HighBit = 15
        ds.PixelRepresentation = 0
        ds.WindowCenter = "40"
        ds.WindowWidth = "400"
        ds.RescaleIntercept = "-1024"
        ds.RescaleSlope = "1"
        ds.RescaleType = "HU"
        ds.PixelData = stored.tobytes()
        name = f"slice_{i + 1:04d}.dcm"
        _save(out / name, ds, CT_IMAGE_STORAGE)
        slices.append({"z": float(z), "sop_instance_uid": sop, "file": name})
    return {
        "study_uid": study,
        "series_uid": series,
        "frame_of_reference_uid": frame,
        "rows": rows,
        "columns": cols,
        "pixel_mm": pixel,
        "spacing_mm": spacing,
        "origin_mm": [float(x0), float(y0)],
        "n_slices": len(slices),
        "hu_inside": float(hu_inside),
        "hu_outside": float(hu_outside),
        "rescale_intercept": -1024.0,
        "rescale_slope": 1.0,
        "slices": slices,
    }


def write_rtstruct(
    path: str | os.PathLike,
    contours: list[dict],
    series: dict,
    roi_name: str = "phantom",
    seed: int = 0,
    color: tuple[int, int, int] = (255, 128, 0),
) -> dict:
    """Write an RT Structure Set with one ROI of CLOSED_PLANAR contours referencing a CT series.

    Parameters
    ----------
    path : str or path-like
        Output file (``rtstruct.dcm``).
    contours : list of dict
        ``{"z": mm, "points": (K, 2) mm}`` entries (:meth:`Phantom.contours`); each z must
        be one of the series' slice positions (to 1e-6 mm).
    series : dict
        What :func:`write_ct_series` returned (UIDs and slice positions).
    roi_name : str
        ROI name.
    seed : int
        Seed of the structure set's own UIDs.
    color : (int, int, int)
        ROIDisplayColor.

    Returns
    -------
    dict
        ``sop_instance_uid``, ``n_contours`` and ``roi_name``.
    """
    from pydicom.dataset import Dataset
    from pydicom.sequence import Sequence

    if not contours:
        raise InputError("contours: the list is empty")
    slice_z = np.array([s["z"] for s in series["slices"]])
    slice_uid = [s["sop_instance_uid"] for s in series["slices"]]

    ds = Dataset()
    _common(ds, "RTSTRUCT", series["study_uid"], seed)
    sop = _uid("rtstruct", seed, series["series_uid"], roi_name)
    ds.SOPClassUID = RT_STRUCTURE_SET_STORAGE
    ds.SOPInstanceUID = sop
    ds.SeriesDescription = "RT Structure Set"
    ds.SeriesInstanceUID = _uid("rtstruct-series", seed, series["series_uid"])
    ds.SeriesNumber = "2"
    ds.InstanceNumber = "1"
    ds.StructureSetLabel = "SYNTH"
    ds.StructureSetDate = "20260101"
    ds.StructureSetTime = "000000"

    def image_ref(uid: str) -> Dataset:
        item = Dataset()
        item.ReferencedSOPClassUID = CT_IMAGE_STORAGE
        item.ReferencedSOPInstanceUID = uid
        return item

    ref_series = Dataset()
    ref_series.SeriesInstanceUID = series["series_uid"]
    ref_series.ContourImageSequence = Sequence([image_ref(u) for u in slice_uid])
    ref_study = Dataset()
    ref_study.ReferencedSOPClassUID = DETACHED_STUDY_MANAGEMENT
    ref_study.ReferencedSOPInstanceUID = series["study_uid"]
    ref_study.RTReferencedSeriesSequence = Sequence([ref_series])
    ref_frame = Dataset()
    ref_frame.FrameOfReferenceUID = series["frame_of_reference_uid"]
    ref_frame.RTReferencedStudySequence = Sequence([ref_study])
    ds.ReferencedFrameOfReferenceSequence = Sequence([ref_frame])

    roi = Dataset()
    roi.ROINumber = "1"
    roi.ReferencedFrameOfReferenceUID = series["frame_of_reference_uid"]
    roi.ROIName = roi_name
    roi.ROIGenerationAlgorithm = "AUTOMATIC"
    ds.StructureSetROISequence = Sequence([roi])

    items = []
    for n, c in enumerate(contours):
        pts = as_array(c.get("points"), f"contours[{n}]['points']", shape=(None, 2))
        if len(pts) < 3:
            raise InputError(f"contours[{n}]: a closed contour needs at least 3 points, got {len(pts)}")
        z = float(c["z"])
        j = int(np.argmin(np.abs(slice_z - z)))
        if abs(slice_z[j] - z) > 1e-6:
            raise InputError(f"contours[{n}]: z = {z} mm matches no CT slice")
        item = Dataset()
        item.ContourImageSequence = Sequence([image_ref(slice_uid[j])])
        item.ContourGeometricType = "CLOSED_PLANAR"
        item.NumberOfContourPoints = str(len(pts))
        xyz = np.column_stack([pts, np.full(len(pts), z)]).ravel()
        item.ContourData = [_ds(v) for v in xyz]
        items.append(item)
    roi_contour = Dataset()
    roi_contour.ROIDisplayColor = [str(int(v)) for v in color]
    roi_contour.ContourSequence = Sequence(items)
    roi_contour.ReferencedROINumber = "1"
    ds.ROIContourSequence = Sequence([roi_contour])

    obs = Dataset()
    obs.ObservationNumber = "1"
    obs.ReferencedROINumber = "1"
    obs.ROIObservationLabel = roi_name
    obs.RTROIInterpretedType = "ORGAN"
    obs.ROIInterpreter = ""
    ds.RTROIObservationsSequence = Sequence([obs])
    ds.ApprovalStatus = "UNAPPROVED"

    _save(Path(path), ds, RT_STRUCTURE_SET_STORAGE)
    return {"sop_instance_uid": sop, "n_contours": len(items), "roi_name": roi_name}
