"""The console protocol as the host sees it, read from the firmware's own
declarations.

At import time this module parses

* ``lib/console/con_commands.def``  (command names, argument synopses, help),
* ``lib/console/con_errors.def``    (error codes and texts),
* ``lib/store/store_settings.def``  (settings: name, type, range, default, unit),

so the host and the firmware cannot disagree: there is no second list here.
It also parses reply and report lines (``ok``, ``error:<code> <text>``,
``<kind key=value ...>``) and validates command lines the way the firmware
does, and renders the Markdown tables of docs/console.md
(``python -m hallhome.protocol --markdown``; ``--update-docs`` rewrites the
generated sections of docs/console.md in place).
"""

from __future__ import annotations

import argparse
import re
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Dict, List, Optional, Tuple, Union

from hallhome.paths import LIB_DIR, PROJECT_ROOT

COMMANDS_DEF = LIB_DIR / "console" / "con_commands.def"
ERRORS_DEF = LIB_DIR / "console" / "con_errors.def"
SETTINGS_DEF = LIB_DIR / "store" / "store_settings.def"
CONSOLE_DOC = PROJECT_ROOT / "docs" / "console.md"

CONSOLE_H = LIB_DIR / "console" / "console.h"
CON_PARSE_C = LIB_DIR / "console" / "con_parse.c"  # the command table: CON_SYN_MAX


def c_define(path: Path, name: str) -> int:
    """Integer value of `#define name <int>` in a C file."""
    m = re.search(r"^#define\s+" + name + r"\s+(\d+)[uUlL]*\b", path.read_text(encoding="ascii"), re.M)
    if not m:
        raise RuntimeError(f"{name} not found in {path}")
    return int(m.group(1))


LINE_MAX = c_define(CONSOLE_H, "CON_LINE_MAX")  # characters per command line
MAX_ARGS = c_define(CONSOLE_H, "CON_MAX_ARGS")  # arguments after the command name
SYN_MAX = c_define(CON_PARSE_C, "CON_SYN_MAX")  # synopsis buffer, terminator included
MAG_MAX = 2147483647   # largest magnitude a number may have after scaling
DECIMALS = {"i": 0, "d": 3}


class ProtocolError(ValueError):
    """A line that is not valid protocol, or a declaration that cannot be parsed."""


class CommandError(ValueError):
    """A command line the firmware would reject; ``code`` is its error code."""

    def __init__(self, code: int, detail: str = ""):
        self.code = code
        err = ERRORS.get(code)
        super().__init__(f"error:{code} {err.text if err else '?'}" + (f" ({detail})" if detail else ""))


# --- declaration parsing --------------------------------------------------------

@dataclass(frozen=True)
class Arg:
    name: str
    kind: str                  # i integer, d decimal (thousandths), w word choice, s text
    required: bool
    min: Optional[int] = None  # scaled like the value (thousandths for d)
    max: Optional[int] = None
    choices: Tuple[str, ...] = ()


@dataclass(frozen=True)
class Command:
    id: str
    name: str
    synopsis: str
    help: str
    args: Tuple[Arg, ...]

    @property
    def usage(self) -> str:
        """The synopsis as `help` prints it: names (or choices) in brackets."""
        parts = []
        for a in self.args:
            o, c = ("<", ">") if a.required else ("[", "]")
            parts.append(o + ("|".join(a.choices) if a.kind == "w" else a.name) + c)
        return " ".join(parts)


@dataclass(frozen=True)
class Error:
    code: int
    id: str
    text: str


@dataclass(frozen=True)
class Setting:
    id: str
    name: str
    type: str
    min: int
    max: int
    default: int
    unit: str
    help: str


_COMMENT = re.compile(r"/\*.*?\*/|//[^\n]*", re.S)
_STRING = re.compile(r'"((?:[^"\\]|\\.)*)"')


def _split_args(body: str) -> List[str]:
    """Splits a macro argument list at top-level commas (not inside strings)."""
    out, cur, depth, in_str, esc = [], [], 0, False, False
    for ch in body:
        if in_str:
            cur.append(ch)
            if esc:
                esc = False
            elif ch == "\\":
                esc = True
            elif ch == '"':
                in_str = False
            continue
        if ch == '"':
            in_str = True
        elif ch == "(":
            depth += 1
        elif ch == ")":
            depth -= 1
        elif ch == "," and depth == 0:
            out.append("".join(cur).strip())
            cur = []
            continue
        cur.append(ch)
    out.append("".join(cur).strip())
    return out


