"""Run every benchmark, then gather their result tables into ``benchmarks/README.md``.

Run: ``make bench`` (or ``.venv/bin/python benchmarks/run_all.py [NAME ...]``, e.g.
``surfaces photometric`` to run only those). Each ``bench_<name>.py`` compares with
its peer in the same run and writes ``results/<name>.md``; this script runs them
one after another (they share the machine's two cores) and rebuilds the README
from all result files present.
"""

from __future__ import annotations

import subprocess
import sys
import time
from pathlib import Path

from surfaces.io import atomic_write_text

HERE = Path(__file__).resolve().parent
ORDER = ["surfaces", "bspline", "mesh_read", "photometric", "nearfield", "rig_capture", "calibration",
         "sphere_calibration", "glossy", "surface_fit", "errors", "uncertainty", "uncertainty_perspective", "texture",
         "slices", "ct_peers", "ct_volume", "render", "boolean", "batch", "inspect", "watch_kill", "memory"]

HEADER = """# Benchmarks

Every figure below was measured on this project's 2-core machine (no GPU) by the
command shown above its table; each benchmark runs the peer it is compared with
in the same run, so the ratios are like for like. `make bench` reruns them all
and rebuilds this page from `benchmarks/results/*.md`.
"""


def _names(argv: list[str]) -> list[str]:
    found = sorted(p.stem.removeprefix("bench_") for p in HERE.glob("bench_*.py"))
    wanted = argv or found
    unknown = sorted(set(wanted) - set(found))
    if unknown:
        raise SystemExit(f"run_all: no benchmark named {', '.join(unknown)} (have: {', '.join(found)})")
    return sorted(wanted, key=lambda n: ORDER.index(n) if n in ORDER else len(ORDER))


def _nest(text: str) -> str:
    """Demote a result file's headings so that its title is a level-2 heading of the README."""
    if not text.startswith("# "):
        return text
    return "\n".join("#" + line if line.startswith("#") else line for line in text.splitlines())


def rebuild_readme() -> Path:
    """Write ``benchmarks/README.md`` from the result files, in a fixed order."""
    results = {p.stem: _nest(p.read_text().strip()) for p in (HERE / "results").glob("*.md")}
    ordered = sorted(results, key=lambda n: ORDER.index(n) if n in ORDER else len(ORDER))
    text = HEADER + "\n" + "\n\n".join(results[n] for n in ordered) + "\n"
    return atomic_write_text(HERE / "README.md", text)


def main(argv: list[str]) -> int:
    failed = []
    for name in _names(argv):
        print(f"== bench_{name}.py", flush=True)
        t0 = time.perf_counter()
        code = subprocess.call([sys.executable, str(HERE / f"bench_{name}.py")])
        print(f"== bench_{name}.py finished in {time.perf_counter() - t0:.1f} s (exit {code})", flush=True)
        if code:
            failed.append(name)
    print(f"wrote {rebuild_readme()}")
    if failed:
        print(f"failed: {', '.join(failed)}", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
