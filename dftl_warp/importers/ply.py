"""PLY, for strand files and head meshes: ``ascii 1.0``, ``binary_little_endian 1.0`` and
``binary_big_endian 1.0``, scalar and list properties (http://paulbourke.net/dataformats/ply/).

Hand-written with numpy rather than the ``plyfile`` package so that every malformed file gives a
one-line error with its byte offset (binary) or line (ASCII), and so that element counts are
checked against the file size before anything is allocated.

Strand PLY files (the convention of kenshi84/hairutil, used to convert CT2Hair and USC-HairSalon
strands, written with hapPLY) hold a ``vertex`` element (``x y z``, optional ``thickness``,
``width`` or ``radius``) and delimit strands with, in order of preference:

1. an element ``strand`` (or ``curve``) with a ``nsegs`` property (segments per strand) or a
   ``vertex_count`` / ``nverts`` / ``num_vertices`` property (vertices per strand);
2. a vertex property ``strand_id`` / ``strand_index`` / ``strand`` / ``curve_id``: runs of
   consecutive vertices with the same value are strands (an id that resumes after another
   strand's vertices is refused);
3. an element ``edge`` with ``vertex1 vertex2``: edges (i, i + 1) join consecutive vertices,
   strands break where there is no such edge.
"""

from __future__ import annotations

import re

import numpy as np

from ..errors import UserError, plural
from . import Groom, Reader
from ._binary import Buffer, drop_short_strands

TYPES = {
    "char": "i1", "int8": "i1", "uchar": "u1", "uint8": "u1",
    "short": "i2", "int16": "i2", "ushort": "u2", "uint16": "u2",
    "int": "i4", "int32": "i4", "uint": "u4", "uint32": "u4",
    "float": "f4", "float32": "f4", "double": "f8", "float64": "f8",
}
FORMATS = {"ascii": None, "binary_little_endian": "<", "binary_big_endian": ">"}
MAX_HEADER = 1 << 20


class Element:
    def __init__(self, name: str, count: int):
        self.name = name
        self.count = count
        #: (name, dtype) for scalars, (name, count dtype, item dtype) for lists
        self.properties: list[tuple] = []
        self.data: dict[str, object] = {}
        #: where the rows are: first line (ASCII), or first byte and bytes per row (binary, scalar rows)
        self.line: int | None = None
        self.offset: int | None = None
        self.row_size: int | None = None
        self.field_offsets: dict[str, int] = {}
        #: first byte of each row (binary rows with lists)
        self.row_offsets: list[int] | None = None

    def has(self, name: str) -> bool:
        return name in self.data

    def where(self, row: int, prop: str = "") -> str:
        """``line N`` (ASCII) or ``offset N`` (binary) of row ``row`` (and property ``prop``), for messages."""
        if self.line is not None:
            return f"line {self.line + row}"
        if self.row_offsets is not None:
            return f"offset {self.row_offsets[row]}"
        if self.offset is not None and self.row_size is not None:
            return f"offset {self.offset + row * self.row_size + self.field_offsets.get(prop, 0)}"
        return f"row {row}"


class PlyElements(dict):
    """The elements of a PLY file by name; ``check_end()`` raises if data follows the last element
    (the element counts do not add up), which the strand reader checks after its own counts."""

    end_error: UserError | None = None

    def check_end(self) -> None:
        if self.end_error is not None:
            raise self.end_error