def _macro_calls(text: str, macro: str) -> List[List[str]]:
    """Every `macro(...)` invocation in a .def file, as argument lists."""
    text = _COMMENT.sub(" ", text)
    calls = []
    pos = 0
    pat = re.compile(r"\b" + re.escape(macro) + r"\s*\(")
    while True:
        m = pat.search(text, pos)
        if not m:
            break
        i, depth, in_str, esc = m.end(), 1, False, False
        while depth:
            if i >= len(text):
                raise ProtocolError(f"unterminated {macro}( in declaration")
            ch = text[i]
            if in_str:
                if esc:
                    esc = False
                elif ch == "\\":
                    esc = True
                elif ch == '"':
                    in_str = False
            elif ch == '"':
                in_str = True
            elif ch == "(":
                depth += 1
            elif ch == ")":
                depth -= 1
            i += 1
        calls.append(_split_args(text[m.end():i - 1]))
        pos = i
    return calls


def _c_string(arg: str) -> str:
    """Value of one or more adjacent C string literals."""
    parts = _STRING.findall(arg)
    if not parts or _STRING.sub("", arg).strip():
        raise ProtocolError(f"expected a string literal, got {arg!r}")
    return "".join(bytes(p, "ascii").decode("unicode_escape") for p in parts)


def _c_int(arg: str) -> int:
    m = re.fullmatch(r"\(?\s*(-?)\s*(0x[0-9a-fA-F]+|\d+)[uUlL]*\s*\)?", arg.strip())
    if not m:
        raise ProtocolError(f"expected an integer, got {arg!r}")
    v = int(m.group(2), 0)
    return -v if m.group(1) else v


def parse_fixed(text: str, decimals: int) -> int:
    """The firmware's number grammar: [+-] digits [. digits], at most
    `decimals` fractional digits, scaled by 10**decimals, magnitude at most
    2147483647. Raises ValueError otherwise."""
    m = re.fullmatch(r"([+-]?)(\d*)(?:\.(\d*))?", text)
    if not m or not (m.group(2) or m.group(3)):
        raise ValueError(f"bad number {text!r}")
    frac = m.group(3) or ""
    if len(frac) > decimals:
        raise ValueError(f"too many decimals in {text!r}")
    v = int((m.group(2) or "0") + frac.ljust(decimals, "0") or "0")
    if v > MAG_MAX:
        raise ValueError(f"number out of range {text!r}")
    return -v if m.group(1) == "-" else v


def parse_synopsis(synopsis: str) -> Tuple[Arg, ...]:
    """Argument specs of a synopsis (grammar in con_commands.def)."""
    args: List[Arg] = []
    for spec in synopsis.split():
        m = re.fullmatch(r"([<\[])([A-Za-z_][A-Za-z0-9_]*):([idws])(?::(.*))?([>\]])", spec)
        if not m or {"<": ">", "[": "]"}[m.group(1)] != m.group(5):
            raise ProtocolError(f"bad argument spec {spec!r}")
        name, kind, params = m.group(2), m.group(3), m.group(4)
        required = m.group(1) == "<"
        if required and args and not args[-1].required:
            raise ProtocolError(f"required argument after an optional one in {synopsis!r}")
        lo = hi = None
        choices: Tuple[str, ...] = ()
        if kind in DECIMALS and params is not None:
            lo_s, _, hi_s = params.partition(":")
            lo, hi = parse_fixed(lo_s, DECIMALS[kind]), parse_fixed(hi_s, DECIMALS[kind])
        elif kind == "w":
            if not params:
                raise ProtocolError(f"word argument without choices: {spec!r}")
            choices = tuple(params.split("|"))
        elif params is not None:
            raise ProtocolError(f"text argument takes no parameters: {spec!r}")
        args.append(Arg(name, kind, required, lo, hi, choices))
    if len(args) > MAX_ARGS:
        raise ProtocolError(f"more than {MAX_ARGS} arguments in {synopsis!r}")
    if len(synopsis) >= SYN_MAX:
        raise ProtocolError(f"synopsis longer than {SYN_MAX - 1} characters: {synopsis!r}")
    return tuple(args)


def load_commands(path: Path = COMMANDS_DEF) -> Tuple[Command, ...]:
    cmds = []
    for a in _macro_calls(path.read_text(encoding="ascii"), "CON_CMD"):
        if len(a) != 4:
            raise ProtocolError(f"CON_CMD takes 4 arguments: {a}")
        syn = _c_string(a[2])
        cmds.append(Command(a[0], _c_string(a[1]), syn, _c_string(a[3]), parse_synopsis(syn)))
    return tuple(cmds)


def load_errors(path: Path = ERRORS_DEF) -> Dict[int, Error]:
    errs: Dict[int, Error] = {}
    for a in _macro_calls(path.read_text(encoding="ascii"), "CON_ERR"):
        if len(a) != 3:
            raise ProtocolError(f"CON_ERR takes 3 arguments: {a}")
        e = Error(_c_int(a[0]), a[1], _c_string(a[2]))
        if e.code in errs:
            raise ProtocolError(f"duplicate error code {e.code}")
        errs[e.code] = e
    return errs


