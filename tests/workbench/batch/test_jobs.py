"""Tests of :mod:`workbench.batch.jobs`: the job record and its kinds."""

from __future__ import annotations

import dataclasses

import pytest

from workbench.batch import KINDS, Job
from workbench.batch.jobs import check_kind


def test_job_is_frozen_with_independent_defaults():
    a, b = Job("a", "slices", "/a"), Job("b", "slices", "/b")
    assert a.options == {} and a.options is not b.options and a.roi is None
    with pytest.raises(dataclasses.FrozenInstanceError):
        a.id = "c"


@pytest.mark.parametrize(
    ("source", "line"),
    [("/data/k.json", "/data/k.json"), (("/t/1.png", "/t/2.png"), "/t/1.png;/t/2.png")],
)
def test_describe_is_one_line(source, line):
    assert Job("j", "photometric", source).describe() == line


def test_check_kind():
    assert [check_kind(k) for k in KINDS] == ["photometric", "slices"]
    for bad in ("", "Slices", "ct"):
        with pytest.raises(ValueError, match=f"kind: expected one of photometric, slices, got {bad!r}"):
            check_kind(bad)