def _parse_header(buf: Buffer):
    data = buf.data
    if not data.startswith(b"ply\n") and not data.startswith(b"ply\r\n"):
        raise buf.error(0, f"signature {data[:4]!r} is not b'ply\\n': not a PLY file")
    end = data.find(b"end_header", 0, MAX_HEADER)
    if end < 0:
        raise buf.error(0, "no end_header line in the first MiB: truncated or not a PLY file")
    nl = data.find(b"\n", end)
    if nl < 0:
        raise buf.error(end, "truncated after end_header")
    body = nl + 1
    try:
        lines = data[:end].decode("ascii").splitlines()
    except UnicodeDecodeError as exc:
        raise buf.error(exc.start, "non-ASCII byte in the PLY header") from None
    fmt = None
    elements: list[Element] = []
    declared: list[int] = []  # header line of each element

    def check_properties():
        if elements and elements[-1].count and not elements[-1].properties:
            raise UserError(f"{buf.path}: line {declared[-1]}: element {elements[-1].name!r} has "
                            f"{elements[-1].count} rows but no properties")

    for i, raw in enumerate(lines[1:], start=2):
        words = raw.split()
        where = f"{buf.path}: line {i}"
        if not words or words[0] in ("comment", "obj_info"):
            continue
        if words[0] == "format":
            if len(words) != 3 or words[1] not in FORMATS or words[2] != "1.0":
                raise UserError(f"{where}: unsupported format line {raw.strip()!r}")
            fmt = words[1]
        elif words[0] == "element":
            if len(words) != 3 or not re.fullmatch(r"\d+", words[2]):
                raise UserError(f"{where}: bad element line {raw.strip()!r}")
            check_properties()
            elements.append(Element(words[1], int(words[2])))
            declared.append(i)
        elif words[0] == "property":
            if not elements:
                raise UserError(f"{where}: property before any element")
            if words[-1] in (p[0] for p in elements[-1].properties):
                raise UserError(f"{where}: property {words[-1]!r} of element {elements[-1].name!r} is declared twice")
            if len(words) == 3 and words[1] in TYPES:
                elements[-1].properties.append((words[2], np.dtype(TYPES[words[1]])))
            elif len(words) == 5 and words[1] == "list" and words[2] in TYPES and words[3] in TYPES \
                    and TYPES[words[2]][0] in "iu":
                elements[-1].properties.append((words[4], np.dtype(TYPES[words[2]]), np.dtype(TYPES[words[3]])))
            else:
                raise UserError(f"{where}: bad property line {raw.strip()!r}")
        else:
            raise UserError(f"{where}: unknown header keyword {words[0]!r}")
    check_properties()
    if fmt is None:
        raise buf.error(0, "no format line in the PLY header")
    return fmt, elements, body, len(lines) + 2  # the first body line: after the end_header line


def _read_binary(buf: Buffer, elements, offset: int, order: str) -> int:
    for el in elements:
        scalar = all(len(p) == 2 for p in el.properties)
        if scalar:
            dtype = np.dtype([(f"p{j}", p[1].newbyteorder(order)) for j, p in enumerate(el.properties)])
            if offset + el.count * dtype.itemsize > buf.size:
                raise buf.error(offset, f"truncated: element {el.name!r} ({el.count} rows of {dtype.itemsize} bytes) "
                                        f"needs {el.count * dtype.itemsize} bytes, the file has "
                                        f"{buf.size - offset} left")
            rows = np.frombuffer(buf.data, dtype=dtype, count=el.count, offset=offset)
            el.offset, el.row_size = offset, dtype.itemsize
            el.field_offsets = {p[0]: dtype.fields[f"p{j}"][1] for j, p in enumerate(el.properties)}
            for j, p in enumerate(el.properties):
                el.data[p[0]] = rows[f"p{j}"].astype(p[1].newbyteorder("="))
            offset += el.count * dtype.itemsize
            continue
        # rows with lists: the minimal row size bounds the count before the row loop
        minimal = sum(p[1].itemsize for p in el.properties)
        if offset + el.count * minimal > buf.size:
            raise buf.error(offset, f"truncated: element {el.name!r} has {el.count} rows, they cannot fit in "
                                    f"the {buf.size - offset} bytes left")
        columns = {p[0]: [] for p in el.properties}
        el.row_offsets = []
        for r in range(el.count):
            el.row_offsets.append(offset)
            for p in el.properties:
                if len(p) == 2:
                    dt = p[1].newbyteorder(order)
                    v = buf.array(dt, 1, offset, f"element {el.name!r} row {r} property {p[0]!r}")
                    columns[p[0]].append(v[0])
                    offset += dt.itemsize
                else:
                    ct, it = p[1].newbyteorder(order), p[2].newbyteorder(order)
                    n = int(buf.array(ct, 1, offset, f"element {el.name!r} row {r} list {p[0]!r} length")[0])
                    if n < 0:
                        raise buf.error(offset, f"element {el.name!r} row {r}: list {p[0]!r} length {n} is negative")
                    offset += ct.itemsize
                    columns[p[0]].append(buf.array(it, n, offset, f"element {el.name!r} row {r} list {p[0]!r}")
                                         .astype(p[2]))
                    offset += n * it.itemsize
        for p in el.properties:
            el.data[p[0]] = np.array(columns[p[0]], dtype=p[1]) if len(p) == 2 else columns[p[0]]
    return offset


