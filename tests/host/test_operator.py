"""Operator commands: the parts that need no board (conversions, report
bookkeeping, output, option ranges, port listing), and command logic
against a scripted board (fakeboard.FakeBoard) where the virtual bench
cannot produce the case on demand. Every subcommand also runs against the
firmware in tests/sim/test_operator_bench.py."""

import json

import click
import pytest
from click.testing import CliRunner
from fakeboard import FakeBoard, rep, use

from hallhome import client as hc
from hallhome import op_common as oc
from hallhome import op_console, op_run, op_status, protocol
from hallhome.cli import main
from hallhome.paths import PROJECT_ROOT

# the committed paper_2seg table's identity (its generated JSON)
TID = json.loads((PROJECT_ROOT / "lookup_tables" / "generated" / "paper_2seg.json")
                 .read_text())["table_id"].lower()

SUBCOMMANDS = ["console", "status", "calibrate", "rehome", "home", "release", "learn", "learned",
               "forget", "history", "monitor", "export"]
VERSION = ("<version name=hallhome version=0.1.0 board=\"Arduino Mega 2560\" table=paper_2seg "
           f"table_id={TID} tendons=6 sensors=3>")
STATUS = ("<status state=idle table=paper_2seg sensors=3 servos=6 homes=0x00000000 homes_now=0x0 "
          "rehome=0 tension_mN=0 count=0 fault=none learned=0 baseline=0 saving=0 loop_max_us=3584 "
          "loops=764>")
SENSORS = ["<sensor index=0 ch=0 addr=105 ok=1 who=234 mag=1 rate_Hz=86.7 bx_uT=258.30 by_uT=1.35 "
           "bz_uT=-81.75 ovf=0 err=0 last_err=0 reinits=0>",
           "<sensor index=1 ch=1 addr=105 ok=1 who=234 mag=1 rate_Hz=87.3 bx_uT=4912.80 by_uT=210.90 "
           "bz_uT=-81.90 ovf=74 err=0 last_err=0 reinits=0>"]
SERVOS = [f"<servo tendon={t} id={t + 1} found=1 pos=100 cal_pos=100 hw_error=0>" for t in range(6)]


def test_grams_and_newtons():
    assert oc.newtons(1000) == pytest.approx(9.80665)
    assert oc.grams(0.8) == pytest.approx(81.577, abs=1e-3)
    for g in (5.0, 81.6, 153.0):
        assert oc.grams(oc.newtons(g)) == pytest.approx(g)


def test_int_list_keeps_marks():
    assert oc.int_list("2650,11*,-5,7?") == [(2650, ""), (11, "*"), (-5, ""), (7, "?")]
    assert oc.int_list("") == []


def test_fixed3_is_a_valid_firmware_decimal():
    assert oc.fixed3(0.8) == "0.800"
    assert protocol.check_command(oc.cmd("cal", oc.fixed3(1.25), 3))[1] == [1250, 3]
    with pytest.raises(RuntimeError):
        oc.cmd("no_such_command")


def test_option_ranges_are_the_boards():
    cal = protocol.COMMANDS_BY_NAME["cal"]
    t, k = cal.args
    assert (oc.TENSION.min, oc.TENSION.max) == (t.min / 1000, t.max / 1000)
    assert (oc.TENDON.min, oc.TENDON.max) == (k.min, k.max)


def test_range_errors_state_the_range():
    with pytest.raises(protocol.CommandError, match=r"tension_N 20 is not in 0\.01\.\.10"):
        protocol.check_command("cal 20")
    r = CliRunner().invoke(main, ["calibrate", "--tension", "20", "--port", "/dev/null-x"])
    assert r.exit_code == 2 and "--tension" in r.output and "0.01<=x<=10" in r.output
    r = CliRunner().invoke(main, ["calibrate", "--tendon", "12", "--port", "/dev/null-x"])
    assert r.exit_code == 2 and "0<=x<=11" in r.output


def test_calview_follows_a_run():
    v = op_run.CalView(3, None)
    for line in ["<progress state=start mode=full tension_mN=800>", "<progress state=preflight>",
                 "<progress state=tendon tendon=0 id=1>", "<target tendon=0 target_uT=106.56 travel_um=378>",
                 "<progress state=engaged tendon=0 pos=4100>",
                 "<result tendon=0 id=1 home=4321 home_um=2000 dB_uT=106.40 target_uT=106.56 travel_um=1356 "
                 "time_ms=2500>", "<progress state=tendon tendon=1 id=2>"]:
        v.feed(rep(line))
    assert v.rows[0]["state"] == "home" and v.rows[0]["home"] == 4321 and v.rows[0]["travel_um"] == 1356
    assert v.rows[1]["state"] == "pulling" and v.rows[2]["state"] == "waiting"
    assert not v.finished
    v.feed(rep("<done mode=full time_ms=9000 tension_mN=800 count=4>"))
    assert v.finished and v.done.get("count") == 4 and v.ok
    j = v.as_json()
    assert j["ok"] and j["count"] == 4 and j["tension_N"] == 0.8
    assert j["tendons"][0]["home_ticks"] == 4321 and j["tendons"][0]["travel_mm"] == 1.356


