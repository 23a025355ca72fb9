"""Every demo figure's data beside its PNG, and the redrawing of all figures from a demo folder.

Each figure of the demo is drawn by a *drawer*: a function of this module's
registry, called as ``drawer(source, **params, **arrays)``, that returns the RGB
picture. The demo saves what the drawer needs beside the PNG:

* ``figures/<name>.json``: the drawer's name, the caption, the command and the
  JSON parameters (numbers, labels, and paths of the run's own files, relative
  to the demo folder, or ``shared:<path>`` inside the real-data folder);
* ``figures/<name>.npz``: the arrays computed for the figure alone (small maps,
  per-vertex values), read back with ``allow_pickle=False``.

The demo draws every figure *from the saved data*, so :func:`redraw` (``workbench
demo --figures-only DIR``) gives the same pictures, and the report can be
redrawn after a change of the pictures without running the pipelines again.
"""

from __future__ import annotations

import base64
import json
import os
import re
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from surfaces.validate import InputError

#: drawer name -> function ``(source, **data) -> (H, W, 3) uint8``
DRAWERS: dict[str, Callable[..., np.ndarray]] = {}
#: prefix of a parameter path inside the real-data folder
SHARED = "shared:"


def drawer(function: Callable[..., np.ndarray]) -> Callable[..., np.ndarray]:
    """Register ``function`` as a figure drawer under ``<module>.<name>`` (a decorator)."""
    DRAWERS[f"{function.__module__.rsplit('.', 1)[-1]}.{function.__name__}"] = function
    return function


def drawer_name(function: Callable[..., np.ndarray]) -> str:
    """The registry name of a drawer (it must have been registered with :func:`drawer`)."""
    name = f"{function.__module__.rsplit('.', 1)[-1]}.{function.__name__}"
    if DRAWERS.get(name) is not function:
        raise InputError(f"draw: {function.__name__} is not a registered figure drawer")
    return name


@dataclass(frozen=True)
class Source:
    """Where a drawer finds its files: the demo folder and the real-data folder.

    Attributes
    ----------
    root : pathlib.Path
        The demo folder (``report.html``'s folder).
    shared : pathlib.Path
        The real-data folder.
    """

    root: Path
    shared: Path

    def path(self, ref: str) -> Path:
        """A parameter path: relative to :attr:`root`, or ``shared:<path>`` inside :attr:`shared`.

        Parameters
        ----------
        ref : str
            The saved reference.

        Returns
        -------
        pathlib.Path
        """
        if ref.startswith(SHARED):
            return self.shared / ref[len(SHARED):]
        return self.root / ref


def save(folder: Path, name: str, draw: Callable[..., np.ndarray], caption: str, command: str,
         params: dict | None = None, arrays: dict | None = None) -> None:
    """Write a figure's data: ``figures/<name>.json`` and, with arrays, ``figures/<name>.npz``.

    Parameters
    ----------
    folder : pathlib.Path
        The demo folder.
    name : str
        Figure name (the PNG's stem).
    draw : callable
        A registered drawer.
    caption, command : str
        As shown in the report.
    params : dict, optional
        JSON-serialisable keyword arguments of the drawer.
    arrays : dict, optional
        Array keyword arguments of the drawer (saved compressed; floats as float32).
    """
    from surfaces.io import atomic_path, write_json

    figures = folder / "figures"
    figures.mkdir(parents=True, exist_ok=True)
    arrays = {k: np.asarray(v) for k, v in (arrays or {}).items()}
    arrays = {k: v.astype(np.float32) if v.dtype == np.float64 else v for k, v in arrays.items()}
    npz = figures / f"{name}.npz"
    if arrays:
        with atomic_path(npz) as tmp, open(tmp, "wb") as fh:
            np.savez_compressed(fh, **arrays)
    elif npz.exists():
        npz.unlink()
    write_json(figures / f"{name}.json", {"draw": drawer_name(draw), "caption": caption, "command": command,
                                          "params": params or {}, "arrays": sorted(arrays)})


def draw(source: Source, name: str) -> np.ndarray:
    """Draw one saved figure from its data.

    Parameters
    ----------
    source : Source
        The demo and real-data folders.
    name : str
        Figure name.

    Returns
    -------
    (H, W, 3) uint8
    """
    _register_all()
    spec_path = source.root / "figures" / f"{name}.json"
    if not spec_path.is_file():
        raise FileNotFoundError(f"{spec_path}: no saved data for figure {name!r}")
    spec = json.loads(spec_path.read_text())
    function = DRAWERS.get(spec.get("draw"))
    if function is None:
        raise InputError(f"{spec_path}: unknown drawer {spec.get('draw')!r}")
    arrays = {}
    if spec.get("arrays"):
        with np.load(source.root / "figures" / f"{name}.npz", allow_pickle=False) as data:
            arrays = {k: data[k] for k in spec["arrays"]}
    return function(source, **spec["params"], **arrays)


def redraw(folder: str | os.PathLike, shared: str | os.PathLike | None = None) -> dict:
    """Redraw every figure of a demo folder from its saved data and embed them in ``report.html`` again.

    Parameters
    ----------
    folder : path-like
        A folder written by ``workbench demo`` (``report.html``, ``figures/*.json``).
    shared : path-like, optional
        The real-data folder (:func:`workbench.demo.context.shared_data_dir` when omitted);
        needed by the figures of the real captures only.

    Returns
    -------
    dict
        ``redrawn`` (figure names), ``skipped`` (name -> reason: a real-data file that is
        absent) and ``report`` (the rewritten ``report.html``).
    """
    from surfaces.io import atomic_write_text, write_png
    from workbench.demo.context import shared_data_dir

    root = Path(folder)
    page_path = root / "report.html"
    if not page_path.is_file():
        raise FileNotFoundError(f"{folder}: no report.html (run workbench demo --out {folder} first)")
    source = Source(root.resolve(), Path(shared) if shared is not None else shared_data_dir())
    page = page_path.read_text(encoding="utf-8")
    names = re.findall(r'<a href="figures/([A-Za-z0-9_\-]+)\.png">', page)
    if not names:
        raise InputError(f"{page_path}: holds no demo figures")
    redrawn, skipped = [], {}
    for name in names:
        try:
            picture = draw(source, name)
        except FileNotFoundError as exc:
            skipped[name] = str(exc)
            continue
        path = write_png(root / "figures" / f"{name}.png", picture)
        uri = "data:image/png;base64," + base64.b64encode(path.read_bytes()).decode("ascii")
        page = re.sub(r'(<figure id="fig-\d+"><img src=")data:image/png;base64,[A-Za-z0-9+/=]*("[^>]*>'
                      rf'<figcaption>(?:(?!</figcaption>).)*?<a href="figures/{re.escape(name)}\.png">)',
                      lambda m, uri=uri: m.group(1) + uri + m.group(2), page, count=1, flags=re.S)
        redrawn.append(name)
    out = atomic_write_text(page_path, page)
    return {"redrawn": redrawn, "skipped": skipped, "report": str(out)}


def _register_all() -> None:
    """Import the section modules, whose drawers register themselves."""
    from workbench.demo import accuracy, breast, ct, inspection, real  # noqa: F401
