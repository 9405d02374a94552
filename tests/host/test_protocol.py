"""hallhome.protocol against the firmware's declarations and the C console.

The .def files are read here a second, independent way (the C preprocessor
expands them into Python literals), so a drift between protocol.py's parser
and the declarations fails. A small native program built from the
console's sources (lib/console/*.c) answers the same command lines as
check_command(), so a drift between the host's validation and the
firmware's fails too.
"""

import ast
import re
import shutil
import subprocess
import textwrap

import pytest

from hallhome import protocol
from hallhome.paths import LIB_DIR, PROJECT_ROOT
from hallhome.protocol import CommandError, ProtocolError, check_command, parse_line

CC = shutil.which("gcc") or shutil.which("cc")
needs_cc = pytest.mark.skipif(CC is None, reason="no C compiler")


def preprocess(def_file, macro_def):
    """Expands a .def file with the given macro definition through cpp."""
    src = f"{macro_def}\n[\n#include \"{def_file}\"\n]\n"
    out = subprocess.run([CC, "-E", "-P", "-x", "c", "-"], input=src, capture_output=True,
                         text=True, check=True).stdout
    return ast.literal_eval(out)


@needs_cc
def test_commands_match_preprocessor():
    got = preprocess(LIB_DIR / "console/con_commands.def",
                     "#define CON_CMD(id, name, syn, help) (#id, name, syn, help),")
    assert [(c.id, c.name, c.synopsis, c.help) for c in protocol.COMMANDS] == got
    assert len(got) >= 16


@needs_cc
def test_errors_match_preprocessor():
    got = preprocess(LIB_DIR / "console/con_errors.def",
                     "#define CON_ERR(code, id, text) (code, #id, text),")
    assert sorted((e.code, e.id, e.text) for e in protocol.ERRORS.values()) == sorted(got)
    assert len({c for c, _, _ in got}) == len(got)  # codes unique


@needs_cc
def test_settings_match_preprocessor():
    got = preprocess(LIB_DIR / "store/store_settings.def",
                     "#define STORE_SETTING(id, name, type, lo, hi, d, unit, help) "
                     "(#id, name, #type, lo, hi, d, unit, help),")
    assert [(s.id, s.name, s.type, s.min, s.max, s.default, s.unit, s.help)
            for s in protocol.SETTINGS] == got


def test_required_commands_and_settings_declared():
    names = set(protocol.COMMANDS_BY_NAME)
    for n in ["help", "version", "status", "sensors", "servos", "cal", "rehome", "home",
              "release", "learn", "table", "history", "get", "set", "save", "reboot"]:
        assert n in names
    for n in ["cal_tension", "target_mode", "filter_k", "approach_fast", "approach_slow",
              "bus_baud"]:
        assert n in protocol.SETTINGS_BY_NAME
    for s in protocol.SETTINGS:
        assert s.min <= s.default <= s.max
        assert s.type in ("U8", "U16", "U32", "I32")
        assert re.fullmatch(r"[a-z][a-z0-9_]{0,22}", s.name)  # store_setting_find's buffer
        assert '"' not in s.help and '"' not in s.unit
    assert len(protocol.SETTINGS) <= 24  # STORE_SETTING_MAX: room in the EEPROM layout
    assert len({s.name for s in protocol.SETTINGS}) == len(protocol.SETTINGS)


def test_declarations_are_well_formed():
    for c in protocol.COMMANDS:
        assert c.name == c.name.lower() and " " not in c.name
        assert '"' not in c.help
        assert len(c.synopsis) < protocol.SYN_MAX
        for a in c.args:
            if a.min is not None:
                assert a.min <= a.max
    assert protocol.ERRORS[1].id == "UNKNOWN_COMMAND"
    assert set(protocol.ERRORS) == set(range(1, len(protocol.ERRORS) + 1))


def test_synopsis_parser():
    args = protocol.COMMANDS_BY_NAME["cal"].args
    assert [(a.name, a.kind, a.required, a.min, a.max) for a in args] == [
        ("tension_N", "d", False, 10, 10000), ("tendon", "i", False, 0, 11)]
    assert protocol.COMMANDS_BY_NAME["servos"].args[0].choices == ("scan", "pos", "err")
    assert protocol.COMMANDS_BY_NAME["learn"].usage == "<tendon> <tension_N> [dB_uT]"
    with pytest.raises(ProtocolError):
        protocol.parse_synopsis("[a:i] <b:i>")
    with pytest.raises(ProtocolError):
        protocol.parse_synopsis("<a:x>")
    with pytest.raises(ProtocolError):
        protocol.parse_synopsis("<a:i]")
    with pytest.raises(ProtocolError):
        protocol.parse_synopsis("<a:i> <b:i> <c:i> <d:i>")
    with pytest.raises(ProtocolError):
        protocol.parse_synopsis("<" + "a" * protocol.SYN_MAX + ":i>")
    assert (protocol.LINE_MAX, protocol.MAX_ARGS) == (48, 3)