def test_calview_fault_ends_the_run_after_a_grace():
    v = op_run.CalView(2, 1)
    assert list(v.rows) == [1]
    f = rep("<fault reason=travel_limit code=10 dev=tendon index=1 id=2 detail=0>")
    v.feed(f)
    assert v.rows[1]["state"] == "fault: travel_limit"
    assert not v.finished
    f.at -= op_run.FAULT_GRACE + 0.1
    assert v.finished and not v.ok
    v2 = op_run.CalView(2, None)
    v2.feed(rep("<released reason=aborted>"))
    assert v2.finished


def test_ends_motion():
    assert oc.ends_motion(rep("<done mode=full time_ms=1 tension_mN=800 count=1>"))
    assert oc.ends_motion(rep("<released reason=aborted>"))
    assert not oc.ends_motion(rep("<progress state=preflight>"))


class StatusSequence:
    """Answers wait_booted()'s `status` with a given sequence of states (the
    bench boots in 0.1 s, too fast to catch in the boot state)."""

    def __init__(self, states):
        self.states = list(states)
        self.sent = []

    def command(self, line):
        from hallhome.client import Reply
        self.sent.append(line)
        st = self.states.pop(0) if len(self.states) > 1 else self.states[0]
        return Reply(line, [rep(f"<status state={st} count=0>")])


def test_wait_booted_polls_until_the_boot_ends(capsys):
    s = StatusSequence(["boot", "boot", "idle"])
    oc.wait_booted(s)
    assert s.sent == ["status"] * 3
    assert "waiting for the board to finish booting" in capsys.readouterr().err
    s = StatusSequence(["fault"])
    oc.wait_booted(s)
    assert s.sent == ["status"]


def test_wait_booted_gives_up(monkeypatch):
    monkeypatch.setattr(oc, "BOOT_WAIT", 0.3)
    with pytest.raises(hc.ReplyTimeout, match="still booting after 0.3 s"):
        oc.wait_booted(StatusSequence(["boot"]))


def test_sparkline():
    from hallhome.op_monitor import sparkline
    assert sparkline([0, 1, 2, 3, 4, 5, 6, 7]) == "▁▂▃▄▅▆▇█"
    assert sparkline([5, 5]) == "▁▁"
    assert len(sparkline(list(range(100)), 40)) == 40


# --- output ---------------------------------------------------------------------------

def test_plain_tables_are_whole_when_not_a_terminal(capsys):
    long = "Mega 2560 R3 - Arduino Mega 2560 with a very long USB description string"
    oc.show_table(oc.out(), "ports", ["port", "description"], [["/dev/ttyACM0", (long, "green")]])
    got = capsys.readouterr().out
    assert long in got and "…" not in got and "│" not in got
    assert got.splitlines()[1].split() == ["port", "description"]


def test_help_reports_become_text():
    r = rep('<help cmd=cal args="[tension_N:d:0.01:10] [tendon:i:0:11]" text="calibrate every tendon">')
    line = op_console.help_text(r)
    assert line.split()[0] == "cal" and line.endswith("calibrate every tendon") and "<help" not in line


class P:
    def __init__(self, device, vid=None, pid=None, desc="n/a"):
        self.device, self.vid, self.pid, self.description = device, vid, pid, desc
        self.serial_number = None


PORTS = [P("/dev/ttyACM0", 0x2341, 0x0042, "Arduino Mega 2560 R3 with a long description that a "
           "narrow table would cut"), P("/dev/ttyS0"), P("/dev/ttyUSB0", 0x1A86, 0x7523, "USB Serial")]


