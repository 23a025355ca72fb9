"""Files for the shared surface model.

Meshes are written with numpy alone (binary little-endian PLY with vertex
normals and colours, Wavefront OBJ with normals, binary STL with facet
normals), atomically: into a temporary file beside the target, renamed when
complete. Reading imports open3d inside the function; the open3d conversion for
viewing is :func:`surfaces.convert.to_open3d`.
"""

from __future__ import annotations

import json
import os
import tempfile
import zipfile
from contextlib import contextmanager
from pathlib import Path

import numpy as np

from surfaces.bezier import BezierPatches
from surfaces.mesh import PATCH_SAMPLES, TriangleMesh, as_mesh, weld
from surfaces.vectors import cross, unit
from surfaces.validate import InputError

MESH_FORMATS = (".ply", ".obj", ".stl")

# the process umask, read once (os.umask can only be read by setting it)
_UMASK = os.umask(0)
os.umask(_UMASK)


@contextmanager
def atomic_path(path, suffix: str | None = None):
    """Yield a temporary path beside ``path``; rename it onto ``path`` on success.

    Parameters
    ----------
    path : str or os.PathLike
        Final file name. Its folder must exist.
    suffix : str, optional
        Suffix of the temporary name (some writers choose the format by it);
        defaults to the suffix of ``path``.

    Yields
    ------
    pathlib.Path
        Where to write. Removed if the block raises.
    """
    target = Path(path)
    if not target.parent.is_dir():
        raise FileNotFoundError(f"{target}: folder {target.parent} does not exist")
    fd, tmp = tempfile.mkstemp(prefix=f".{target.name}.", suffix=suffix or target.suffix, dir=target.parent)
    os.close(fd)
    try:
        yield Path(tmp)
        # mkstemp makes owner-only files; results are meant to be shared like any new file
        os.chmod(tmp, 0o666 & ~_UMASK)
        os.replace(tmp, target)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise


def atomic_write_bytes(path, data: bytes) -> Path:
    """Write ``data`` to ``path`` atomically (temporary file beside it, then rename).

    Parameters
    ----------
    path : str or os.PathLike
        Destination file; its folder must exist.
    data : bytes
        File content.

    Returns
    -------
    pathlib.Path
        The destination path.
    """
    with atomic_path(path) as tmp:
        tmp.write_bytes(data)
    return Path(path)


def atomic_write_text(path, text: str) -> Path:
    """Write UTF-8 ``text`` to ``path`` atomically (see :func:`atomic_write_bytes`).

    Parameters
    ----------
    path : str or os.PathLike
        Destination file; its folder must exist.
    text : str
        File content.

    Returns
    -------
    pathlib.Path
        The destination path.
    """
    return atomic_write_bytes(path, text.encode("utf-8"))