def test_def_parser_rejects_broken_files(tmp_path):
    p = tmp_path / "x.def"
    p.write_text('CON_ERR(1, A, "a")\nCON_ERR(1, B, "b")\n')
    with pytest.raises(ProtocolError):
        protocol.load_errors(p)
    p.write_text('CON_CMD(A, "a", "")\n')
    with pytest.raises(ProtocolError):
        protocol.load_commands(p)
    p.write_text('/* CON_CMD(X, "x", "", "commented out") */\nCON_CMD(A, "a", "", "one" " two")\n')
    assert [(c.name, c.help) for c in protocol.load_commands(p)] == [("a", "one two")]


def test_parse_fixed():
    assert protocol.parse_fixed("0.8", 3) == 800
    assert protocol.parse_fixed(".125", 3) == 125
    assert protocol.parse_fixed("+1.", 3) == 1000
    assert protocol.parse_fixed("-12", 0) == -12
    assert protocol.parse_fixed("2147483.647", 3) == 2147483647
    for bad in ["", "-", ".", "+.", "1.0001", "1e3", "--1", "1.2.3", " 1", "2147483.648"]:
        with pytest.raises(ValueError):
            protocol.parse_fixed(bad, 3)
    with pytest.raises(ValueError):
        protocol.parse_fixed("1.5", 0)


def test_parse_line_replies():
    assert parse_line("ok") == {"type": "ok"}
    assert parse_line("ok\r\n") == {"type": "ok"}
    assert parse_line("error:9 busy") == {"type": "error", "code": 9, "name": "BUSY",
                                          "text": "busy"}
    assert parse_line("error:999 from the future")["name"] is None
    for bad in ["OK", "error:x busy", "error:9", "<cal t=3", "cal t=3>", "", "<>", "ok ok"]:
        with pytest.raises(ProtocolError):
            parse_line(bad)


def test_parse_line_reports():
    r = parse_line('<cal t=3 pos=-123456 N=0.800 name=paper_2seg msg="two words" e="" f="a=b">')
    assert r == {"type": "report", "kind": "cal",
                 "fields": {"t": 3, "pos": -123456, "N": "0.800", "name": "paper_2seg",
                            "msg": "two words", "e": "", "f": "a=b"}}
    assert parse_line("<boot>") == {"type": "report", "kind": "boot", "fields": {}}
    assert protocol.is_final(parse_line("ok")) and not protocol.is_final(parse_line("<a b=1>"))


def test_check_command():
    cmd, v = check_command("cal 0.8 3")
    assert cmd.name == "cal" and v == [800, 3]
    assert check_command("CAL")[1] == [None, None]
    assert check_command("servos err")[1] == [2]
    assert check_command("set filter_k -5")[1] == ["filter_k", -5]
    cases = {"nope": "UNKNOWN_COMMAND", "cal x": "BAD_NUMBER", "cal 0": "OUT_OF_RANGE",
             "learn 1": "MISSING_ARG", "status 1": "TOO_MANY_ARGS", "servos foo": "BAD_WORD",
             "x" * (protocol.LINE_MAX + 1): "LINE_TOO_LONG", "st\x00atus": "BAD_CHAR", "st\u00e4tus": "BAD_CHAR"}
    for line, name in cases.items():
        with pytest.raises(CommandError) as ei:
            check_command(line)
        assert ei.value.code == protocol.ERROR_CODES[name], line
    with pytest.raises(ValueError):
        check_command("   ")


# --- the native console, built from the same sources ------------------------------

ECHO_C = textwrap.dedent(r"""
    #include <stdio.h>
    #include <string.h>
    #include "console/console.h"

    static int16_t rd(void *ctx) { int c = getchar(); (void)ctx; return c == EOF ? -1 : (int16_t)c; }
    static void wr(void *ctx, const char *b, uint8_t n) { (void)ctx; fwrite(b, 1, n, stdout); }
    static void cp(void *d, const void *s, size_t n) { memcpy(d, s, n); }
    static int8_t h(con_t *c, const con_args_t *a, void *app)
    {
        (void)app;
        con_report_begin(c, "args");
        con_report_int(c, "given", a->given);
        for (int i = 0; i < CON_MAX_ARGS; i++) {
            char k[4] = {'v', (char)('0' + i), 0, 0};
            if (a->given & (1u << i)) {
                if (a->s[i] != NULL) con_report_str(c, "s", a->s[i]);
                con_report_int(c, k, a->v[i]);
            }
        }
        con_report_end(c);
        return 0;
    }
    int main(void)
    {
        static con_handler_fn hs[CON_CMD_COUNT];
        con_io_t io = {NULL, rd, wr};
        con_rt_t rt = {0, 0};
        con_t con;
        for (int i = 0; i < CON_CMD_COUNT; i++) hs[i] = h;
        con_init(&con, &io, hs, NULL, cp, &rt);
        for (int i = 0; i < 200000; i++) con_poll(&con, 0);
        return 0;
    }
""")