def test_ports_command_lists_and_marks(monkeypatch):
    monkeypatch.setattr(op_status, "list_ports", lambda: hc.list_ports(lambda: PORTS))
    monkeypatch.setattr(op_status, "find_port", lambda p: hc.find_port(p, lambda: PORTS))
    r = CliRunner().invoke(main, ["ports"], env={"COLUMNS": "60"})
    assert r.exit_code == 0, r.output
    assert "2341:0042" in r.output and "Arduino Mega 2560 R3" in r.output
    assert "a narrow table would cut" in r.output  # not a terminal: nothing truncated
    assert "CH340 (Mega clone?)" in r.output
    assert "default port: /dev/ttyACM0" in r.output
    r = CliRunner().invoke(main, ["ports", "--json"])
    d = json.loads(r.output)
    assert d["default"] == "/dev/ttyACM0" and [p["device"] for p in d["ports"]][0] == "/dev/ttyACM0"
    assert d["ports"][0]["mega"] is True and d["ports"][1]["usb_id"] is None


def test_no_board_found_is_a_clear_error(monkeypatch):
    monkeypatch.delenv("HALLHOME_PORT", raising=False)
    monkeypatch.setattr(oc, "find_port", lambda p: hc.find_port(p, lambda: []))
    r = CliRunner().invoke(main, ["status"])
    assert r.exit_code == 5
    assert "no Arduino Mega found" in r.output


@pytest.mark.parametrize("name", SUBCOMMANDS)
def test_every_board_subcommand_has_help_and_port(name):
    r = CliRunner().invoke(main, [name, "--help"])
    assert r.exit_code == 0
    assert "--port" in r.output and "HALLHOME_PORT" in r.output


def test_ask_tells_ctrl_c_from_end_of_input(monkeypatch):
    def interrupted(*a, **k):
        try:
            raise KeyboardInterrupt
        except KeyboardInterrupt:
            raise click.exceptions.Abort() from None
    monkeypatch.setattr(click, "prompt", interrupted)
    with pytest.raises(KeyboardInterrupt):
        oc.ask("x")

    def ended(*a, **k):
        try:
            raise EOFError
        except EOFError:
            raise click.exceptions.Abort() from None
    monkeypatch.setattr(click, "prompt", ended)
    with pytest.raises(hc.HallhomeError, match="standard input ended"):
        oc.ask("x")


# --- status against a scripted board -------------------------------------------------

def status_board(sensors=SENSORS, version=VERSION):
    return FakeBoard({"version": [version], "status": [STATUS], "sensors": sensors,
                      "servos pos": SERVOS})


@pytest.fixture
def same_table(monkeypatch):
    monkeypatch.setattr(op_status, "table_check", lambda info, exp: None)
    monkeypatch.setattr(op_status, "expected", lambda robot, learned: None)
    monkeypatch.setattr(op_run, "expected", lambda robot, learned: None)
    monkeypatch.setattr(op_run, "table_check", lambda info, exp: None)


def test_status_saturated_sensor_exits_nonzero_with_its_overflows(monkeypatch, same_table):
    use(monkeypatch, status_board(), op_status)
    r = CliRunner().invoke(main, ["status"])
    assert r.exit_code == 1, r.output
    assert "sensor 1 saturated (overflows: 74)" in r.output
    assert "0x69" in r.output and "105" not in r.output.split("sensors")[1].split("\n")[2]
    r = CliRunner().invoke(main, ["status", "--json"])
    d = json.loads(r.stdout)
    assert [s["state"] for s in d["sensors"]] == ["ok", "saturated"]
    assert d["sensors"][1]["addr"] == "0x69" and d["problems"] == ["sensor 1 saturated (overflows: 74)"]


def test_status_reads_the_later_firmwares_saturated_state(monkeypatch, same_table):
    later = [SENSORS[0], "<sensor index=1 ch=1 addr=105 state=saturated ok=1 rate_Hz=87.3 bx_uT=300.00 "
                         "by_uT=1.00 bz_uT=2.00 ovf=9 err=0>"]
    use(monkeypatch, status_board(later), op_status)
    r = CliRunner().invoke(main, ["status"])
    assert r.exit_code == 1 and "sensor 1 saturated (overflows: 9)" in r.output


def test_status_healthy_board_exits_zero(monkeypatch, same_table):
    use(monkeypatch, status_board([SENSORS[0]]), op_status)
    r = CliRunner().invoke(main, ["status"])
    assert r.exit_code == 0, r.output
    assert "paper_2seg" in r.output and "…" not in r.output


def test_missing_why3_sensor_is_named_saturated():
    m = rep("<missing dev=sensor index=1 why=3 bits=0>")
    assert op_status.missing_text(m, [rep(SENSORS[1])]) == (
        "sensor 1 saturated (overflows: 74): move the magnet or iron away")
    assert op_status.missing_text(m) == "sensor 1: read errors or overflows"
    assert op_status.missing_text(rep("<missing dev=servo index=2 id=3 why=2 bits=0>")) == \
        "missing servo 2 (servo id 3): no answer"
    assert op_status.missing_text(rep("<missing dev=sensor index=0 ch=0 addr=105 err=-2>")) == \
        "missing sensor 0: did not come up on mux channel 0 at 0x69 (driver error -2)"