def jsonable(value):
    """``value`` with numpy scalars and arrays turned into plain Python (lists, floats, ints, bools).

    Parameters
    ----------
    value : object
        Nested dicts, lists, tuples, numpy arrays and scalars.

    Returns
    -------
    object
        The same structure, serialisable by :mod:`json`.
    """
    if isinstance(value, dict):
        return {str(k): jsonable(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [jsonable(v) for v in value]
    if isinstance(value, np.ndarray):
        return jsonable(value.tolist())
    if isinstance(value, Path):
        return str(value)
    if isinstance(value, np.bool_):
        return bool(value)
    if isinstance(value, np.integer):
        return int(value)
    if isinstance(value, np.floating):
        return float(value)
    return value


def write_json(path, content, indent: int = 2) -> Path:
    """Write ``content`` as indented JSON atomically; numpy values become plain Python.

    Parameters
    ----------
    path : str or os.PathLike
        Destination file.
    content : dict or list
        JSON-serialisable content (numpy values and paths allowed).
    indent : int
        Indentation of the JSON text.

    Returns
    -------
    pathlib.Path
    """
    return atomic_write_text(path, json.dumps(jsonable(content), indent=indent) + "\n")


def png_bytes(image) -> bytes:
    """Encode an RGB or grey picture as PNG bytes (8 or 16 bits per channel).

    Parameters
    ----------
    image : (H, W) or (H, W, 3) uint8 or uint16 array
        Grey or RGB picture (RGB order; converted to OpenCV's BGR order here).

    Returns
    -------
    bytes
        The PNG file content.

    Raises
    ------
    ValueError
        Another dtype or shape, or an encoding failure.
    """
    import cv2

    img = np.asarray(image)
    if img.dtype not in (np.uint8, np.uint16):
        raise InputError(f"image: expected uint8 or uint16 pixels, got {img.dtype}")
    if img.ndim == 3 and img.shape[2] == 3:
        img = img[..., ::-1]
    elif img.ndim != 2:
        raise InputError(f"image: expected shape (H, W) or (H, W, 3), got {img.shape}")
    ok, data = cv2.imencode(".png", np.ascontiguousarray(img))
    if not ok:
        raise InputError(f"image: PNG encoding failed for shape {img.shape}")
    return data.tobytes()


def write_png(path, image) -> Path:
    """Write an RGB or grey picture as PNG, atomically; the one PNG writer of the workbench.

    Parameters
    ----------
    path : str or os.PathLike
        Output file; its folder is created when missing.
    image : (H, W) or (H, W, 3) uint8 or uint16 array
        Grey or RGB picture (RGB channel order).

    Returns
    -------
    pathlib.Path
        The written file.

    Examples
    --------
    >>> import tempfile, cv2
    >>> folder = tempfile.mkdtemp()
    >>> img = np.zeros((2, 3, 3), np.uint8); img[..., 0] = 255
    >>> path = write_png(Path(folder) / "red.png", img)
    >>> cv2.imread(str(path))[0, 0].tolist()  # OpenCV reads BGR
    [0, 0, 255]
    """
    data = png_bytes(image)
    out = Path(path)
    out.parent.mkdir(parents=True, exist_ok=True)
    return atomic_write_bytes(out, data)


def save_npy(path, array) -> Path:
    """Save one array as ``.npy`` atomically (no pickles).

    Parameters
    ----------
    path : str or os.PathLike
        Destination file.
    array : array_like
        The array, saved with its dtype.

    Returns
    -------
    pathlib.Path
    """
    with atomic_path(path, suffix=".npy") as tmp:
        with open(tmp, "wb") as fh:
            np.save(fh, np.asarray(array), allow_pickle=False)
    return Path(path)


class NpyRowWriter:
    """Appends row blocks of one array to an ``.npy`` file (see :func:`npy_row_writer`)."""

    def __init__(self, fh, shape: tuple[int, ...], dtype: np.dtype, name: str) -> None:
        self._fh, self.shape, self.dtype, self._name = fh, shape, dtype, name
        self.rows_written = 0

    def __setitem__(self, rows: slice, block) -> None:
        """``writer[rows] = block``: :meth:`write`, for callers that fill arrays by row slices.

        Raises
        ------
        ValueError
            When ``rows`` is not the next slice of rows (the file is written in order).
        """
        ordered = isinstance(rows, slice) and (rows.start or 0) == self.rows_written and rows.step in (None, 1)
        if not ordered:
            raise InputError(f"{self._name}: rows must be written in order; expected a slice from row "
                             f"{self.rows_written}, got {rows!r}")
        self.write(block)

    def write(self, block) -> None:
        """Append ``block``, shape ``(k, *shape[1:])``: the next ``k`` rows of the array.

        Raises
        ------
        ValueError
            When the block's trailing shape differs or it runs past the last row.
        """
        arr = np.ascontiguousarray(block, dtype=self.dtype)
        if arr.shape[1:] != self.shape[1:] or self.rows_written + arr.shape[0] > self.shape[0]:
            raise InputError(f"{self._name}: block of shape {arr.shape} does not continue an array of shape "
                             f"{self.shape} at row {self.rows_written}")
        arr.tofile(self._fh)
        self.rows_written += arr.shape[0]


@contextmanager
def npy_row_writer(path, shape, dtype):
    """Write an ``.npy`` file block by block of rows, atomically (only the block is in memory).

    Parameters
    ----------
    path : str or os.PathLike
        Destination file; its folder must exist.
    shape : tuple of int
        Shape of the whole array; rows are its first axis.
    dtype : numpy dtype
        Stored dtype (blocks are converted to it).

    Yields
    ------
    NpyRowWriter
        Its ``write(block)`` appends the next rows (C order), as does
        ``writer[rows] = block`` for the next slice of rows. The file appears at
        ``path`` when the block ends with every row written.

    Raises
    ------
    ValueError
        When fewer rows than ``shape[0]`` were written (the file is not created).

    Examples
    --------
    >>> import tempfile
    >>> path = Path(tempfile.mkdtemp()) / "a.npy"
    >>> with npy_row_writer(path, (3, 2), np.float32) as out:
    ...     out.write(np.zeros((2, 2)))
    ...     out.write(np.ones((1, 2)))
    >>> np.load(path).tolist()
    [[0.0, 0.0], [0.0, 0.0], [1.0, 1.0]]
    """
    shape = tuple(int(n) for n in shape)
    dtype = np.dtype(dtype)
    with atomic_path(path, suffix=".npy") as tmp:
        with open(tmp, "wb") as fh:
            header = {"descr": np.lib.format.dtype_to_descr(dtype), "fortran_order": False, "shape": shape}
            if _needs_v2(header):
                np.lib.format.write_array_header_2_0(fh, header)
            else:
                np.lib.format.write_array_header_1_0(fh, header)
            writer = NpyRowWriter(fh, shape, dtype, str(path))
            yield writer
        if writer.rows_written != shape[0]:
            raise InputError(f"{path}: {writer.rows_written} of {shape[0]} rows written")


def _needs_v2(header: dict) -> bool:
    """Version 1.0 headers hold at most 65535 bytes (numpy's own rule)."""
    return len(repr(header)) > 65000


def read_npy_rows(path, start: int, stop: int) -> np.ndarray:
    """Rows ``start:stop`` of a C-order ``.npy`` file, read without mapping the file.

    Parameters
    ----------
    path : str or os.PathLike
        An ``.npy`` file (no pickles, C order).
    start, stop : int
        Row range, ``0 <= start <= stop <= shape[0]``.

    Returns
    -------
    numpy.ndarray, shape (stop - start, *shape[1:])
        A fresh array (only these rows are read into memory).

    Raises
    ------
    ValueError
        When the file is Fortran ordered, holds objects, or the range is outside its rows.
    """
    with open(path, "rb") as fh:
        version = np.lib.format.read_magic(fh)
        if version not in ((1, 0), (2, 0)):
            raise InputError(f"{path}: .npy format version {version} is not supported here")
        read = np.lib.format.read_array_header_1_0 if version == (1, 0) else np.lib.format.read_array_header_2_0
        shape, fortran, dtype = read(fh)
        if fortran or dtype.hasobject or len(shape) == 0:
            raise InputError(f"{path}: expected a C-order numeric array of at least one axis")
        if not 0 <= start <= stop <= shape[0]:
            raise InputError(f"rows: {start}:{stop} is outside the {shape[0]} rows of {path}")
        row = int(np.prod(shape[1:], dtype=np.int64))
        fh.seek(start * row * dtype.itemsize, os.SEEK_CUR)
        out = np.fromfile(fh, dtype=dtype, count=(stop - start) * row)
    return out.reshape((stop - start, *shape[1:]))


#: records per block when a mesh file is written (bounds the extra memory of writing to ~50 MB)
WRITE_BLOCK = 1 << 21


def _write_ply(mesh: TriangleMesh, fh) -> None:
    fields = [("x", "<f4"), ("y", "<f4"), ("z", "<f4")]
    if mesh.vertex_normals is not None:
        fields += [("nx", "<f4"), ("ny", "<f4"), ("nz", "<f4")]
    if mesh.vertex_colors is not None:
        fields += [("red", "u1"), ("green", "u1"), ("blue", "u1")]
    names = {"<f4": "float", "u1": "uchar"}
    header = ["ply", "format binary_little_endian 1.0", "comment surface-workbench"]
    header.append(f"element vertex {mesh.n_vertices}")
    header += [f"property {names[t]} {n}" for n, t in fields]
    header += [f"element face {mesh.n_triangles}", "property list uchar int vertex_indices", "end_header"]
    fh.write(("\n".join(header) + "\n").encode("ascii"))
    for start in range(0, mesh.n_vertices, WRITE_BLOCK):
        part = slice(start, start + WRITE_BLOCK)
        vert = np.empty(len(mesh.vertices[part]), dtype=fields)
        vert["x"], vert["y"], vert["z"] = mesh.vertices[part].T
        if mesh.vertex_normals is not None:
            vert["nx"], vert["ny"], vert["nz"] = mesh.vertex_normals[part].T
        if mesh.vertex_colors is not None:
            rgb = np.clip(np.round(mesh.vertex_colors[part] * 255.0), 0, 255).astype(np.uint8)
            vert["red"], vert["green"], vert["blue"] = rgb.T
        fh.write(vert.tobytes())
    for start in range(0, mesh.n_triangles, WRITE_BLOCK):
        tri = mesh.triangles[start:start + WRITE_BLOCK]
        faces = np.empty(len(tri), dtype=[("n", "u1"), ("idx", "<i4", (3,))])
        faces["n"] = 3
        faces["idx"] = tri
        fh.write(faces.tobytes())


def _obj_text(mesh: TriangleMesh) -> str:
    lines = ["# surface-workbench"]
    lines += [f"v {x:.9g} {y:.9g} {z:.9g}" for x, y, z in mesh.vertices]
    face = mesh.triangles + 1
    if mesh.vertex_normals is not None:
        lines += [f"vn {x:.7g} {y:.7g} {z:.7g}" for x, y, z in mesh.vertex_normals]
        lines += [f"f {a}//{a} {b}//{b} {c}//{c}" for a, b, c in face]
    else:
        lines += [f"f {a} {b} {c}" for a, b, c in face]
    return "\n".join(lines) + "\n"


def _write_stl(mesh: TriangleMesh, fh) -> None:
    fh.write(b"surface-workbench binary STL".ljust(80, b" ") + np.uint32(mesh.n_triangles).tobytes())
    for start in range(0, mesh.n_triangles, WRITE_BLOCK):
        tri = mesh.triangles[start:start + WRITE_BLOCK]
        rec = np.zeros(len(tri), dtype=[("n", "<f4", (3,)), ("v", "<f4", (3, 3)), ("attr", "<u2")])
        corners = mesh.vertices[tri]
        rec["n"] = unit(cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0]))
        rec["v"] = corners
        fh.write(rec.tobytes())