def _read_ascii(buf: Buffer, elements, offset: int, first_line: int) -> UserError | None:
    """Fill the elements from an ASCII body, one row per line; returns the error for non-blank lines
    after the last element (raised by the caller after its own checks), or None."""
    try:
        text = buf.data[offset:].decode("ascii")
    except UnicodeDecodeError as exc:
        raise buf.error(offset + exc.start, "non-ASCII byte in an ASCII PLY body") from None
    lines = text.splitlines()
    i = 0
    for el in elements:
        scalar = all(len(p) == 2 for p in el.properties)
        el.line = first_line + i
        if i + el.count > len(lines):
            raise UserError(f"{buf.path}: line {first_line + len(lines)}: truncated: element {el.name!r} needs "
                            f"{el.count} lines, {len(lines) - i} left")
        if scalar:
            rows = [line.split() for line in lines[i:i + el.count]]
            nprop = len(el.properties)
            values = None
            if all(len(words) == nprop for words in rows):
                try:
                    values = np.array([w for words in rows for w in words], dtype=np.float64)
                except ValueError:
                    pass
            if values is None:
                for r, words in enumerate(rows):  # find the bad line
                    try:
                        [float(w) for w in words]
                    except ValueError:
                        words = None
                    if words is None or len(words) != nprop:
                        raise UserError(f"{buf.path}: line {first_line + i + r}: element {el.name!r} row {r}: "
                                        f"expected {nprop} numbers, got {lines[i + r].strip()[:60]!r}")
                raise UserError(f"{buf.path}: line {first_line + i}: element {el.name!r}: cannot parse its rows")
            values = values.reshape(el.count, nprop)
            for j, p in enumerate(el.properties):
                el.data[p[0]] = values[:, j].astype(p[1]) if p[1].kind == "f" else \
                    _ascii_int(values[:, j], p[1], buf.path, first_line + i, el.name, p[0])
        else:
            columns = {p[0]: [] for p in el.properties}
            for r in range(el.count):
                line_no = first_line + i + r
                words = lines[i + r].split()
                k = 0
                try:
                    for p in el.properties:
                        if len(p) == 2:
                            columns[p[0]].append(float(words[k]))
                            k += 1
                        else:
                            n = int(words[k])
                            if n < 0 or k + 1 + n > len(words):
                                raise ValueError
                            columns[p[0]].append(np.array(words[k + 1:k + 1 + n], dtype=np.float64))
                            k += 1 + n
                    if k != len(words):
                        raise ValueError
                except (ValueError, IndexError):
                    raise UserError(f"{buf.path}: line {line_no}: element {el.name!r} row {r}: cannot parse "
                                    f"{lines[i + r].strip()[:60]!r}") from None
            for p in el.properties:
                if len(p) == 2:
                    el.data[p[0]] = np.array(columns[p[0]], dtype=np.float64).astype(p[1])
                else:
                    el.data[p[0]] = [_ascii_int(v, p[2], buf.path, first_line + i, el.name, p[0]) if p[2].kind != "f"
                                     else v.astype(p[2]) for v in columns[p[0]]]
        i += el.count
    for r in range(i, len(lines)):
        if lines[r].strip():
            last = f"the last element ({elements[-1].name!r}, {elements[-1].count} rows)" if elements else "the header"
            return UserError(f"{buf.path}: line {first_line + r}: {lines[r].strip()[:60]!r} after {last}: the "
                             f"element counts do not add up")
    return None


