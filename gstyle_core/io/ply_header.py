"""A small PLY reader: header parsing and fixed-size element tables (ascii, binary LE/BE).

Counts are checked against the file size before anything is allocated, so a header claiming 10^12
vertices fails at once. Trailing bytes after the last element that is read are tolerated (reported as a
warning by the caller).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import SceneFormatError

PLY_TYPES = {
    "char": "i1",
    "int8": "i1",
    "uchar": "u1",
    "uint8": "u1",
    "short": "i2",
    "int16": "i2",
    "ushort": "u2",
    "uint16": "u2",
    "int": "i4",
    "int32": "i4",
    "uint": "u4",
    "uint32": "u4",
    "float": "f4",
    "float32": "f4",
    "double": "f8",
    "float64": "f8",
}
FORMATS = {"ascii": None, "binary_little_endian": "<", "binary_big_endian": ">"}
MAX_HEADER_BYTES = 1 << 20


@dataclass
class PlyElement:
    """One ``element`` of a PLY header: name, count and (name, numpy type code) properties."""

    name: str
    count: int
    properties: list[tuple[str, str]]
    has_list: bool = False

    def property_names(self) -> list[str]:
        return [p for p, _ in self.properties]

    def dtype(self, endian: str) -> np.dtype:
        return np.dtype([(p, endian + t) for p, t in self.properties])


@dataclass
class PlyHeader:
    """A parsed PLY header; ``body_offset`` is where the data starts."""

    fmt: str
    elements: list[PlyElement]
    body_offset: int
    comments: list[str]

    def element(self, name: str) -> PlyElement | None:
        return next((e for e in self.elements if e.name == name), None)


def _quote(line: str) -> str:
    """A header line for an error message: quoted, control characters escaped, at most 80 characters."""
    return repr(line if len(line) <= 80 else line[:77] + "...")


def is_ply(data: bytes) -> bool:
    """True when the bytes start with the PLY magic line."""
    return data[:4] in (b"ply\n", b"ply\r")


def parse_header(data: bytes, name: str) -> PlyHeader:
    """Parse the header text up to ``end_header``; raise ``SceneFormatError`` on anything malformed."""
    end = data.find(b"end_header", 0, MAX_HEADER_BYTES)
    if end < 0:
        raise SceneFormatError(f"{name}: PLY header has no end_header line")
    newline = data.find(b"\n", end)
    if newline < 0:
        raise SceneFormatError(f"{name}: PLY header is not terminated by a newline")
    try:
        text = data[:end].decode("ascii")
    except UnicodeDecodeError:
        raise SceneFormatError(f"{name}: PLY header is not ASCII text") from None
    lines = [ln.strip() for ln in text.splitlines()]
    if not lines or lines[0] != "ply":
        raise SceneFormatError(f"{name}: not a PLY file (first line is not 'ply')")
    fmt = None
    elements: list[PlyElement] = []
    comments: list[str] = []
    for ln in lines[1:]:
        words = ln.split()
        if not words:
            continue
        key = words[0]
        if key in ("comment", "obj_info"):
            comments.append(ln[len(key) :].strip())
        elif key == "format":
            if len(words) != 3 or words[1] not in FORMATS:
                raise SceneFormatError(f"{name}: unsupported PLY format line {_quote(ln)}")
            fmt = words[1]
        elif key == "element":
            if len(words) != 3 or not words[2].isdigit() or len(words[2]) > 19:  # 19 digits: any count < 10^19
                raise SceneFormatError(f"{name}: malformed PLY element line {_quote(ln)}")
            elements.append(PlyElement(words[1], int(words[2]), []))
        elif key == "property":
            if not elements:
                raise SceneFormatError(f"{name}: PLY property before any element: {_quote(ln)}")
            if len(words) == 5 and words[1] == "list":
                elements[-1].has_list = True
                elements[-1].properties.append((words[4], "list"))
                continue
            if len(words) != 3 or words[1] not in PLY_TYPES:
                raise SceneFormatError(f"{name}: malformed PLY property line {_quote(ln)}")
            elements[-1].properties.append((words[2], PLY_TYPES[words[1]]))
        else:
            raise SceneFormatError(f"{name}: unexpected PLY header line {_quote(ln)}")
    if fmt is None:
        raise SceneFormatError(f"{name}: PLY header has no format line")
    return PlyHeader(fmt, elements, newline + 1, comments)


def read_elements(
    data: bytes, header: PlyHeader, wanted: set[str], name: str
) -> tuple[dict[str, np.ndarray], int]:
    """Read the fixed-size elements named in ``wanted`` (and all before them).

    Returns structured arrays by element name and the number of unread trailing bytes (binary) or
    tokens (ascii) after the last element read.
    """
    last = max((i for i, e in enumerate(header.elements) if e.name in wanted), default=-1)
    needed = header.elements[: last + 1]
    for e in needed:
        if e.has_list:
            raise SceneFormatError(f"{name}: PLY element '{e.name}' has list properties (not a splat file)")
        if len({p for p, _ in e.properties}) != len(e.properties):
            raise SceneFormatError(f"{name}: PLY element '{e.name}' repeats a property name")
    if header.fmt == "ascii":
        return _read_ascii(data, header.body_offset, needed, wanted, name)
    endian = FORMATS[header.fmt]
    offset = header.body_offset
    available = len(data) - offset
    claimed = sum(e.count * e.dtype(endian).itemsize for e in needed)
    if claimed > available:
        raise SceneFormatError(
            f"{name}: truncated: header declares {claimed:,} bytes of data but only {available:,} follow"
        )
    out: dict[str, np.ndarray] = {}
    for e in needed:
        dt = e.dtype(endian)
        if e.name in wanted:
            out[e.name] = np.frombuffer(data, dt, e.count, offset)
        offset += e.count * dt.itemsize
    return out, len(data) - offset


def _read_ascii(
    data: bytes, offset: int, needed: list[PlyElement], wanted: set[str], name: str
) -> tuple[dict[str, np.ndarray], int]:
    """ASCII bodies: whitespace-separated numbers, one row per item."""
    body = data[offset:]
    tokens_needed = sum(e.count * len(e.properties) for e in needed)
    if tokens_needed * 2 > len(body) + 1:  # every number takes at least one digit and one separator
        raise SceneFormatError(
            f"{name}: truncated: header declares {tokens_needed:,} numbers "
            f"(at least {2 * tokens_needed - 1:,} bytes) but only {len(body):,} bytes follow"
        )
    tokens = body.split()
    if len(tokens) < tokens_needed:
        raise SceneFormatError(
            f"{name}: truncated: header declares {tokens_needed:,} numbers, file holds {len(tokens):,}"
        )
    out: dict[str, np.ndarray] = {}
    pos = 0
    for e in needed:
        n = e.count * len(e.properties)
        if e.name in wanted:
            try:
                values = np.array(tokens[pos : pos + n], dtype=np.float64).reshape(e.count, len(e.properties))
            except ValueError:
                raise SceneFormatError(f"{name}: non-numeric value in ASCII element '{e.name}'") from None
            arr = np.empty(e.count, e.dtype("<"))
            for j, (p, t) in enumerate(e.properties):
                arr[p] = values[:, j].astype(t)
            out[e.name] = arr
        pos += n
    return out, len(tokens) - pos