@pytest.fixture(scope="module")
def native_console(tmp_path_factory):
    if CC is None:
        pytest.skip("no C compiler")
    d = tmp_path_factory.mktemp("con")
    (d / "echo.c").write_text(ECHO_C)
    exe = d / "echo"
    subprocess.run([CC, "-std=c99", "-I", str(LIB_DIR), "-o", str(exe), str(d / "echo.c")]
                   + [str(src) for src in sorted((LIB_DIR / "console").glob("*.c"))], check=True)

    def run(data: bytes):
        out = subprocess.run([str(exe)], input=data, capture_output=True, check=True).stdout
        return [parse_line(ln) for ln in out.decode("ascii").split("\r\n") if ln]
    return run


def test_native_help_matches_declaration(native_console):
    replies = native_console(b"help\n")
    assert replies[-1] == {"type": "ok"}
    helps = replies[:-1]
    assert [(r["kind"], r["fields"]["cmd"], r["fields"]["args"], r["fields"]["text"])
            for r in helps] == [("help", c.name, c.usage, c.help) for c in protocol.COMMANDS]


LINES = ["cal", "cal 0.8", "cal 0.8 3", "cal .01 11", "cal 10.001", "cal 1.2345", "cal 0.8 12",
         "cal 1 2 3", "learn", "learn 1", "learn 11 2.5", "learn 12 1", "learn 1 0", "servos",
         "servos scan", "servos pos", "servos err", "servos foo", "get", "get cal_tension",
         "set filter_k 4", "set filter_k", "set x 1.5", "set x 2147483648", "reboot 252",
         "reboot 253", "reboot -1", "reboot 0x1", "status", "status 1", "STATUS", "help 1",
         "nope", "x" * protocol.LINE_MAX, "x" * (protocol.LINE_MAX + 1), "cal\t0.5", "version", "rehome", "home", "release",
         "table", "history", "save", "sensors"]


def test_native_console_agrees_with_check_command(native_console):
    data = "".join(ln + "\n" for ln in LINES).encode("ascii")
    replies = native_console(data)
    finals = [r for r in replies if protocol.is_final(r)]
    assert len(finals) == len(LINES)  # exactly one reply per line
    it = iter(replies)
    for line in LINES:
        r = next(it)
        try:
            cmd, values = check_command(line)
        except CommandError as e:
            assert r["type"] == "error" and r["code"] == e.code, line
            continue
        if cmd.name == "help":
            continue
        assert r["type"] == "report" and r["kind"] == "args", line
        given = sum(1 << i for i, v in enumerate(values) if v is not None)
        assert r["fields"]["given"] == given, line
        for i, v in enumerate(values):
            if v is not None and not isinstance(v, str):
                assert r["fields"][f"v{i}"] == v, line
        assert next(it) == {"type": "ok"}, line


# --- docs/console.md ------------------------------------------------------------------

def test_console_doc_matches_declarations():
    text = protocol.CONSOLE_DOC.read_text(encoding="utf-8")
    found = protocol.doc_sections(text)
    want = protocol.markdown_sections()
    assert set(found) == set(want), "docs/console.md lacks a generated section"
    for name in want:
        assert found[name] == want[name], (
            f"docs/console.md section {name} is stale: run "
            "`.venv/bin/python -m hallhome.protocol --update-docs`")
    assert protocol.update_doc(text) == text
    assert f"At most {protocol.LINE_MAX} characters per line" in text


def test_markdown_cli(capsys):
    assert protocol.main(["--markdown"]) == 0
    out = capsys.readouterr().out
    assert "<!-- BEGIN GENERATED commands -->" in out and "| `cal` |" in out


def test_every_error_and_command_documented():
    text = (PROJECT_ROOT / "docs/console.md").read_text(encoding="utf-8")
    for c in protocol.COMMANDS:
        assert f"`{c.name}`" in text
    for e in protocol.ERRORS.values():
        assert f"| {e.code} | `{e.id}` |" in text