def _ascii_int(values, dtype, path, line, element, prop):
    info = np.iinfo(dtype)
    bad = ~np.isfinite(values) | (values != np.round(values)) | (values < info.min) | (values > info.max)
    if np.any(bad):
        r = int(np.flatnonzero(bad)[0])
        raise UserError(f"{path}: line {line + r}: element {element!r} property {prop!r}: {values[r]:g} is not "
                        f"a {dtype} integer")
    return values.astype(dtype)


def read_ply(data: bytes, path: str, *, defer_end: bool = False) -> PlyElements:
    """Parse a PLY file into its elements (name -> Element with ``data[property]``). Data after
    the last element is an error (the element counts do not add up), raised here or, with
    ``defer_end``, by the result's ``check_end()``."""
    buf = Buffer(data, path)
    fmt, elements, body, first_line = _parse_header(buf)
    names = [e.name for e in elements]
    dupes = {n for n in names if names.count(n) > 1}
    if dupes:
        raise buf.error(0, f"element {sorted(dupes)[0]!r} is declared twice")
    result = PlyElements((e.name, e) for e in elements)
    if fmt == "ascii":
        result.end_error = _read_ascii(buf, elements, body, first_line)
    else:
        end = _read_binary(buf, elements, body, FORMATS[fmt])
        if end < buf.size:
            last = f"the last element ({elements[-1].name!r}, {elements[-1].count} rows)" if elements else "the header"
            result.end_error = buf.error(end, f"{buf.size - end} bytes after {last}: the element counts do not "
                                              f"add up (file size {buf.size})")
    if not defer_end:
        result.check_end()
    return result


def unused_note(elements: dict, used: dict, path: str, why: str) -> str | None:
    """One warning listing the elements and properties of a PLY file that a reader did not use
    (``used``: element name -> the properties it read); None when it used everything."""
    parts = []
    for name, el in elements.items():
        if name not in used:
            if el.count:
                parts.append(f"element {name!r} ({el.count} row{'s' if el.count > 1 else ''})")
            continue
        rest = [p[0] for p in el.properties if p[0] not in used[name]]
        if rest:
            parts.append(f"{name} propert{'y' if len(rest) == 1 else 'ies'} {', '.join(repr(r) for r in rest)}")
    return f"{path}: not imported: {'; '.join(parts)} ({why})" if parts else None


def vertex_positions(elements: dict, path: str) -> np.ndarray:
    v = elements.get("vertex")
    if v is None:
        raise UserError(f"{path}: no 'vertex' element")
    for c in "xyz":
        if not v.has(c) or isinstance(v.data[c], list):
            raise UserError(f"{path}: element 'vertex' has no scalar property {c!r}")
    return np.stack([v.data[c].astype(np.float64) for c in "xyz"], axis=1).reshape(-1, 3)


STRAND_ELEMENTS = ("strand", "curve", "strands", "curves")
SEGMENT_PROPS = ("nsegs", "num_segments", "segments")
VERTEX_COUNT_PROPS = ("vertex_count", "nverts", "num_vertices", "num_verts", "count")
ID_PROPS = ("strand_id", "strand_index", "strand", "curve_id", "curve_index")


def _scalar(el, name):
    value = el.data.get(name)
    return None if value is None or isinstance(value, list) else value


def _integers(el, name: str, path: str) -> np.ndarray:
    """The scalar property ``name`` of ``el`` as int64; a count or index must be a whole number
    (a float property of 3.7 is an error, not 3)."""
    col = el.data[name]
    if col.dtype.kind == "f":
        bad = ~np.isfinite(col) | (col != np.round(col)) | (np.abs(col) > 2.0 ** 53)
        if bad.any():
            r = int(np.flatnonzero(bad)[0])
            raise UserError(f"{path}: {el.where(r, name)}: element {el.name!r} row {r} property {name!r} = {col[r]:g}: "
                            f"expected a whole number")
    return col.astype(np.int64)


