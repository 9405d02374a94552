"""The C contract of the lookup tables: what lib/table/table.h declares
(integer constants, the typedef'd structs, the TBL_LAYOUT members), parsed
from the header so the generator never restates it.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path

from hallhome.paths import LIB_DIR

TABLE_HEADER = LIB_DIR / "table" / "table.h"

_CTYPES = {"uint8_t": ("B", 0, 0xFF), "int8_t": ("b", -0x80, 0x7F),
           "uint16_t": ("H", 0, 0xFFFF), "int16_t": ("h", -0x8000, 0x7FFF),
           "uint32_t": ("I", 0, 0xFFFFFFFF), "int32_t": ("i", -0x80000000, 0x7FFFFFFF),
           "char": ("c", 0, 0x7F)}


class TableError(RuntimeError):
    """The table cannot be generated (message names the robot and the cause)."""


@dataclass(frozen=True)
class CField:
    ctype: str
    name: str
    count: int | None  # array length, None for a scalar
    dims: tuple[str, ...] = ()  # TBL_LAYOUT members: the count parameters (NT, NS, NG)


@dataclass(frozen=True)
class TableSpec:
    """What lib/table/table.h declares: integer constants, struct fields and
    the stored layout (TBL_LAYOUT's members, sized by the robot's counts)."""

    constants: dict[str, int]
    structs: dict[str, tuple[CField, ...]]
    layout: tuple[CField, ...] = ()
    layout_params: tuple[str, str, str] = ("NT", "NS", "NG")

    def __getitem__(self, name: str) -> int:
        return self.constants[name]


def parse_table_header(path: Path = TABLE_HEADER) -> TableSpec:
    """Parse the #define constants and the typedef'd structs of table.h."""
    text = path.read_text(encoding="utf-8")
    text = re.sub(r"/\*.*?\*/", "", text, flags=re.S)
    text = re.sub(r"//[^\n]*", "", text)
    consts: dict[str, int] = {}
    for name, value in re.findall(r"#define\s+(TBL_\w+)\s+(0[xX][0-9A-Fa-f]+|\d+)[uUlL]*\b",
                                  text):
        consts[name] = int(value, 0)
    structs: dict[str, tuple[CField, ...]] = {}
    for body, sname in re.findall(r"typedef\s+struct\s*\{(.*?)\}\s*(\w+)\s*;", text, flags=re.S):
        fields = []
        for decl in body.split(";"):
            decl = " ".join(decl.split())
            if not decl:
                continue
            m = re.fullmatch(r"(?:const\s+)?(\w+)\s+(\w+)(?:\s*\[\s*(\w+)\s*\])?", decl)
            if m is None:
                fields = None  # pointers, function types: not table data
                break
            ctype, name, dim = m.groups()
            count = None if dim is None else (consts[dim] if dim in consts else int(dim, 0))
            fields.append(CField(ctype, name, count))
        if fields is not None:
            structs[sname] = tuple(fields)
    for needed in ("TBL_MAGIC", "TBL_FORMAT_VERSION", "TBL_MAX_GRID", "TBL_MAX_TENDONS",
                   "TBL_MAX_SENSORS", "TBL_NAME_LEN", "TBL_NO_MUX", "TBL_MODE_DELTA",
                   "TBL_MODE_ABSOLUTE", "TBL_CUT_PER_LSB"):
        if needed not in consts:
            raise TableError(f"{path}: constant {needed} not found")
    m = re.search(r"#define\s+TBL_LAYOUT\(\s*(\w+)\s*,\s*(\w+)\s*,\s*(\w+)\s*\)\s*\\\s*"
                  r"struct\s+tbl_table\s*\{(.*?)\}", text, flags=re.S)
    if m is None:
        raise TableError(f"{path}: macro TBL_LAYOUT(NT, NS, NG) not found")
    params = m.group(1, 2, 3)
    layout = []
    for decl in m.group(4).replace("\\", " ").split(";"):
        decl = " ".join(decl.split())
        if not decl:
            continue
        fm = re.fullmatch(r"(\w+)\s+(\w+)((?:\s*\[\s*\w+\s*\])*)", decl)
        if fm is None:
            raise TableError(f"{path}: TBL_LAYOUT member {decl!r} not understood")
        dims = tuple(re.findall(r"\w+", fm.group(3)))
        if any(d not in params for d in dims):
            raise TableError(f"{path}: TBL_LAYOUT member {decl!r}: sizes must be {params}")
        layout.append(CField(fm.group(1), fm.group(2), None, dims))
    if not layout or layout[0].ctype not in structs or layout[0].dims:
        raise TableError(f"{path}: TBL_LAYOUT must start with the header struct")
    return TableSpec(consts, structs, tuple(layout), params)