def load_settings(path: Path = SETTINGS_DEF) -> Tuple[Setting, ...]:
    out = []
    for a in _macro_calls(path.read_text(encoding="ascii"), "STORE_SETTING"):
        if len(a) != 8:
            raise ProtocolError(f"STORE_SETTING takes 8 arguments: {a}")
        out.append(Setting(a[0], _c_string(a[1]), a[2], _c_int(a[3]), _c_int(a[4]),
                           _c_int(a[5]), _c_string(a[6]), _c_string(a[7])))
    return tuple(out)


COMMANDS: Tuple[Command, ...] = load_commands()
COMMANDS_BY_NAME: Dict[str, Command] = {c.name: c for c in COMMANDS}
ERRORS: Dict[int, Error] = load_errors()
ERROR_CODES: Dict[str, int] = {e.id: e.code for e in ERRORS.values()}
SETTINGS: Tuple[Setting, ...] = load_settings()
SETTINGS_BY_NAME: Dict[str, Setting] = {s.name: s for s in SETTINGS}


# --- command lines ---------------------------------------------------------------

Value = Union[int, str]


def check_command(line: str) -> Tuple[Command, List[Optional[Value]]]:
    """Validates a command line as the firmware does and returns the command
    and its argument values (ints for i/d, the choice index for w, the text
    for s, None when absent). Raises CommandError with the firmware's code.
    Empty lines are valid in the protocol (reply `ok`) but name no command:
    ValueError. Line assembly details (backspace, `!`) are not modelled."""
    if len(line) > LINE_MAX:
        raise CommandError(ERROR_CODES["LINE_TOO_LONG"])
    if any(not (0x20 <= ord(ch) <= 0x7E) and ch != "\t" for ch in line):
        raise CommandError(ERROR_CODES["BAD_CHAR"])
    toks = line.replace("\t", " ").split()
    if not toks:
        raise ValueError("empty line")
    cmd = COMMANDS_BY_NAME.get(toks[0].lower())
    if cmd is None:
        raise CommandError(ERROR_CODES["UNKNOWN_COMMAND"], toks[0])
    values: List[Optional[Value]] = []
    for i, a in enumerate(cmd.args):
        if i + 1 >= len(toks):
            if a.required:
                raise CommandError(ERROR_CODES["MISSING_ARG"], a.name)
            values.append(None)
            continue
        t = toks[i + 1]
        if a.kind in DECIMALS:
            try:
                v = parse_fixed(t, DECIMALS[a.kind])
            except ValueError:
                raise CommandError(ERROR_CODES["BAD_NUMBER"], t) from None
            lo = -MAG_MAX if a.min is None else a.min
            hi = MAG_MAX if a.max is None else a.max
            if not lo <= v <= hi:
                raise CommandError(ERROR_CODES["OUT_OF_RANGE"],
                                   f"{a.name} {t} is not in {arg_range_text(a)}")
            values.append(v)
        elif a.kind == "w":
            if t not in a.choices:
                raise CommandError(ERROR_CODES["BAD_WORD"], f"{a.name} {t} is not one of "
                                   + ", ".join(a.choices))
            values.append(a.choices.index(t))
        else:
            values.append(t)
    if len(toks) - 1 > len(cmd.args):
        raise CommandError(ERROR_CODES["TOO_MANY_ARGS"])
    return cmd, values


def arg_bounds(command: str, arg: str) -> Tuple[float, float]:
    """(min, max) of a numeric argument in its own unit (newtons for
    `tension_N`), from the declaration."""
    cmd = COMMANDS_BY_NAME[command]
    for a in cmd.args:
        if a.name == arg:
            if a.min is None or a.max is None:
                raise ProtocolError(f"{command} {arg} declares no range")
            scale = 10 ** DECIMALS[a.kind]
            return a.min / scale, a.max / scale
    raise ProtocolError(f"{command} has no argument {arg!r}")


def arg_range_text(a: Arg) -> str:
    """`lo..hi` of a numeric argument as the user types it."""
    if a.min is None or a.max is None:
        return "any number"
    scale = 10 ** DECIMALS[a.kind]
    return f"{a.min / scale:g}..{a.max / scale:g}"


# --- replies and reports ---------------------------------------------------------

_REPORT = re.compile(r"<([A-Za-z_][A-Za-z0-9_]*)((?:\s+[^\s=>]+=(?:\"[^\"]*\"|[^\s\">]*))*)\s*>")
_FIELD = re.compile(r"([^\s=>]+)=(\"[^\"]*\"|[^\s\">]*)")
_INT = re.compile(r"-?\d+")


