"""Files for the shared surface model.

Meshes are written with numpy alone (binary little-endian PLY with vertex
normals and colours, Wavefront OBJ with normals, binary STL with facet
normals), atomically: into a temporary file beside the target, renamed when
complete. Reading parses the three formats with numpy and checks every size,
index and coordinate (no bytes go unchecked to a C reader); the open3d conversion
for viewing is :func:`surfaces.convert.to_open3d`.
"""

from __future__ import annotations

import json
import os
import re
import tempfile
import zipfile
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from surfaces.bezier import BezierPatches
from surfaces.mesh import PATCH_SAMPLES, TriangleMesh, as_mesh, vertex_normals, weld
from surfaces.vectors import cross, unit
from surfaces.validate import InputError, reading

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
    """Read a triangle mesh from PLY, OBJ or STL.

    The files are parsed here with numpy (no foreign C reader sees bytes that
    were not checked): PLY in ASCII or binary of either byte order, with vertex
    ``x, y, z`` and optional ``nx, ny, nz`` and ``red, green, blue``, faces from
    the ``vertex_indices`` (or ``vertex_index``) list; Wavefront OBJ ``v`` and
    ``f`` lines (``v x y z [r g b]``, ``f v``, ``f v/vt``, ``f v//vn``,
    ``f v/vt/vn``, negative indices counted back from the last ``v`` line,
    ``vn`` normals); binary or ASCII STL. Polygons are split into triangle fans
    ``(0, i, i + 1)``. Sizes are checked against the header, indices against the
    vertex count, coordinates for finiteness.

    STL files store every triangle's corners separately; their coincident
    vertices are welded so that the mesh is indexed again, and the vertex
    normals are the area-weighted normals of the welded triangles
    (:func:`surfaces.mesh.vertex_normals`).

    Parameters
    ----------
    path : str or os.PathLike
        Mesh file.

    Returns
    -------
    TriangleMesh
        With vertex normals and colours when the file has them (colours in
        [0, 1]: integer PLY colours are divided by their type's maximum).

    Raises
    ------
    FileNotFoundError
        When ``path`` is not a file.
    InputError
        An unknown suffix, or a damaged file: the message names the file and
        what is wrong (``file ends after 3 of 4 face records``, an index out of
        range, a NaN coordinate, no triangles).

    Examples
    --------
    STL stores every corner of every triangle; reading welds them again.

    >>> import tempfile
    >>> from surfaces.mesh import TriangleMesh
    >>> square = TriangleMesh([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], [[0, 1, 2], [0, 2, 3]])
    >>> read_mesh(write_mesh(square, Path(tempfile.mkdtemp()) / "square.stl")).n_vertices
    4

    A damaged file is one clean error:

    >>> path = Path(tempfile.mkdtemp()) / "cut.ply"
    >>> _ = path.write_bytes(write_mesh(square, path).read_bytes()[:-5])
    >>> read_mesh(path)
    Traceback (most recent call last):
    ...
    surfaces.validate.InputError: ...cut.ply: file ends after 1 of 2 face records
    """
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"{path}: no such mesh file")
    suffix = path.suffix.lower()
    if suffix not in MESH_FORMATS:
        raise InputError(f"{path}: unsupported mesh format; use one of {', '.join(MESH_FORMATS)}")
    data = path.read_bytes()
    name = str(path)
    read = {".ply": _read_ply, ".obj": _read_obj, ".stl": _read_stl}[suffix]
    # an integer past int64 in a text file raises OverflowError in numpy's conversion
    with reading(path, f"{suffix[1:].upper()} file", also=(OverflowError,)):
        verts, tri, normals, colors = read(data, name)
    _check_mesh_arrays(verts, tri, normals, colors, name)
    mesh = TriangleMesh.unchecked(verts, tri, normals, colors)
    if suffix == ".stl":
        mesh = weld(mesh)
        if mesh.n_triangles == 0:
            raise InputError(f"{name}: every triangle collapses when coincident corners are welded")
        mesh.vertex_normals = vertex_normals(mesh.vertices, mesh.triangles)
    return mesh


def _check_mesh_arrays(verts, tri, normals, colors, name: str) -> None:
    """The checks of :class:`TriangleMesh`, with the file named in the message."""
    if len(tri) == 0:
        raise InputError(f"{name}: no triangles could be read (the file holds {len(verts)} vertices and no faces)")
    finite = np.isfinite(verts).all(axis=1)
    if not finite.all():
        raise InputError(f"{name}: {np.count_nonzero(~finite)} of {len(verts)} vertices have a NaN or infinite "
                         f"coordinate (first: vertex {np.argmin(finite)})")
    low, high = int(tri.min()), int(tri.max())
    if low < 0 or high >= len(verts):
        bad = low if low < 0 else high
        raise InputError(f"{name}: a face refers to vertex {bad}; the file has vertices 0 to {len(verts) - 1}")
    for what, values in (("normal", normals), ("colour", colors)):
        if values is not None and not np.isfinite(values).all():
            raise InputError(f"{name}: vertex {what}s hold NaN or infinite values")