def read(data: bytes, path: str) -> Groom:
    elements = read_ply(data, path, defer_end=True)
    points = vertex_positions(elements, path)
    n = points.shape[0]
    vertex = elements["vertex"]
    counts = None
    how = ""
    used = {"vertex": {"x", "y", "z"}}
    for name in STRAND_ELEMENTS:
        el = elements.get(name)
        if el is None:
            continue
        for prop in SEGMENT_PROPS + VERTEX_COUNT_PROPS:
            col = _scalar(el, prop)
            if col is not None:
                counts = _integers(el, prop, path) + (1 if prop in SEGMENT_PROPS else 0)
                how = f"element {name!r} property {prop!r}"
                used[name] = {prop}
                break
        if counts is not None:
            break
    if counts is None:
        for prop in ID_PROPS:
            col = _scalar(vertex, prop)
            if col is not None:
                if n == 0:
                    counts = np.zeros(0, dtype=np.int64)
                else:
                    breaks = np.flatnonzero(col[1:] != col[:-1]) + 1
                    counts = np.diff(np.concatenate([[0], breaks, [n]])).astype(np.int64)
                    # a strand's vertices are one run: an id seen again after others would split it
                    starts = np.concatenate([[0], breaks])
                    ids, first = np.unique(col[starts], return_index=True)
                    if len(ids) < len(starts):
                        again = np.setdiff1d(np.arange(len(starts)), first)[0]
                        raise UserError(f"{path}: {prop} {col[starts[again]]:g} is not contiguous: its "
                                        f"vertices resume at vertex {int(starts[again])} after other strands' "
                                        "(a strand's vertices must follow one another)")
                how = f"vertex property {prop!r}"
                used["vertex"].add(prop)
                break
    if counts is None and "edge" in elements:
        e = elements["edge"]
        a, b = _scalar(e, "vertex1"), _scalar(e, "vertex2")
        if a is None or b is None:
            raise UserError(f"{path}: element 'edge' has no scalar vertex1/vertex2 properties")
        a, b = _integers(e, "vertex1", path), _integers(e, "vertex2", path)
        bad = (b != a + 1) | (a < 0) | (b >= n)
        if bad.any():
            r = int(np.flatnonzero(bad)[0])
            raise UserError(f"{path}: edge {r} = ({a[r]}, {b[r]}): strand edges must join consecutive vertices "
                            f"(i, i + 1) within the {n} vertices")
        linked = np.zeros(max(n - 1, 0), dtype=bool)
        linked[a] = True
        breaks = np.flatnonzero(~linked) + 1
        counts = np.diff(np.concatenate([[0], breaks, [n]])).astype(np.int64) if n else np.zeros(0, np.int64)
        how = "element 'edge'"
        used["edge"] = {"vertex1", "vertex2"}
    if counts is None:
        raise UserError(f"{path}: cannot tell where strands start: expected an element 'strand' with 'nsegs' "
                        f"(or 'vertex_count'), a vertex property 'strand_id', or an element 'edge'")
    if np.any(counts < 0):
        k = int(np.flatnonzero(counts < 0)[0])
        raise UserError(f"{path}: strand {k}: negative vertex count {counts[k]} ({how})")
    if int(counts.sum()) != n:
        raise UserError(f"{path}: {how} gives {int(counts.sum())} vertices for {plural(counts.size, 'strand')} but the "
                        f"'vertex' element has {n}")
    elements.check_end()
    widths = None
    for prop, scale in (("thickness", 1.0), ("width", 1.0), ("radius", 2.0)):
        col = _scalar(vertex, prop)
        if col is not None:
            widths = col.astype(np.float64) * scale
            bad = ~np.isfinite(widths) | (widths < 0)
            if bad.any():
                i = int(np.flatnonzero(bad)[0])
                raise UserError(f"{path}: vertex {i}: {prop} = {col[i]:g}: expected a finite number >= 0")
            used["vertex"].add(prop)
            break
    warnings = []
    note = unused_note(elements, used, path, "only positions, widths and strands are imported")
    if note:
        warnings.append(note)
    points, counts, widths = drop_short_strands(path, points, counts, widths, warnings)
    return Groom(points, counts, widths=widths, warnings=warnings)


READER = Reader("ply", (".ply",), read, meters_per_unit=0.001, up_axis="Y",
                description="strand PLY (vertex + strand/nsegs, strand_id or edge), ascii or binary")