def write_mesh(mesh, path, samples: int = PATCH_SAMPLES) -> Path:
    """Write a mesh (or a tessellated patch model) to PLY, OBJ or STL.

    Parameters
    ----------
    mesh : TriangleMesh, BezierPatches or mesh-like
        What to write; patches are tessellated with ``samples`` subdivisions
        (any input of :func:`surfaces.mesh.as_mesh`).
    path : str or os.PathLike
        Output file; the format follows the suffix (.ply, .obj, .stl).
    samples : int
        Subdivisions per patch side when ``mesh`` is a patch model.

    Returns
    -------
    pathlib.Path
        The written path.

    Examples
    --------
    >>> import tempfile
    >>> from surfaces.mesh import TriangleMesh
    >>> square = TriangleMesh([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], [[0, 1, 2], [0, 2, 3]])
    >>> path = write_mesh(square, Path(tempfile.mkdtemp()) / "square.ply")
    >>> back = read_mesh(path)
    >>> back.n_triangles, back.surface_area()
    (2, 1.0)

    The mesh comes first:

    >>> write_mesh("square.ply", square)
    Traceback (most recent call last):
    ...
    TypeError: path: expected a file name (str or os.PathLike), got TriangleMesh; the order is write_mesh(mesh, path)
    """
    if not isinstance(path, str | os.PathLike):
        raise TypeError(f"path: expected a file name (str or os.PathLike), got {type(path).__name__}; "
                        "the order is write_mesh(mesh, path)")
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in MESH_FORMATS:
        raise InputError(f"path: unsupported mesh format {path.suffix!r}; use one of {', '.join(MESH_FORMATS)}")
    mesh = as_mesh(mesh, "mesh", samples)
    with atomic_path(path) as tmp:
        if suffix == ".obj":
            tmp.write_text(_obj_text(mesh))
            return path
        with open(tmp, "wb") as fh:
            (_write_ply if suffix == ".ply" else _write_stl)(mesh, fh)
    return path