# ---- PLY -----------------------------------------------------------------------------------------

#: PLY scalar types (the classic and the sized spellings) as numpy type codes, without byte order
_PLY_TYPES = {"char": "i1", "int8": "i1", "uchar": "u1", "uint8": "u1", "short": "i2", "int16": "i2",
              "ushort": "u2", "uint16": "u2", "int": "i4", "int32": "i4", "uint": "u4", "uint32": "u4",
              "float": "f4", "float32": "f4", "double": "f8", "float64": "f8"}
_PLY_ORDERS = {"ascii": None, "binary_little_endian": "<", "binary_big_endian": ">"}
_PLY_END = re.compile(rb"end_header[ \t]*(\r\n|\r|\n)")
#: records read at once after a change of list lengths in a PLY element (doubles while they stay the same)
_PLY_RUN = 64


@dataclass(frozen=True)
class _PlyProperty:
    name: str
    type: str  #: numpy code of the value (of the items, for a list)
    count: str | None = None  #: numpy code of a list's length; None for a scalar


@dataclass(frozen=True)
class _PlyElement:
    name: str
    count: int
    properties: tuple[_PlyProperty, ...]


def _ply_header(data: bytes, name: str) -> tuple[str, list[_PlyElement], int]:
    """Format, elements and where the body starts."""
    if data[:3] != b"ply" or data[3:4] not in (b"\n", b"\r"):
        raise InputError(f"{name}: not a PLY file (the first line is not 'ply')")
    end = _PLY_END.search(data)
    if end is None:
        raise InputError(f"{name}: the PLY header has no 'end_header' line")
    try:
        text = data[:end.start()].decode("ascii")
    except UnicodeDecodeError:
        raise InputError(f"{name}: the PLY header is not ASCII text") from None
    fmt, elements, props = None, [], []

    def close():
        if elements:
            elements[-1] = _PlyElement(elements[-1].name, elements[-1].count, tuple(props))

    for number, line in enumerate(text.splitlines()[1:], 2):
        words = line.split()
        if not words or words[0] in ("comment", "obj_info"):
            continue
        bad = f"{name}: PLY header line {number} {line.strip()!r}"
        if words[0] == "format":
            if len(words) != 3 or words[1] not in _PLY_ORDERS:
                raise InputError(f"{bad}: expected 'format ascii|binary_little_endian|binary_big_endian 1.0'")
            fmt = words[1]
        elif words[0] == "element":
            if len(words) != 3 or not words[2].isdigit():
                raise InputError(f"{bad}: expected 'element NAME COUNT'")
            close()
            elements.append(_PlyElement(words[1], int(words[2]), ()))
            props = []
        elif words[0] == "property" and elements:
            if len(words) == 5 and words[1] == "list" and words[2] in _PLY_TYPES and words[3] in _PLY_TYPES \
                    and _PLY_TYPES[words[2]][0] in "iu":
                prop = _PlyProperty(words[4], _PLY_TYPES[words[3]], _PLY_TYPES[words[2]])
            elif len(words) == 3 and words[1] in _PLY_TYPES:
                prop = _PlyProperty(words[2], _PLY_TYPES[words[1]])
            else:
                raise InputError(f"{bad}: expected 'property TYPE NAME' or 'property list INTTYPE TYPE NAME'")
            if any(p.name == prop.name for p in props):
                raise InputError(f"{bad}: property {prop.name!r} appears twice")
            props.append(prop)
        else:
            raise InputError(f"{bad}: not a PLY header line")
    close()
    if fmt is None:
        raise InputError(f"{name}: the PLY header has no 'format' line")
    return fmt, elements, end.end()


