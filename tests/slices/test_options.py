"""Reconstruction options: one home for every default, checked when they are made."""

from __future__ import annotations

import math

import pytest

from slices.caps import CAP_KINDS
from slices.options import ReadOptions, SurfaceOptions, split_options, surface_options
from slices.surface import CORRESPONDENCES, LATTICE_MODES, METHODS


def test_defaults():
    opts = SurfaceOptions()
    assert (opts.method, opts.n_rays, opts.caps, opts.lattice_factor) == ("blending", 64, "trend", 2.0)
    assert (opts.lattice_mode, opts.correspondence, opts.start_angle, opts.samples) == ("balanced", "seed", None, None)
    assert ReadOptions() == ReadOptions(None, None, None, False)


def test_every_choice_is_accepted():
    for method in METHODS:
        assert SurfaceOptions(method=method).method == method
    for caps in CAP_KINDS:
        assert SurfaceOptions(caps=caps).caps == caps
    for mode in LATTICE_MODES:
        assert SurfaceOptions(lattice_mode=mode).lattice_mode == mode
    for corr in CORRESPONDENCES:
        assert SurfaceOptions(correspondence=corr).correspondence == corr


@pytest.mark.parametrize(("field", "value", "message"), [
    ("method", "nurbs", "method"),
    ("caps", "round", "caps"),
    ("lattice_mode", "dense", "lattice_mode"),
    ("correspondence", "nearest", "correspondence"),
    ("n_rays", 2, "n_rays"),
    ("n_rays", 8.5, "n_rays"),
    ("lattice_factor", 0.5, "lattice_factor"),
    ("lattice_factor", math.inf, "lattice_factor"),
    ("start_angle", math.nan, "start_angle"),
    ("samples", 0, "samples"),
])
def test_bad_values_are_named(field, value, message):
    with pytest.raises(ValueError, match=message):
        SurfaceOptions(**{field: value})


def test_values_are_normalised():
    opts = SurfaceOptions(n_rays=32.0, lattice_factor=3, samples=2.0)
    assert type(opts.n_rays) is int and type(opts.lattice_factor) is float and type(opts.samples) is int


def test_surface_options_overrides_and_rejects_unknown_names():
    base = SurfaceOptions(caps="half")
    assert surface_options(base) is base
    assert surface_options(base, n_rays=16) == SurfaceOptions(caps="half", n_rays=16)
    with pytest.raises(ValueError, match="unknown"):
        surface_options(rays=16)


def test_split_options_sorts_reading_from_surface():
    read, surf = split_options({"hu_min": 100, "resample": True, "caps": "dome", "start_angle": 0.1})
    assert read == ReadOptions(hu_min=100, resample=True)
    assert surf == SurfaceOptions(caps="dome", start_angle=0.1)
    read, surf = split_options({}, ReadOptions(spacing="1,1,1"), SurfaceOptions(samples=3))
    assert read.spacing == "1,1,1" and surf.samples == 3
    with pytest.raises(ValueError, match=r"unknown \['lattice'\]"):
        split_options({"lattice": 2.0})


@pytest.mark.parametrize(("field", "value"), [("n_rays", "many"), ("n_rays", True), ("lattice_factor", "wide"),
                                              ("start_angle", "north"), ("samples", [2])])
def test_values_that_are_no_numbers_are_named(field, value):
    with pytest.raises(ValueError, match=f"{field}: "):
        SurfaceOptions(**{field: value})