def read_mesh(path) -> TriangleMesh:
    """Read a triangle mesh from PLY, OBJ or STL (through open3d).

    STL files store every triangle's corners separately; their coincident
    vertices are welded so that the mesh is indexed again.

    Parameters
    ----------
    path : str or os.PathLike
        Mesh file.

    Returns
    -------
    TriangleMesh
        With vertex normals and colours when the file has them.

    Examples
    --------
    STL stores every corner of every triangle; reading welds them again.

    >>> import tempfile
    >>> from surfaces.mesh import TriangleMesh
    >>> square = TriangleMesh([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], [[0, 1, 2], [0, 2, 3]])
    >>> read_mesh(write_mesh(square, Path(tempfile.mkdtemp()) / "square.stl")).n_vertices
    4
    """
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"{path}: no such mesh file")
    if path.suffix.lower() not in MESH_FORMATS:
        raise InputError(f"{path}: unsupported mesh format; use one of {', '.join(MESH_FORMATS)}")
    import open3d as o3d

    # open3d and its RPly reader print their own complaints about a bad file straight to the
    # process's stderr; they are caught and the ValueError below says it once
    with o3d.utility.VerbosityContextManager(o3d.utility.VerbosityLevel.Error), _captured_stderr() as said:
        m = o3d.io.read_triangle_mesh(str(path))
    verts = np.asarray(m.vertices, dtype=np.float64)
    tri = np.asarray(m.triangles, dtype=np.int64)
    if len(verts) == 0 or len(tri) == 0:
        reason = next((line.strip() for line in said if line.strip()), "")
        raise InputError(f"{path}: no triangles could be read" + (f" ({reason})" if reason else ""))
    normals = np.asarray(m.vertex_normals, dtype=np.float64) if m.has_vertex_normals() else None
    colors = np.asarray(m.vertex_colors, dtype=np.float64) if m.has_vertex_colors() else None
    mesh = TriangleMesh(verts, tri, normals, colors)
    if path.suffix.lower() == ".stl":
        mesh = weld(mesh)
    return mesh


