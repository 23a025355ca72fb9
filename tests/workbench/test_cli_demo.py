"""Tests of ``workbench demo``'s options (the demo's own run is tested in ``test_demo.py``)."""

from __future__ import annotations

from workbench.cli import build_parser
from workbench.commands.demo import run


def test_defaults_and_options():
    args = build_parser().parse_args(["demo"])
    assert (args.out, args.quick, args.shared_data, args.func) == ("demo_out", False, None, run)
    args = build_parser().parse_args(["demo", "--out", "d", "--quick", "--shared-data", "/data"])
    assert (args.out, args.quick, args.shared_data) == ("d", True, "/data")
