"""hallhome.operator: the parts that need no board (conversions, report
bookkeeping, port listing, options). Every subcommand runs against the
firmware in test_operator_bench.py."""

import time

import pytest
from click.testing import CliRunner

from hallhome import client as hc
from hallhome import operator as op
from hallhome.cli import main
from hallhome.client import Report

SUBCOMMANDS = ["console", "status", "calibrate", "learn", "history", "monitor", "export"]


def rep(line: str) -> Report:
    from hallhome.protocol import parse_line
    m = parse_line(line)
    return Report(m["kind"], m["fields"], line, time.monotonic())


def test_grams_and_newtons():
    assert op.newtons(1000) == pytest.approx(9.80665)
    assert op.grams(0.8) == pytest.approx(81.577, abs=1e-3)
    for g in (5.0, 81.6, 153.0):
        assert op.grams(op.newtons(g)) == pytest.approx(g)


def test_snap_to_grid():
    grid = [200, 300, 800, 1500]
    assert op.snap_to_grid(op.newtons(81.6), grid, 1.0)[0] == 800
    g, dev = op.snap_to_grid(op.newtons(20.3), grid, 1.0)
    assert g == 200 and dev == pytest.approx(-0.46, abs=0.01)
    with pytest.raises(ValueError, match=r"80.0 g is 0.785 N, -1.9 % from the nearest grid tension "
                                         r"0.800 N \(81.6 g\)"):
        op.snap_to_grid(op.newtons(80), grid, 1.0)
    assert op.snap_to_grid(op.newtons(80), grid, 2.0)[0] == 800


def test_default_learn_points_surround_the_default_tension():
    grid = [200, 300, 400, 500, 600, 700, 800, 900, 1000, 1100, 1300, 1500]
    assert op.default_points(grid, 800) == [700, 800, 900]
    assert op.default_points(grid, 200) == [200, 300]
    assert op.default_points(grid, 1450) == [1300, 1500]
    assert [round(op.grams(g / 1000), 1) for g in op.default_points(grid, 800)] == [71.4, 81.6, 91.8]


def test_int_list_keeps_marks():
    assert op.int_list("2650,11*,-5,7?") == [(2650, ""), (11, "*"), (-5, ""), (7, "?")]
    assert op.int_list("") == []


def test_fixed3_is_a_valid_firmware_decimal():
    from hallhome.protocol import check_command
    assert op.fixed3(0.8) == "0.800"
    assert check_command(op.cmd("cal", op.fixed3(1.25), 3))[1] == [1250, 3]
    with pytest.raises(RuntimeError):
        op.cmd("no_such_command")


def test_calview_follows_a_run():
    v = op.CalView(3, None)
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
    assert v.finished and v.done.get("count") == 4


def test_calview_fault_ends_the_run_after_a_grace():
    v = op.CalView(2, 1)
    assert list(v.rows) == [1]
    f = rep("<fault reason=travel_limit code=10 dev=tendon index=1 id=2 detail=0>")
    v.feed(f)
    assert v.rows[1]["state"] == "fault: travel_limit"
    assert not v.finished
    f.at -= op.FAULT_GRACE + 0.1
    assert v.finished
    v2 = op.CalView(2, None)
    v2.feed(rep("<released reason=aborted>"))
    assert v2.finished


def test_ends_motion():
    assert op.ends_motion(rep("<done mode=full time_ms=1 tension_mN=800 count=1>"))
    assert op.ends_motion(rep("<released reason=aborted>"))
    assert not op.ends_motion(rep("<progress state=preflight>"))


class StatusSequence:
    """Not a board: answers wait_booted()'s `status` with a given sequence
    of states, to check the waiting logic alone (the bench boots in 0.1 s,
    too fast to catch in the boot state)."""

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
    op.wait_booted(s)
    assert s.sent == ["status"] * 3
    assert "waiting for the board to finish booting" in capsys.readouterr().err
    s = StatusSequence(["fault"])
    op.wait_booted(s)
    assert s.sent == ["status"]


def test_wait_booted_gives_up(monkeypatch):
    from hallhome.client import ReplyTimeout
    monkeypatch.setattr(op, "BOOT_WAIT", 0.3)
    with pytest.raises(ReplyTimeout, match="still booting after 0.3 s"):
        op.wait_booted(StatusSequence(["boot"]))


def test_sparkline():
    assert op.sparkline([0, 1, 2, 3, 4, 5, 6, 7]) == "▁▂▃▄▅▆▇█"
    assert op.sparkline([5, 5]) == "▁▁"
    assert len(op.sparkline(list(range(100)), 40)) == 40


class P:
    def __init__(self, device, vid=None, pid=None, desc="n/a"):
        self.device, self.vid, self.pid, self.description = device, vid, pid, desc
        self.serial_number = None


def test_ports_command_lists_and_marks(monkeypatch):
    ports = [P("/dev/ttyACM0", 0x2341, 0x0042, "Arduino Mega"), P("/dev/ttyS0"),
             P("/dev/ttyUSB0", 0x1A86, 0x7523, "USB Serial")]
    monkeypatch.setattr(op, "list_ports", lambda: hc.list_ports(lambda: ports))
    monkeypatch.setattr(op, "find_port", lambda p: hc.find_port(p, lambda: ports))
    r = CliRunner().invoke(main, ["ports"], env={"COLUMNS": "160"})
    assert r.exit_code == 0, r.output
    assert "2341:0042" in r.output and "Arduino Mega 2560 R3" in r.output
    assert "CH340 (Mega clone?)" in r.output
    assert "default port: /dev/ttyACM0" in r.output


def test_no_board_found_is_a_clear_error(monkeypatch):
    monkeypatch.delenv("HALLHOME_PORT", raising=False)
    monkeypatch.setattr(op, "find_port", lambda p: hc.find_port(p, lambda: []))
    r = CliRunner().invoke(main, ["status"])
    assert r.exit_code == 5
    assert "no Arduino Mega found" in r.output


@pytest.mark.parametrize("name", SUBCOMMANDS)
def test_every_board_subcommand_has_help_and_port(name):
    r = CliRunner().invoke(main, [name, "--help"])
    assert r.exit_code == 0
    assert "--port" in r.output and "HALLHOME_PORT" in r.output


def test_calibrate_checks_its_options_before_connecting():
    r = CliRunner().invoke(main, ["calibrate", "--tension", "20", "--port", "/dev/null-x"])
    assert r.exit_code == 2 and "--tension" in r.output
    r = CliRunner().invoke(main, ["calibrate", "--tendon", "12", "--port", "/dev/null-x"])
    assert r.exit_code == 2 and "--tendon" in r.output