def test_calibrate_names_the_grid_when_the_tension_is_off_it(monkeypatch, same_table):
    b = status_board([SENSORS[0]])
    b.answers["cal"] = "error:16 tension outside the table grid"
    b.answers["table"] = [f"<table name=paper_2seg table_id={TID} tendons=6 grid_mN=200,300,1500>"]
    use(monkeypatch, b, op_status, op_run)
    r = CliRunner().invoke(main, ["calibrate", "-N", "5"])
    assert r.exit_code == 1
    assert "TENSION_RANGE): the table's grid spans 0.2..1.5 N" in r.output


def test_status_and_calibrate_check_the_table(monkeypatch):
    other = VERSION.replace(f"table_id={TID}", "table_id=0x12345678")
    use(monkeypatch, status_board([SENSORS[0]], other), op_status, op_run)
    r = CliRunner().invoke(main, ["status"])
    assert r.exit_code == 0, r.output  # a warning, not a failure
    assert "warning: the board runs table paper_2seg 0x12345678, but paper_2seg.toml gives " \
           f"paper_2seg {TID}" in r.output
    b = status_board([SENSORS[0]], other)
    use(monkeypatch, b, op_status, op_run)
    r = CliRunner().invoke(main, ["calibrate"])
    assert r.exit_code == 1 and "--force calibrates anyway" in r.output
    assert not any(s.startswith("cal") for s in b.sent)  # refused before anything moved


def test_calibrate_force_and_json(monkeypatch):
    other = VERSION.replace(f"table_id={TID}", "table_id=0x12345678")
    b = status_board([SENSORS[0]], other)
    b.events.extend(["<progress state=tendon tendon=0 id=1>",
                     "<result tendon=0 id=1 home=4321 straight=4274 home_um=2000 dB_uT=106.40 "
                     "target_uT=106.56 travel_um=1356 time_ms=2500>",
                     "<done mode=single time_ms=2600 tension_mN=800 count=3>"])
    use(monkeypatch, b, op_status, op_run)
    monkeypatch.setenv("HALLHOME_RUNS", "")
    r = CliRunner().invoke(main, ["calibrate", "--force", "-k", "0", "-N", "0.8", "--json"])
    assert r.exit_code == 0, r.output
    d = json.loads(r.stdout)
    assert d["ok"] and d["count"] == 3 and d["tendons"] == [
        {"tendon": 0, "servo_id": 1, "state": "home", "home_ticks": 4321, "straight_ticks": 4274,
         "travel_mm": 1.356, "dB_uT": 106.4, "target_uT": 106.56, "time_s": 2.5}]
    assert "cal 0.800 0" in b.sent
    assert "warning: the board runs table" in r.stderr


def test_calibrate_refusal_names_a_saturated_sensor(monkeypatch, same_table):
    b = status_board()
    b.answers["cal"] = lambda line: (_ for _ in ()).throw(hc.BoardError(
        line, 13, "sensor missing or faulty", [rep("<missing dev=sensor index=1 why=3 bits=0>")]))
    use(monkeypatch, b, op_status, op_run)
    r = CliRunner().invoke(main, ["calibrate"])
    assert r.exit_code == 1
    assert "sensor 1 saturated (overflows: 74)" in r.output and "SENSOR_FAULT" in r.output


def test_home_waits_for_the_end(monkeypatch):
    b = FakeBoard({"status": [STATUS]})
    b.events.extend(["<progress state=release>", "<done mode=home time_ms=1500>"])
    use(monkeypatch, b, op_run)
    r = CliRunner().invoke(main, ["home"])
    assert r.exit_code == 0 and "every tendon at its home in 1.5 s" in r.output
    b = FakeBoard({"status": [STATUS]})
    b.events.extend(["<fault reason=servo_stall error=0 dev=servo index=2>", "<released reason=fault>"])
    use(monkeypatch, b, op_run)
    r = CliRunner().invoke(main, ["release"])
    assert r.exit_code == 1 and "fault during `release`: servo_stall on servo 2" in r.output


def test_port_busy_is_its_own_error(tmp_path):
    import os
    master, slave = os.openpty()
    path = os.ttyname(slave)
    try:
        first = hc.Client(path, sync=False)
        with pytest.raises(hc.PortBusy, match="port busy"):
            hc.Client(path, sync=False)
        first.close()
        hc.Client(path, sync=False).close()  # free again once the first closed
    finally:
        os.close(master)
        os.close(slave)
