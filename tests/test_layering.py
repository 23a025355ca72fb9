"""The layering of the packages, checked on their source (``ast``; nothing is imported).

The rules of DESIGN.md and STYLE.md:

* ``surfaces`` imports no other package of the workbench;
* ``photometric`` and ``slices`` never import each other;
* the library packages (``surfaces``, ``photometric``, ``slices``, ``datasets_synthetic``)
  never import ``workbench`` or matplotlib, nor ``datasets_synthetic`` (except itself);
* no ``_private`` name crosses a package: no ``from pkg.mod import _name``, no
  ``import pkg._mod``, no ``mod._name`` or ``Class._name`` on a module or class imported
  from another package;
* the tests of the library packages do not run the command line (those live in
  ``tests/workbench``).

Every import counts, the ones inside functions too (a lazy import is still a dependency).
"""

from __future__ import annotations

import ast
import functools
from dataclasses import dataclass
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
PACKAGES = ("surfaces", "photometric", "slices", "datasets_synthetic", "workbench")
LIBRARY = ("surfaces", "photometric", "slices", "datasets_synthetic")
#: Known breaches, each with its reason; the test fails when one is no longer needed, so the list only shrinks.
KNOWN = {
    ("surfaces/colormap.py", "matplotlib"): "colour-map tables (matplotlib.colormaps) and the colour bar's tick "
    "values (MaxNLocator) for the renderer and PLY colours; imported lazily inside the two functions; "
    "to move onto a colour-map table of our own (not done in issue 30)",
}


@dataclass(frozen=True)
class Use:
    """One import (or private attribute use) found in a file."""

    path: str
    line: int
    module: str  # the imported module, dotted
    name: str  # the imported name ("" for ``import module``), or the private attribute used

    def __str__(self) -> str:
        return f"{self.path}:{self.line}: {self.module}{'.' + self.name if self.name else ''}"


def _top(module: str) -> str:
    return module.split(".")[0]


def _private(name: str) -> bool:
    return name.startswith("_") and not name.startswith("__")


def _package_of(path: Path, root: Path) -> str | None:
    """The package a file belongs to: its own for package code, ``tests/<package>/...`` for tests."""
    parts = path.relative_to(root).parts
    if parts[0] == "tests":
        parts = parts[1:]
    return parts[0] if parts and parts[0] in PACKAGES else None


def uses(path: Path, root: Path = REPO) -> list[Use]:
    """Every import in ``path``, and every private attribute taken from a name another package gave.

    Parameters
    ----------
    path : Path
        A Python source file below ``root``.
    root : Path
        The repository.

    Returns
    -------
    list of Use
        Imports (``name`` empty for ``import module``) and ``alias._name`` uses, where
        ``alias`` is bound by an import from a workbench package other than the file's own.
    """
    return list(_uses(path, root))


@functools.cache
def _uses(path: Path, root: Path) -> tuple[Use, ...]:
    """:func:`uses`, each file parsed once."""
    rel = str(path.relative_to(root))
    tree = ast.parse(path.read_text(encoding="utf-8"), filename=rel)
    own = _package_of(path, root)
    found: list[Use] = []
    foreign: dict[str, str] = {}  # local name -> the dotted thing it stands for, from another package
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            for alias in node.names:
                found.append(Use(rel, node.lineno, alias.name, ""))
                if _top(alias.name) in PACKAGES and _top(alias.name) != own:
                    # ``import a.b`` binds ``a``; ``import a.b as c`` binds ``c`` to ``a.b``
                    local, target = (alias.asname, alias.name) if alias.asname else (_top(alias.name), _top(alias.name))
                    foreign[local] = target
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            for alias in node.names:
                found.append(Use(rel, node.lineno, node.module, alias.name))
                if _top(node.module) in PACKAGES and _top(node.module) != own:
                    foreign[alias.asname or alias.name] = f"{node.module}.{alias.name}"
    for node in ast.walk(tree):
        if isinstance(node, ast.Attribute) and _private(node.attr):
            chain, base = [node.attr], node.value
            while isinstance(base, ast.Attribute):  # surfaces.blending._name
                chain.append(base.attr)
                base = base.value
            if isinstance(base, ast.Name) and base.id in foreign:
                found.append(Use(rel, node.lineno, ".".join([foreign[base.id], *reversed(chain[1:])]), node.attr))
    return tuple(found)