def parse_line(line: str) -> dict:
    """Parses one line from the firmware (CR/LF stripped).

    ``ok``                      -> {"type": "ok"}
    ``error:<code> <text>``     -> {"type": "error", "code": int, "name": id or None,
                                    "text": str}
    ``<kind key=value ...>``    -> {"type": "report", "kind": str, "fields": {key: value}}
                                   integer values become int, quotes are removed, other
                                   values (decimals like 0.800) stay str.
    Anything else raises ProtocolError."""
    line = line.rstrip("\r\n")
    if line == "ok":
        return {"type": "ok"}
    m = re.fullmatch(r"error:(\d+) (.*)", line)
    if m:
        code = int(m.group(1))
        err = ERRORS.get(code)
        return {"type": "error", "code": code, "name": err.id if err else None,
                "text": m.group(2)}
    m = _REPORT.fullmatch(line)
    if m:
        fields: Dict[str, Value] = {}
        for k, v in _FIELD.findall(m.group(2)):
            if v.startswith('"'):
                fields[k] = v[1:-1]
            elif _INT.fullmatch(v):
                fields[k] = int(v)
            else:
                fields[k] = v
        return {"type": "report", "kind": m.group(1), "fields": fields}
    raise ProtocolError(f"not a protocol line: {line!r}")


def is_final(reply: dict) -> bool:
    """True for the one reply that ends a command (ok or error)."""
    return reply["type"] in ("ok", "error")


# --- documentation -------------------------------------------------------------

def _md_escape(s: str) -> str:
    return s.replace("|", "\\|")


def _arg_doc(a: Arg) -> str:
    if a.kind == "w":
        what = "one of " + ", ".join(f"`{c}`" for c in a.choices)
    elif a.kind == "s":
        what = "text"
    else:
        unit = "decimal, 3 places" if a.kind == "d" else "integer"
        if a.min is not None:
            scale = 10 ** DECIMALS[a.kind]
            fmt = (lambda v: f"{v / scale:g}") if scale > 1 else str
            what = f"{unit}, {fmt(a.min)} to {fmt(a.max)}"
        else:
            what = unit
    return f"`{a.name}` ({'required' if a.required else 'optional'}; {what})"


def markdown_sections() -> Dict[str, str]:
    """The generated tables of docs/console.md, by section name."""
    cmd = ["| command | arguments | does |", "| --- | --- | --- |"]
    for c in COMMANDS:
        args = "<br>".join(_arg_doc(a) for a in c.args) or "none"
        cmd.append(f"| `{c.name}` | {_md_escape(args)} | {_md_escape(c.help)} |")
    err = ["| code | name | text |", "| --- | --- | --- |"]
    for e in sorted(ERRORS.values(), key=lambda e: e.code):
        err.append(f"| {e.code} | `{e.id}` | {_md_escape(e.text)} |")
    st = ["| name | type | min | max | default | unit | meaning |",
          "| --- | --- | --- | --- | --- | --- | --- |"]
    for s in SETTINGS:
        st.append(f"| `{s.name}` | {s.type} | {s.min} | {s.max} | {s.default} | {s.unit} | "
                  f"{_md_escape(s.help)} |")
    return {"commands": "\n".join(cmd), "errors": "\n".join(err), "settings": "\n".join(st)}


_SECTION = re.compile(r"(<!-- BEGIN GENERATED (\w+)[^>]*-->\n)(.*?)(<!-- END GENERATED \2 -->)", re.S)


def doc_sections(text: str) -> Dict[str, str]:
    """The generated sections found in a document, by name."""
    return {m.group(2): m.group(3).rstrip("\n") for m in _SECTION.finditer(text)}


def update_doc(text: str) -> str:
    """The document with every generated section replaced by the current tables."""
    gen = markdown_sections()

    def repl(m: "re.Match[str]") -> str:
        if m.group(2) not in gen:
            raise ProtocolError(f"unknown generated section {m.group(2)!r}")
        return m.group(1) + gen[m.group(2)] + "\n" + m.group(4)

    return _SECTION.sub(repl, text)


def main(argv: Optional[List[str]] = None) -> int:
    p = argparse.ArgumentParser(prog="python -m hallhome.protocol", description=__doc__.split("\n")[0])
    p.add_argument("--markdown", action="store_true", help="print the generated tables")
    p.add_argument("--update-docs", action="store_true",
                   help=f"rewrite the generated sections of {CONSOLE_DOC.relative_to(PROJECT_ROOT)}")
    ns = p.parse_args(argv)
    if ns.update_docs:
        CONSOLE_DOC.write_text(update_doc(CONSOLE_DOC.read_text(encoding="utf-8")), encoding="utf-8")
        return 0
    for name, table in markdown_sections().items():
        print(f"<!-- BEGIN GENERATED {name} -->\n{table}\n<!-- END GENERATED {name} -->\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
