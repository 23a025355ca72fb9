"""Fault injection: interrupted, killed and concurrent writers, bad outputs, and the cases of issue 20.

A reconstruct command is run in a subprocess whose write stage is made to pause
half-way (a file-writing function of :mod:`workbench.runs` is wrapped to signal
"writing" and sleep); the test then sends SIGINT or SIGKILL, or starts a second
writer on the same ``--out``. Afterwards ``--out`` must hold the previous
complete result or nothing, never a mix.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import pytest

from workbench.cli import main
from workbench.runs.folder import COMPLETE_MARKER

# Run ``workbench ARGS`` with WRITER (module.function of workbench.runs) pausing after its first call.
# Ctrl-C as a user's terminal delivers it: a test run started in the background (a
# non-interactive shell's `cmd &`) passes SIGINT on ignored, so the writer restores it
PAUSING = textwrap.dedent("""
    import sys, time, importlib, signal
    signal.signal(signal.SIGINT, signal.default_int_handler)
    flag, module, func, *argv = sys.argv[1:]
    mod = importlib.import_module(module)
    real = getattr(mod, func)
    def pausing(*args, **kwargs):
        result = real(*args, **kwargs)
        open(flag, "w").close()
        time.sleep(120)
        return result
    setattr(mod, func, pausing)
    from workbench.cli import main
    sys.exit(main(argv))