def _files(*folders: str, root: Path = REPO) -> list[Path]:
    return sorted(p for folder in folders for p in (root / folder).rglob("*.py"))


def _imports_of(package: str) -> list[Use]:
    return [use for path in _files(package) for use in uses(path)]


@pytest.mark.parametrize(
    ("package", "forbidden"),
    [
        ("surfaces", {"photometric", "slices", "datasets_synthetic", "workbench"}),
        ("photometric", {"slices", "datasets_synthetic", "workbench", "matplotlib"}),
        ("slices", {"photometric", "datasets_synthetic", "workbench", "matplotlib"}),
        ("datasets_synthetic", {"workbench", "matplotlib"}),
    ],
)
def test_library_packages_import_only_what_they_may(package, forbidden):
    if package == "surfaces":
        forbidden = forbidden | {"matplotlib"}
    found = [use for use in _imports_of(package) if _top(use.module) in forbidden]
    bad = [str(use) for use in found if (use.path, _top(use.module)) not in KNOWN]
    assert not bad, f"{package} imports what it must not:\n" + "\n".join(bad)
    known = {key for key in KNOWN if key[0].startswith(f"{package}/")}
    assert known <= {(use.path, _top(use.module)) for use in found}, "a known breach is gone: drop it from KNOWN"


def cross_package_private_uses(*folders: str, root: Path = REPO) -> list[Use]:
    """Private names (``_name`` or a ``_module``) that a file takes from another workbench package.

    Parameters
    ----------
    *folders : str
        Folders below ``root`` to scan.
    root : Path
        The repository.

    Returns
    -------
    list of Use
    """
    bad = []
    for path in _files(*folders, root=root):
        own = _package_of(path, root)
        for use in uses(path, root):
            if _top(use.module) not in PACKAGES or _top(use.module) == own:
                continue
            if _private(use.name) or any(_private(part) for part in use.module.split(".")):
                bad.append(use)
    return bad


def test_no_private_name_crosses_a_package():
    """0 private names used across packages (issue 30): other packages' kernels have public names."""
    bad = cross_package_private_uses(*PACKAGES)
    assert not bad, "private names used across packages:\n" + "\n".join(map(str, bad))


def test_the_tests_of_a_package_use_no_other_package_s_private_names():
    bad = cross_package_private_uses(*(f"tests/{package}" for package in PACKAGES))
    assert not bad, "private names used across packages:\n" + "\n".join(map(str, bad))


def test_tests_of_the_library_packages_do_not_run_the_command_line():
    """The CLI's tests live in tests/workbench; a lower package's tests test the library."""
    bad = [str(use) for package in LIBRARY for path in _files(f"tests/{package}")
           for use in uses(path) if _top(use.module) == "workbench"]
    assert not bad, "tests of library packages import workbench:\n" + "\n".join(bad)


def test_the_scan_finds_what_it_looks_for(tmp_path):
    """The checks can fail: a file with every kind of forbidden use is caught."""
    (tmp_path / "slices").mkdir()
    (tmp_path / "slices" / "bad.py").write_text(
        "import photometric\n"
        "import surfaces.blending as B\n"
        "from surfaces import mesh\n"
        "from surfaces.mesh import TriangleMesh, _hidden\n"
        "from surfaces._kernels import fast\n"
        "from slices.io import _existing\n"
        "def f():\n"
        "    import workbench.cli\n"
        "    return B._blend, mesh._weld, TriangleMesh._trusted, surfaces_like._x\n"
    )
    found = {str(use).split(": ", 1)[1] for use in uses(tmp_path / "slices" / "bad.py", tmp_path)}
    assert {"photometric", "workbench.cli", "surfaces.blending._blend", "surfaces.mesh._weld",
            "surfaces.mesh.TriangleMesh._trusted"} <= found
    private = {str(use).split(": ", 1)[1] for use in cross_package_private_uses("slices", root=tmp_path)}
    assert private == {"surfaces.mesh._hidden", "surfaces._kernels.fast", "surfaces.blending._blend",
                       "surfaces.mesh._weld", "surfaces.mesh.TriangleMesh._trusted"}