@contextmanager
def _captured_stderr():
    """Redirect the process's file descriptor 2 (C libraries write there) into a list of lines."""
    lines: list[str] = []
    try:
        saved = os.dup(2)
    except OSError:  # no stderr to redirect
        yield lines
        return
    with tempfile.TemporaryFile() as sink:
        os.dup2(sink.fileno(), 2)
        try:
            yield lines
        finally:
            os.dup2(saved, 2)
            os.close(saved)
            sink.seek(0)
            lines.extend(sink.read().decode("utf-8", "replace").splitlines())


def save_patches(patches: BezierPatches, path) -> Path:
    """Save the Bezier control points and closure flags to ``.npz``.

    Parameters
    ----------
    patches : BezierPatches
        The model.
    path : str or os.PathLike
        Output ``.npz`` file (keys ``control`` (R, C, 4, 4, 3), ``closed_u``, ``closed_v``;
        patches of mixed sizes, :class:`surfaces.mixed.MixedPatches`, also ``cells`` (R, 3)).

    Returns
    -------
    pathlib.Path
    """
    path = Path(path)
    with atomic_path(path, suffix=".npz") as tmp:
        with open(tmp, "wb") as fh:
            extra = {} if getattr(patches, "cells", None) is None else {"cells": patches.cells}
            np.savez_compressed(
                fh, control=patches.control, closed_u=patches.closed_u, closed_v=patches.closed_v, **extra
            )
    return path


def load_patches(path) -> BezierPatches:
    """Load a patch model written by :func:`save_patches`.

    Parameters
    ----------
    path : str or os.PathLike
        ``.npz`` file.

    Returns
    -------
    BezierPatches
        A :class:`surfaces.mixed.MixedPatches` when the file has ``cells``.
    """
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"{path}: no such patch file")
    try:
        data = np.load(path, allow_pickle=False)
    except (OSError, ValueError, EOFError, zipfile.BadZipFile) as exc:
        raise InputError(f"{path}: not a readable patch file ({exc})") from None
    if not isinstance(data, np.lib.npyio.NpzFile):
        raise InputError(f"{path}: not a patch file (an .npz archive with a 'control' array)")
    with data:
        if "control" not in data:
            raise InputError(f"{path}: no 'control' array (not a patch file)")
        try:
            flags = [data[name] if name in data else np.array(False) for name in ("closed_u", "closed_v")]
            control = data["control"]
            cells = data["cells"] if "cells" in data else None
        except (OSError, ValueError, EOFError, zipfile.BadZipFile) as exc:
            raise InputError(f"{path}: not a readable patch file ({exc})") from None
    if cells is not None:
        from surfaces.mixed import MixedPatches

        return MixedPatches(control, cells=cells)
    if any(flag.size != 1 for flag in flags):
        raise InputError(f"{path}: closed_u and closed_v must be single flags")
    return BezierPatches(control, bool(flags[0]), bool(flags[1]))
