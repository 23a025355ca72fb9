"""Run the ``Examples`` of every module of the project's packages: one test per module that has any.

The package trees are walked on disk (new modules are found without editing
this file; nothing is imported to collect the tests) and every module whose
source holds a ``>>>`` prompt is imported and run through :mod:`doctest`. A
prompt that doctest cannot find (outside a docstring) fails too, so an example
is never silently skipped. Examples run in the test's temporary working
directory (see ``tests/conftest.py``), so files they write land there.
"""

from __future__ import annotations

import doctest
import importlib
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
PACKAGES = ("surfaces", "photometric", "slices", "datasets_synthetic", "workbench")
FLAGS = doctest.ELLIPSIS | doctest.NORMALIZE_WHITESPACE


def modules_with_examples(root: Path = REPO, packages: tuple[str, ...] = PACKAGES) -> list[str]:
    """Dotted names of the modules below ``root/<package>`` whose source holds a ``>>>`` prompt.

    ``__main__`` modules are left out: importing them runs the program.
    """
    names = []
    for package in packages:
        for path in sorted((root / package).rglob("*.py")):
            if path.name == "__main__.py" or ">>>" not in path.read_text(encoding="utf-8"):
                continue
            parts = path.relative_to(root).with_suffix("").parts
            names.append(".".join(parts[:-1] if parts[-1] == "__init__" else parts))
    return names


MODULES = modules_with_examples()


def test_walk_finds_modules_in_subpackages(tmp_path):
    (tmp_path / "pkg" / "sub").mkdir(parents=True)
    (tmp_path / "pkg" / "__init__.py").write_text('"""\n>>> 1 + 1\n2\n"""\n')
    (tmp_path / "pkg" / "__main__.py").write_text('""">>> 1"""\n')
    (tmp_path / "pkg" / "plain.py").write_text('"""No examples."""\n')
    (tmp_path / "pkg" / "sub" / "deep.py").write_text('def f():\n    """\n    >>> f()\n    """\n')
    assert modules_with_examples(tmp_path, ("pkg",)) == ["pkg", "pkg.sub.deep"]
    assert {"workbench.cli", "workbench.report", "workbench.commands.common"} <= set(MODULES)


@pytest.mark.parametrize("name", MODULES)
def test_doctests(name):
    module = importlib.import_module(name)
    tests = [test for test in doctest.DocTestFinder().find(module) if test.examples]
    assert tests, f"{name}: its '>>>' prompts are not in a docstring doctest finds"
    runner = doctest.DocTestRunner(optionflags=FLAGS)
    report: list[str] = []
    for test in tests:
        runner.run(test, out=report.append)
    result = runner.summarize(verbose=False)
    assert result.failed == 0, "".join(report)