class _PlyBody:
    """Reads records of one element from a PLY body: bytes (binary) or a float array of tokens (ASCII).

    Positions count bytes (binary) or tokens (ASCII). A block of records with the
    same list lengths has a fixed layout: a structured dtype (binary) or a
    ``(k, width)`` view of the tokens (ASCII).
    """

    def __init__(self, data: bytes, start: int, order: str | None) -> None:
        self.order = order
        if order is None:
            self.buf = np.array(data[start:].split(), dtype=np.float64)
        else:
            self.buf = data
        self.start = 0 if order is None else start

    def size(self, code: str) -> int:
        return 1 if self.order is None else np.dtype(code).itemsize

    def length_at(self, pos: int, code: str) -> int | None:
        """A list length stored at ``pos``; None past the end, -1 when it is not a count."""
        if pos + self.size(code) > len(self.buf):
            return None
        if self.order is None:
            value = self.buf[pos]
            return int(value) if value >= 0 and float(value).is_integer() else -1
        return int(np.frombuffer(self.buf, self.order + code, 1, pos)[0])

    def lengths_at(self, pos: int, props, where: str) -> tuple[int, ...] | None:
        """The list lengths of the record at ``pos``; None when it runs past the end."""
        lengths = []
        for p in props:
            if p.count is None:
                pos += self.size(p.type)
                continue
            n = self.length_at(pos, p.count)
            if n is None:
                return None
            if n < 0:
                raise InputError(f"{where} has a negative or broken list length")
            lengths.append(n)
            pos += self.size(p.count) + n * self.size(p.type)
        return tuple(lengths) if pos <= len(self.buf) else None

    def width(self, props, lengths) -> int:
        """Size of a record whose lists have ``lengths`` (bytes, or tokens in ASCII)."""
        counts = iter(lengths)
        return sum(self.size(p.type) if p.count is None else self.size(p.count) + next(counts) * self.size(p.type)
                   for p in props)

    def block(self, pos: int, k: int, props, lengths) -> tuple[list[np.ndarray], list[np.ndarray]]:
        """``k`` records from ``pos`` laid out by ``lengths``: the columns and the stored list lengths."""
        counts = iter(lengths)
        shape = [None if p.count is None else next(counts) for p in props]
        if self.order is None:
            width = sum(1 if n is None else 1 + n for n in shape)
            rows = self.buf[pos:pos + k * width].reshape(k, width)
            cols, stored, at = [], [], 0
            for n in shape:
                if n is None:
                    cols.append(rows[:, at])
                    at += 1
                else:
                    stored.append(rows[:, at])
                    cols.append(rows[:, at + 1:at + 1 + n])
                    at += 1 + n
            return cols, stored
        fields = []
        for i, (p, n) in enumerate(zip(props, shape)):
            if n is not None:
                fields.append((f"n{i}", self.order + p.count))
            fields.append((f"p{i}", self.order + p.type, () if n is None else (n,)))
        dtype = np.dtype(fields)
        rec = np.frombuffer(self.buf, dtype, k, pos)
        stored = [rec[f"n{i}"] for i, n in enumerate(shape) if n is not None]
        return [rec[f"p{i}"] for i in range(len(props))], stored

    def element(self, pos: int, element: _PlyElement, name: str) -> tuple[list[list[np.ndarray]], int]:
        """All records of ``element`` from ``pos``: per property, its blocks of columns; the next position."""
        props, count = element.properties, element.count
        blocks: list[list[np.ndarray]] = [[] for _ in props]
        done, run = 0, count  # first all records at once: one np.frombuffer when every face has the same size
        while done < count and props:
            lengths = () if all(p.count is None for p in props) else \
                self.lengths_at(pos, props, f"{name}: {element.name} record {done}")
            width = None if lengths is None else self.width(props, lengths)
            fits = 0 if width is None else (len(self.buf) - pos) // width
            k = min(count - done, fits if not lengths else min(run, fits))
            if k == 0:
                raise InputError(f"{name}: file ends after {done} of {count} {element.name} records")
            cols, stored = self.block(pos, k, props, lengths)
            same = np.ones(k, bool)
            for column, n in zip(stored, lengths):
                same &= column == n
            k = int(np.argmin(same)) if not same.all() else k  # the first record of other lengths ends the run
            run = 2 * run if same.all() else _PLY_RUN
            for i, column in enumerate(cols):
                blocks[i].append(column[:k])
            pos += k * width
            done += k
        return blocks, pos


def _fan(polygons: np.ndarray) -> np.ndarray:
    """Triangle fans ``(0, i, i + 1)`` of polygons of one size, shape (k, n) -> (k * (n - 2), 3)."""
    k, n = polygons.shape
    if n < 3:
        return np.empty((0, 3), np.int64)
    first = np.broadcast_to(polygons[:, :1], (k, n - 2))
    return np.stack([first, polygons[:, 1:-1], polygons[:, 2:]], axis=-1).reshape(-1, 3)