""")

# the write stage of each command, and a function it calls after some files are written
WRITERS = {
    "photometric": ("workbench.runs.photometric", "write_png"),
    "slices": ("workbench.runs.slices", "save_body_patches"),
}


@pytest.fixture(scope="module")
def inputs(tmp_path_factory):
    """Small inputs for both reconstruct commands: a rendered triad folder and a contour file."""
    from datasets_synthetic.phantoms import make_phantom
    from datasets_synthetic.render import make_triad_folder

    base = tmp_path_factory.mktemp("inputs")
    make_triad_folder(base / "triad", scene="plate", size=48, noise=0.0, shadows="none", deviate=None,
                      albedo=0.8, pixel_size=0.2, seed=1)
    cs = make_phantom("ellipsoid", a=12.0, b=9.0, c=10.0).contours(2.0, n_points=32)
    (base / "contours.json").write_text(json.dumps({"units": "mm", "contours": [
        {"z": c["z"], "points": c["points"].tolist()} for c in cs]}))
    return {
        "photometric": ["photometric", "reconstruct", str(base / "triad"), "--step", "8"],
        "slices": ["slices", "reconstruct", str(base / "contours.json"), "--rays", "16", "--no-render"],
    }


def _state(out: Path) -> dict | None:
    """The files of a result folder with their bytes, or None when there is no folder."""
    if not out.exists():
        return None
    return {p.name: p.read_bytes() for p in sorted(out.iterdir())}


def _start_pausing(kind: str, argv: list[str], tmp_path: Path) -> tuple[subprocess.Popen, Path]:
    flag = tmp_path / f"writing-{time.monotonic_ns()}"
    module, func = WRITERS[kind]
    proc = subprocess.Popen([sys.executable, "-c", PAUSING, str(flag), module, func, *argv],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    deadline = time.monotonic() + 120
    while not flag.exists():
        if proc.poll() is not None:
            pytest.fail(f"writer ended before its write stage: {proc.communicate()}")
        if time.monotonic() > deadline:
            proc.kill()
            pytest.fail("writer never reached its write stage")
        time.sleep(0.05)
    return proc, flag


def _assert_no_leftovers_after_next_run(kind, argv, out):
    assert main(argv) == 0
    assert (out / COMPLETE_MARKER).is_file()
    assert sorted(p.name for p in out.parent.iterdir() if p.name.startswith(f".{out.name}")) == []


@pytest.mark.slow
@pytest.mark.parametrize("kind", ["photometric", "slices"])
@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGKILL], ids=["SIGINT", "SIGKILL"])
@pytest.mark.parametrize("before", [True, False], ids=["previous-result", "no-result"])
def test_interrupted_write_leaves_previous_result_or_nothing(inputs, tmp_path, kind, sig, before):
    out = tmp_path / "out"
    argv = [*inputs[kind], "--out", str(out)]
    if before:
        assert main(argv) == 0
    previous = _state(out)
    proc, _ = _start_pausing(kind, argv, tmp_path)
    # the writer is half-way through: --out is unchanged
    assert _state(out) == previous
    proc.send_signal(sig)
    proc.wait(timeout=60)
    assert proc.returncode == (130 if sig == signal.SIGINT else -signal.SIGKILL)
    assert _state(out) == previous
    if sig == signal.SIGINT:  # a clean exit removes its temporary folder and lock at once
        assert sorted(p.name for p in tmp_path.iterdir() if p.name.startswith(".out")) == []
    _assert_no_leftovers_after_next_run(kind, argv, out)


@pytest.mark.slow
@pytest.mark.parametrize("kind", ["photometric", "slices"])
def test_second_concurrent_writer_is_refused(inputs, tmp_path, kind, capsys):
    out = tmp_path / "out"
    argv = [*inputs[kind], "--out", str(out)]
    proc, _ = _start_pausing(kind, argv, tmp_path)
    try:
        assert main(argv) == 2
        err = capsys.readouterr().err.strip().splitlines()[-1]
        assert err.startswith("workbench: error: out_dir: ") and "is being written by another run" in err
        assert f"pid {proc.pid}" in err and not out.exists()
    finally:
        proc.send_signal(signal.SIGINT)
        proc.wait(timeout=60)
    assert not out.exists()
    _assert_no_leftovers_after_next_run(kind, argv, out)


@pytest.mark.parametrize("kind", ["photometric", "slices"])
def test_out_naming_a_file_is_one_clear_line(inputs, tmp_path, kind, capsys):
    target = tmp_path / "taken"
    target.write_text("mine")
    assert main([*inputs[kind], "--out", str(target)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "exists and is not a folder" in err and "Traceback" not in err
    assert target.read_text() == "mine" and sorted(p.name for p in tmp_path.iterdir()) == ["taken"]


@pytest.mark.parametrize("kind", ["photometric", "slices"])
def test_failed_run_creates_nothing(tmp_path, kind, capsys):
    out = tmp_path / "new" / "out"
    bad = tmp_path / "missing"
    argv = {"photometric": ["photometric", "reconstruct", str(bad)],
            "slices": ["slices", "reconstruct", str(bad / "c.json")]}[kind]
    assert main([*argv, "--out", str(out)]) == 2
    assert capsys.readouterr().err.count("\n") == 1
    assert list(tmp_path.iterdir()) == []


def test_out_holding_other_data_is_refused_and_kept(inputs, tmp_path, capsys):
    data = tmp_path / "data"
    data.mkdir()
    (data / "notes.txt").write_text("keep me")
    assert main([*inputs["slices"], "--out", str(data)]) == 2
    assert "not a result of this command (notes.txt)" in capsys.readouterr().err
    assert sorted(p.name for p in data.iterdir()) == ["notes.txt"]


def test_signal_free_rerun_replaces_a_result_whole(inputs, tmp_path):
    """A rerun with other options replaces every file (no stale render.png beside a --no-render result)."""
    out = tmp_path / "out"
    argv = [*inputs["slices"], "--out", str(out)]
    assert main([a for a in argv if a != "--no-render"]) == 0
    assert (out / "render.png").is_file()
    assert main(argv) == 0
    assert not (out / "render.png").exists() and (out / COMPLETE_MARKER).is_file()
    assert os.listdir(tmp_path) == ["out"]


REPO = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def module_cwd() -> Path:
    """The working directory module-scoped fixtures run in (before any test's own)."""
    return Path.cwd()


def test_fixtures_never_run_in_the_repository(module_cwd):
    """``make test`` once left an empty ``photometric_out/`` in the repository root: a fixture set up
    before the per-test working directory ran in the directory pytest started in."""
    assert REPO != module_cwd and REPO not in module_cwd.parents


def test_cli_runs_leave_the_repository_root_alone(inputs, tmp_path, monkeypatch, capsys):
    """The default ``--out`` (``photometric_out``) lands in the working directory, never in the repository."""
    before = sorted(p.name for p in REPO.iterdir())
    monkeypatch.chdir(tmp_path)
    assert main(inputs["photometric"]) == 0
    assert main(["photometric", "reconstruct", str(tmp_path / "missing")]) == 2
    assert main(["photometric", "reconstruct"]) == 2
    capsys.readouterr()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["photometric_out"]
    assert (tmp_path / "photometric_out" / COMPLETE_MARKER).is_file()
    assert sorted(p.name for p in REPO.iterdir()) == before
