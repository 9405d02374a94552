"""Every command shown in README.md, sim/README.md and docs/*.md runs here,
or is checked cheaply, so documentation examples cannot rot.

Commands are collected from fenced shell blocks, indented blocks and inline
code spans that start with a command (make, hallhome, hh_bench, ...). Each
one must match a rule below, which says how it is exercised:

- run: as shown (placeholders filled in, output redirected into a temporary
  directory), exit status 0;
- dry: `make -n` (the target exists and resolves), for targets that are
  suites of `make test` themselves, take longer than a test should, rewrite
  committed files, or need a board;
- help: the subcommand or option exists (`--help`), for commands that talk to
  a board on a serial port;
- special checks (the interactive bench, the HEX an uploader is given).

A command that matches no rule fails the test: a new example needs a rule.
"""

import os
import re
import shlex
import shutil
import signal
import subprocess
import time
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
DOCS = [ROOT / "README.md", ROOT / "sim" / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
HALLHOME = ROOT / ".venv" / "bin" / "hallhome"
BENCH = ROOT / "build" / "sim" / "hh_bench"
PAPER = "lookup_tables/robots/paper_2seg.toml"
COMMAND = re.compile(r"^(make|\.venv/bin/hallhome|hallhome|build/sim/hh_bench|hh_bench|"
                     r"arduino-cli|avrdude|pytest|\.venv/bin/pytest)(\s|$)")
SHELL_FENCES = ("", "sh", "bash", "console", "shell")

# `make sim` and the files it keeps under build/ are shared: one of these
# tests at a time (conftest.py), in whichever worker of `pytest -n`.


def _strip_comment(line: str) -> str:
    return re.split(r"\s+#\s", line, maxsplit=1)[0].strip()


def collect() -> dict[str, str]:
    """command -> where it is first shown (file:line)."""
    found: dict[str, str] = {}

    def add(cmd, path, lineno):
        cmd = " ".join(cmd.split())
        if COMMAND.match(cmd):
            found.setdefault(cmd, f"{path.relative_to(ROOT)}:{lineno}")

    for path in DOCS:
        lines = path.read_text(encoding="utf-8").splitlines()
        fence = None
        prev_blank = True
        for n, line in enumerate(lines, 1):
            m = re.match(r"^\s*```(\w*)", line)
            if m:
                fence = None if fence is not None else m.group(1)
                continue
            if fence is not None:
                if fence in SHELL_FENCES:
                    add(_strip_comment(line), path, n)
                continue
            if line.startswith("    ") and (prev_blank or lines[n - 2].startswith("    ")):
                add(_strip_comment(line), path, n)
            for span in re.findall(r"`([^`]+)`", line):
                add(span, path, n)
            prev_blank = not line.strip()
    return found


def run(args, timeout=300, **kw):
    r = subprocess.run(args, cwd=ROOT, capture_output=True, text=True, timeout=timeout, **kw)
    r.out = r.stdout + r.stderr
    return r


def fill(cmd: str, tmp: Path) -> list[str]:
    """The command with its placeholders filled in, as argv."""
    subs = [("<robot>", "paper_2seg"), ("SEED=N", "SEED=3"), ("TENSION=T", "TENSION=0.8"),
            ("[IDENTIFY=0]", "IDENTIFY=0"), ("<name>", "sensor_unplug"), ("FAULT=...", "FAULT=sensor_unplug"),
            ("PORT=...", "PORT=/dev/null"), ("DIR/", f"{tmp}/"), ("=DIR", f"={tmp}"), ("[--check]", ""),
            ("ROBOT.toml ...", PAPER), ("ROBOT.toml N ...", f"{PAPER} 0 0 0 1.5 0 0"),
            ("[ROBOT.toml]", PAPER), ("ROBOT.toml OUT", f"{PAPER} {tmp}/plant.cfg"),
            ("[--robot R.toml [--write]]", f"--robot {PAPER}"), ("ROBOT.toml...", PAPER), ("ROBOT.toml", PAPER),
            ("T1 T2 ...", "0 0 0 1.5 0 0"), ("--out-dir DIR", f"--out-dir {tmp}"),
            ("DATA.csv", "lookup_tables/examples/paper_fig1_synthetic.csv"),
            ("[--robot R.toml]", f"--robot {PAPER}")]
    for a, b in subs:
        cmd = cmd.replace(a, b)
    argv = cmd.split()
    if argv[0] == ".venv/bin/hallhome":
        argv[0] = "hallhome"
    if argv[0] == "hallhome":
        argv[0] = str(HALLHOME)
    return argv


# --- how each command is exercised ------------------------------------------------

_PASSED: set = set()


def filled(cmd):
    """The command as it runs (argv, a fixed stand-in for the temporary
    directory): examples that differ only in how they are written match."""
    return tuple(fill(cmd, Path("/TMP")))


def once(check=None, *, key=filled):
    """Examples whose ``key`` is the same run once (per worker): ``@once``, or
    ``@once(key=...)``."""
    if check is None:
        return lambda c: once(c, key=key)

    def wrapper(cmd, tmp):
        k = (check.__name__, key(cmd))
        if k in _PASSED:
            return
        check(cmd, tmp)
        _PASSED.add(k)
    wrapper.__name__ = check.__name__
    return wrapper


@once
def do_run(cmd, tmp):
    argv = fill(cmd, tmp)
    r = run(argv)
    assert r.returncode == 0, f"{' '.join(argv)}:\n{r.out[-3000:]}"
    return r


def do_make_run(cmd, tmp):
    argv = fill(cmd, tmp)
    r = run(argv)
    assert r.returncode == 0, f"{' '.join(argv)}:\n{r.out[-3000:]}"
    assert "No rule to make target" not in r.out


def sim_argv(cmd, tmp):
    # A fixed SEED: with a random one the outcome depends on the draw (some
    # seeds land outside the 10 % tolerance, sim/README.md).
    argv = fill(cmd, tmp)
    if not any(a.startswith("SEED=") for a in argv):
        argv.append("SEED=3")
    return argv


def sim_key(cmd):
    """`make sim` and `make sim SEED=N` are one command; so are the same
    variables in any order."""
    argv = sim_argv(cmd, Path("/TMP"))
    return (argv[0], argv[1], *sorted(argv[2:]))


@once(key=sim_key)
def do_make_sim(cmd, tmp):
    argv = sim_argv(cmd, tmp)
    r = run(argv)
    assert r.returncode == 0, f"{' '.join(argv)}:\n{r.out[-3000:]}"
    assert re.search(r"^\s+0\s+1\s+\d+ .*\s(pass|-)$", r.stdout, re.M), r.stdout[-2000:]


def do_pytest_options(cmd, tmp):
    """The options select among the suites' tests: a collection of one file
    with them leaves some out (`-m "not slow"`: the long fits)."""
    argv = shlex.split(cmd)
    r = run([str(ROOT / ".venv" / "bin" / "pytest"), *argv[1:], "--collect-only", "-q",
             "tests/host/test_identify.py"])
    assert r.returncode == 0 and re.search(r"\d+/\d+ tests collected \(\d+ deselected\)", r.out), \
        r.out[-2000:]


def do_dry(cmd, tmp):
    argv = fill(cmd, tmp)
    r = run([argv[0], "-n", *argv[1:]], timeout=120)
    assert r.returncode == 0, r.out[-3000:]
    assert "No rule to make target" not in r.out
    return r


def do_dry_chaos(cmd, tmp):
    # a table row: the target, its VAR=value settings (brackets mark optional
    # ones, shown with their defaults), then prose
    words = cmd.replace("[", " ").replace("]", " ").split()
    argv = [w for w in words[:2] if w in ("make",) or w.startswith("chaos")]
    argv += [w for w in words[2:] if re.fullmatch(r"[A-Z0-9]+=\d+", w)]
    argv += ["SEED=1"] if "chaos-replay" in argv and not any(w.startswith("SEED=") for w in argv) \
        else []
    r = run([argv[0], "-n", *argv[1:]], timeout=120)
    assert r.returncode == 0 and "No rule to make target" not in r.out, r.out[-3000:]


def do_dry_flash(cmd, tmp):
    r = do_dry(cmd, tmp)
    robot = re.search(r"ROBOT=(\S+)", " ".join(fill(cmd, tmp)))
    robot = robot.group(1) if robot else "paper_2seg"
    hexfile = run(["make", "-s", "fw-path", f"ROBOT={robot}"]).stdout.strip()[:-4] + ".hex"
    assert f"flash:w:{hexfile}:i" in r.stdout


def do_dry_learned(cmd, tmp):
    # A learned table needs targets measured on a board (hallhome learn); a
    # copy of the model's table under the learned name stands in for it.
    shutil.copy(ROOT / "lookup_tables" / "generated" / "paper_2seg.c",
                tmp / "paper_2seg_learned.c")
    argv = fill(cmd, tmp)
    if not any(a.startswith("TABLES_DIR=") for a in argv):
        argv.append(f"TABLES_DIR={tmp}")
    r = run(["make", "-n", *argv[1:]])
    assert r.returncode == 0, r.out
    assert f"{tmp}/paper_2seg_learned.c -o build/fw/paper_2seg_learned/avr/" in r.stdout


def do_dry_identified(cmd, tmp):
    # The identified description and its table come from `make sim`'s
    # identification (tests/sim/test_make.py runs it); copies of the
    # nominal ones under the identified name stand in for them.
    shutil.copy(ROOT / "lookup_tables" / "robots" / "paper_2seg.toml", tmp / "paper_2seg_id.toml")
    shutil.copy(ROOT / "lookup_tables" / "generated" / "paper_2seg.c", tmp / "paper_2seg_id.c")
    argv = fill(cmd, tmp)
    r = run(["make", "-n", *argv[1:], f"ROBOTS_DIR={tmp}", f"TABLES_DIR={tmp}"])
    assert r.returncode == 0, r.out
    assert f"{tmp}/paper_2seg_id.c -o build/fw/paper_2seg_id/avr/" in r.stdout


def do_help(cmd, tmp):
    """The subcommand(s) exist and know every option the example shows."""
    argv = fill(cmd, tmp)
    subs = [a for a in argv[1:2] if re.match(r"^[a-z-]+(\|[a-z-]+)*$", a)]
    options = re.findall(r"(?:^|\s|\[)(--?[A-Za-z][\w-]*)", cmd)
    for sub in (subs[0].split("|") if subs else [None]):
        r = run([str(HALLHOME), *([sub] if sub else []), "--help"])
        assert r.returncode == 0 and "Usage:" in r.out, r.out
        for opt in options:
            assert re.search(rf"(^|[\s,/]){re.escape(opt)}\b", r.out), f"{sub}: {opt}"


def do_fw_path(cmd, tmp):
    r = run(fill(cmd, tmp))
    assert r.returncode == 0 and r.stdout == "build/fw/paper_2seg/hallhome-paper_2seg.elf\n"


@once
def do_tables(cmd, tmp):
    argv = fill(cmd, tmp)
    r = run([*argv, "--out-dir", str(tmp)])
    assert r.returncode == 0, r.out
    assert (tmp / "paper_2seg.c").read_bytes() == \
        (ROOT / "lookup_tables" / "generated" / "paper_2seg.c").read_bytes()


def do_learned_option(cmd, tmp):
    # needs learned_<robot>.json exported from a board by `hallhome learn`;
    # tests/host/test_tablegen_learned.py runs the option on made-up files
    r = run([str(HALLHOME), "tables", "--help"])
    assert "--learned" in r.out


@once
def do_characterize(cmd, tmp):
    argv = fill(cmd, tmp)
    if "DATA.csv" not in cmd and len(argv) == 2:
        argv.append("lookup_tables/examples/paper_fig1_synthetic.csv")
    r = run([*argv, "--plot", str(tmp / "fit.png")])
    if "--robot" in argv:
        # the paper's figure-1 data contradict the paper robot's magnet (85 % rms):
        # characterize says so and exits 1 (docs/operator.md); --write is not
        # run against the committed TOML
        assert r.returncode == 1 and "does not explain these data" in r.out, r.out
    else:
        assert r.returncode == 0 and "R^2" in r.out, r.out


def do_bench_option(cmd, tmp):
    r = run([str(BENCH), "--help"])
    assert r.returncode == 0
    for opt in re.findall(r"--[a-z-]+", cmd):
        assert opt in r.out, opt


def do_upload(cmd, tmp):
    # arduino-cli is not installed here and an upload needs a board: the HEX
    # it is given must be the one `make firmware` writes
    hexfile = re.search(r"--input-file (\S+)", cmd).group(1)
    elf = run(["make", "-s", "fw-path"]).stdout.strip()
    assert hexfile == elf[:-4] + ".hex"


def do_interactive(cmd, tmp):
    link = ROOT / "build" / "sim" / "console"
    if link.is_symlink():
        link.unlink()
    p = subprocess.Popen(fill(cmd, tmp), cwd=ROOT, stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                         stderr=subprocess.STDOUT, text=True, start_new_session=True)
    try:
        deadline = time.monotonic() + 120
        while not link.exists() and time.monotonic() < deadline and p.poll() is None:
            time.sleep(0.2)
        assert link.exists(), "no pty link build/sim/console"
        assert os.readlink(link).startswith("/dev/pts/")
        p.stdin.write("quit\n")  # what the README says stops it
        p.stdin.flush()
        out, _ = p.communicate(timeout=60)
    finally:
        if p.poll() is None:
            os.killpg(p.pid, signal.SIGTERM)
            p.wait()
    assert p.returncode == 0, out[-2000:]
    assert "quit" in out and "console pty: /dev/pts/" in out


def do_identify(cmd, tmp):
    """`hallhome identify [fit|install|survey]`: the subcommand and every
    option shown exist (tests/host/test_identify.py runs the fit on synthetic
    surveys, tests/sim/test_operator_bench.py the install on the bench,
    tests/sim/test_survey_bench.py the survey)."""
    argv = fill(cmd, tmp)
    sub = [argv[2]] if len(argv) > 2 and argv[2] in ("fit", "install", "survey") else []
    r = run([str(HALLHOME), "identify", *sub, "--help"])
    assert r.returncode == 0 and "Usage:" in r.out, r.out
    for opt in re.findall(r"(?:^|\s|\[)(--[A-Za-z][\w-]*)", cmd):
        assert re.search(rf"(^|[\s,/]){re.escape(opt)}\b", r.out), opt


DRY_WHY = ("a suite of `make test` or longer than a test should take: dry run", do_dry)
BOARD_WHY = ("talks to a board on a serial port (tests/sim/test_operator_bench.py runs the "
             "operator tools against the virtual bench): --help", do_help)

# (pattern, (why, check)), first match wins
RULES = [
    (r"^make sim INTERACTIVE=1$", ("pty, real time, stopped with `quit`", do_interactive)),
    (r"^make sim(\s|$)", ("run (3-30 s with the identification), SEED=3 when none is shown",
                          do_make_sim)),
    (r"^make (sim-test|test|bench|bench-check|unit|host-test|pytest-suites|lint|fuzz|tables-check)(\s|$)",
     DRY_WHY),
    (r"^make chaos(-\w+)?(\s|$)", ("runs for minutes to hours on the bench: dry run",
                                   do_dry_chaos)),
    (r"^make format$", ("rewrites every C file in place: dry run", do_dry)),
    (r"^make tables$", ("rewrites the committed tables (make tables-check runs for real): dry run",
                        do_dry)),
    (r"^make flash(\s|$)", ("needs a board: dry run, avrdude gets ROBOT's HEX", do_dry_flash)),
    (r"^make firmware ROBOT=<robot>_learned", ("needs targets learned on a board: dry run",
                                                do_dry_learned)),
    (r"^make firmware ROBOT=<robot>_id", ("needs an identified robot (make sim): dry run",
                                          do_dry_identified)),
    (r"^make( firmware| size| help)?$", ("run", do_make_run)),
    (r"^make -s fw-path$", ("run: one line", do_fw_path)),
    (r"^hallhome (check|tables)$", ("a name in prose, arguments required: --help", do_help)),
    (r"^(\.venv/bin/)?hallhome tables .*--learned", ("needs a learned file from a board",
                                                    do_learned_option)),
    (r"^(\.venv/bin/)?hallhome tables ", ("run into a temporary directory", do_tables)),
    (r"^hallhome (check|solve|plot|bench)(\s|$)", ("run", do_run)),
    (r"^hallhome characterize", ("run, plot into a temporary directory", do_characterize)),
    (r"^hallhome (ports|console|status|calibrate|learn|learned|forget|history|monitor|export|"
     r"rehome|home|release)(\s|\||$)", BOARD_WHY),
    (r"^hallhome plant-config", ("run into a temporary directory", do_run)),
    (r"^(\.venv/bin/)?hallhome identify(\s|$)", ("needs a survey: its options exist",
                                                 do_identify)),
    (r"^hallhome$", ("--help", do_help)),
    (r"^(\.venv/bin/)?pytest ", ("runs the suites' tests: its options on a collection",
                                 do_pytest_options)),
    (r"^(build/sim/)?hh_bench(\s|$)", ("its options exist (the bench runs in test_bench.py)",
                                       do_bench_option)),
    (r"^arduino-cli upload ", ("not installed, needs a board: the HEX path", do_upload)),
]

COMMANDS = collect()


# The rules that run `make` for real (not `-n`): they share what `make sim`
# keeps under build/ (conftest.py, make_sim_lock); the others run beside them.
SHARES_MAKE_SIM = (do_make_sim, do_interactive, do_make_run)


def rule_for(cmd):
    for pattern, rule in RULES:
        if re.search(pattern, cmd):
            return rule
    return None


def test_the_docs_show_commands_and_every_one_has_a_rule():
    assert len(COMMANDS) > 30  # the collector still finds them
    missing = [f"{where}: {cmd}" for cmd, where in COMMANDS.items() if rule_for(cmd) is None]
    assert not missing, "documented commands without a rule here:\n" + "\n".join(missing)


def _shares_make_sim(cmd):
    rule = rule_for(cmd)
    return rule is not None and rule[1] in SHARES_MAKE_SIM


@pytest.mark.parametrize("cmd", [
    pytest.param(c, id=c[:60], marks=[pytest.mark.make_sim] if _shares_make_sim(c) else [])
    for c in sorted(COMMANDS)])
def test_documented_command(cmd, tmp_path, request):
    rule = rule_for(cmd)
    if rule is None:
        pytest.fail(f"{COMMANDS[cmd]}: no rule for {cmd!r}")
    if request.node.get_closest_marker("make_sim"):
        request.getfixturevalue("make_sim_lock")
    rule[1](cmd, tmp_path)