def _as_indices(values: np.ndarray, name: str, what: str) -> np.ndarray:
    """Integer indices; float tokens of an ASCII file must be whole numbers within int64."""
    if values.dtype.kind == "f":
        whole = np.isfinite(values) & (np.abs(values) < 2.0**62)
        if not whole.all() or not np.array_equal(values, np.floor(values)):
            raise InputError(f"{name}: {what} holds numbers that are not vertex indices (not whole, or too large)")
    return values.astype(np.int64)


def _read_ply(data: bytes, name: str):
    fmt, elements, start = _ply_header(data, name)
    body = _PlyBody(data, start, _PLY_ORDERS[fmt])
    pos, found = body.start, {}
    for element in elements:
        blocks, pos = body.element(pos, element, name)
        found.setdefault(element.name, (element, blocks))
    if "vertex" not in found:
        raise InputError(f"{name}: the PLY file has no 'vertex' element")
    element, blocks = found["vertex"]
    columns = {p.name: (p, blocks[i]) for i, p in enumerate(element.properties) if p.count is None}

    def stack(names):
        if not all(n in columns for n in names):
            return None
        if element.count == 0:
            return np.zeros((0, len(names)))
        return np.stack([np.concatenate(columns[n][1]).astype(np.float64) for n in names], axis=1)

    verts = stack(("x", "y", "z"))
    if verts is None:
        raise InputError(f"{name}: the PLY vertex element has no x, y, z properties")
    normals = stack(("nx", "ny", "nz"))
    colors = stack(("red", "green", "blue"))
    if colors is not None and np.dtype(columns["red"][0].type).kind in "iu":
        colors /= np.iinfo(np.dtype(columns["red"][0].type)).max
    tri = np.empty((0, 3), np.int64)
    if "face" in found:
        element, blocks = found["face"]
        index = [i for i, p in enumerate(element.properties)
                 if p.count is not None and p.name in ("vertex_indices", "vertex_index")]
        if not index:
            raise InputError(f"{name}: the PLY face element has no 'vertex_indices' list")
        fans = [_fan(_as_indices(b, name, "a face")) for b in blocks[index[0]]]
        tri = np.concatenate(fans) if fans else tri
    return verts, tri, normals, colors


# ---- STL -----------------------------------------------------------------------------------------

_STL_RECORD = np.dtype([("n", "<f4", (3,)), ("v", "<f4", (3, 3)), ("attr", "<u2")])
_STL_VERTEX = re.compile(rb"vertex\s+(\S+)\s+(\S+)\s+(\S+)", re.IGNORECASE)
_STL_FACET = re.compile(rb"(?<![a-z])facet\b", re.IGNORECASE)


def _read_stl(data: bytes, name: str):
    n = int.from_bytes(data[80:84], "little") if len(data) >= 84 else None
    if n is not None and len(data) == 84 + _STL_RECORD.itemsize * n:
        corners = np.frombuffer(data, _STL_RECORD, n, 84)["v"].reshape(-1, 3).astype(np.float64)
    elif data.lstrip()[:5].lower() == b"solid":
        found = _STL_VERTEX.findall(data)
        facets = len(_STL_FACET.findall(data))
        if len(found) != 3 * facets:
            raise InputError(f"{name}: ASCII STL with {facets} facets and {len(found)} vertices (3 per facet expected)")
        if re.search(rb"endsolid", data, re.IGNORECASE) is None:
            raise InputError(f"{name}: ASCII STL without 'endsolid' (the file is cut short)")
        corners = np.array(found, dtype=np.float64).reshape(-1, 3)
    elif n is None:
        raise InputError(f"{name}: {len(data)} bytes, shorter than the 84-byte header of a binary STL")
    else:
        raise InputError(f"{name}: a binary STL of {n} triangles has {84 + _STL_RECORD.itemsize * n} bytes, "
                         f"the file has {len(data)}")
    return corners, np.arange(len(corners), dtype=np.int64).reshape(-1, 3), None, None


# ---- OBJ -----------------------------------------------------------------------------------------

def _obj_lines(lines: list[bytes], key: bytes, name: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The values of the lines starting with ``key`` (an object array of bytes), how many each line has,
    and the lines' numbers; one split of the joined lines instead of one per line."""
    prefixes = (key + b" ", key + b"\t")
    at = np.fromiter((i for i, line in enumerate(lines) if line.startswith(prefixes)), np.int64)
    tokens = np.array(b" ".join([lines[i] for i in at]).split(), dtype=object)
    marks = np.flatnonzero(tokens == key)
    if len(marks) != len(at):
        raise InputError(f"{name}: a '{key.decode()}' line holds '{key.decode()}' as a value")
    lengths = np.diff(np.append(marks, len(tokens))) - 1
    return np.delete(tokens, marks), lengths, at


def _obj_columns(values: np.ndarray, lengths: np.ndarray, first: int, count: int, dtype) -> np.ndarray:
    """Values ``first:first + count`` of every line, shape (lines, count); every line has that many."""
    starts = np.cumsum(lengths) - lengths
    return values[starts[:, None] + np.arange(first, first + count)].astype(dtype).reshape(-1, count)


def _obj_index(idx: np.ndarray, before: np.ndarray | None, total: int, name: str, what: str) -> np.ndarray:
    """0-based indices of 1-based OBJ references; negative ones count back from ``before`` (per reference)."""
    if np.any(idx == 0):
        raise InputError(f"{name}: a face refers to {what} 0 (OBJ counts from 1)")
    idx = np.where(idx < 0, idx + (0 if before is None else before), idx - 1)
    if idx.size and (idx.min() < 0 or idx.max() >= total):
        raise InputError(f"{name}: a face refers to a {what} outside the {total} of the file")
    return idx


def _obj_corners(values: np.ndarray, name: str) -> tuple[np.ndarray, np.ndarray | None]:
    """Vertex and normal references of face corners ``v``, ``v/vt``, ``v//vn`` or ``v/vt/vn``."""
    if not len(values):
        return np.zeros(0, np.int64), None
    joined = b" ".join(values.tolist())
    if b"/" not in joined:
        return values.astype(np.int64), None
    pattern = values[0].split(b"/")
    numbers = joined.replace(b"/", b" ").split()
    k = sum(1 for part in pattern if part)
    uniform = (joined.count(b"/") == (len(pattern) - 1) * len(values) and len(numbers) == k * len(values)
               and joined.count(b"//") == (pattern[1:2] == [b""]) * len(values))
    if uniform:  # every corner has the first one's form: one split of the whole text
        refs = np.array(numbers, dtype=object).reshape(-1, k)
        normal = len(pattern) == 3 and pattern[2]
        return refs[:, 0].astype(np.int64), refs[:, k - 1].astype(np.int64) if normal else None
    parts = [corner.split(b"/") for corner in values.tolist()]
    vi = np.array([p[0] for p in parts], dtype=np.int64)
    if all(len(p) == 3 and p[2] for p in parts):
        return vi, np.array([p[2] for p in parts], dtype=np.int64)
    return vi, None


def _read_obj(data: bytes, name: str):
    lines = data.splitlines()
    if re.search(rb"^[ \t]+[vf]", data, re.MULTILINE):
        lines = [line.lstrip() for line in lines]
    values, lengths, v_at = _obj_lines(lines, b"v", name)
    if len(lengths) and (lengths.min() < 3 or lengths.max() > 7):
        bad = lengths[(lengths < 3) | (lengths > 7)][0]
        raise InputError(f"{name}: a 'v' line has {bad} numbers (3, 4 or 6 expected)")
    verts = _obj_columns(values, lengths, 0, 3, np.float64)
    colors = _obj_columns(values, lengths, 3, 3, np.float64) if len(lengths) and (lengths == 6).all() else None
    values, lengths, vn_at = _obj_lines(lines, b"vn", name)
    if len(lengths) and (lengths != 3).any():
        raise InputError(f"{name}: every 'vn' line needs 3 numbers")
    vn = _obj_columns(values, lengths, 0, 3, np.float64)
    values, sides, f_at = _obj_lines(lines, b"f", name)
    vi, ni = _obj_corners(values, name)
    before = None
    if np.any(vi < 0) or (ni is not None and np.any(ni < 0)):
        # negative references count back from the last v (vn) line above the face
        before = np.repeat(f_at, sides)
    vi = _obj_index(vi, None if before is None else np.searchsorted(v_at, before), len(verts), name, "vertex")
    normals = None
    if ni is not None and len(vn):
        ni = _obj_index(ni, None if before is None else np.searchsorted(vn_at, before), len(vn), name, "normal")
        normals = np.zeros_like(verts)
        normals[vi] = vn[ni]
    # fans (0, j, j + 1) of every polygon, without a loop over faces
    n_tri = np.maximum(sides - 2, 0)
    face = np.repeat(np.arange(len(sides)), n_tri)
    first = (np.cumsum(sides) - sides)[face]
    j = np.arange(len(face)) - np.repeat(np.cumsum(n_tri) - n_tri, n_tri) + 1
    tri = vi[np.stack([first, first + j, first + j + 1], axis=1)] if len(face) else np.empty((0, 3), np.int64)
    return verts, tri, normals, colors


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
