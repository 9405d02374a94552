"""The seeded schedule generator of the chaos suite (docs/chaos.md).

A schedule is a bench script (sim/bench `step` chains plus timed console
traffic) for one robot of the pool. It is a list of episodes, each one to
three disturbed calibrations in a row followed by a clean one (the recovery
attempt), and it ends with a power cycle that checks the stored records.
A disturbance is a fault of any scenario type, an abort (`!`, the host's
Ctrl-C, a long press), a reset (watchdog, reset pin, power cycle) or a
console storm, injected at a random moment of a random phase: found by the
phase's progress report, then a random delay inside the phase's duration.
The same seed gives the same schedule, byte for byte.
"""

from __future__ import annotations

import random
from dataclasses import dataclass, field

# Phases: the console line that opens each one (regexes without spaces, as
# `step on` takes them) and how long it usually lasts (s), so a random delay
# lands inside it. {k} is the tendon.
PHASES = {
    "release": (r"^<progress.state=release", 0.0, 0.45),
    "slack_check": (r"^<progress.state=release", 0.45, 0.7),
    "baseline": (r"^<progress.state=baseline", 0.0, 0.006),
    "take_up": (r"^<progress.state=tendon.tendon={k}[^0-9]", 0.0, 0.8),
    "fine_approach": (r"^<progress.state=engaged.tendon={k}[^0-9]", 0.0, 0.45),
    "final_move": (r"^<progress.state=final", 0.0, 0.12),
    # a calibration's own done, when it saves its homes: not the done of a
    # release the board makes after a servo's reboot (seed 17064: the magnet
    # came off in the next calibration's fine approach, which was then judged
    # as the final, undisturbed one)
    "eeprom_save": (r"^<done.mode=(full|quick|single)", 0.0, 0.8),
}

# The end of a calibration attempt, whatever it was: its `<done>` or its
# `<fault>` (docs/app.md: a calibration ends with exactly one of them). Not
# the end of an app move (`<done mode=release|home>`) nor a `<released>`
# report: after a stop the board may still release on its own (a servo in
# hardware error rebooted, then `<released reason=servo_error>`, `<done
# mode=release>`), and a calibration started meanwhile was taken for ended
# by those reports (chaos seed 1027: the power cycle then cut the final
# calibration). The bench reads a step's pattern up to the next space: `.`
# stands for one.
RUN_END = r"^<(done.mode=(full|quick|single)|fault)"
def run_within(robot) -> str:
    """How long to wait for a phase or a calibration's end: a bring-up and
    a calibration of this robot with room to spare (about 1.5 s per tendon
    when all goes well)."""
    return f"{8 + 2 * robot.tendons}s"

# Faults: event, how the world is put right afterwards (None: the firmware
# must recover alone), weight. {k} a sensor, {i} a tendon, {id} its servo.
FAULTS = {
    "sensor_unplug": ("sensor-unplug {k}", "sensor-plug {k}", 2),
    "mux_unplug": ("mux-unplug", "mux-plug", 1),
    "i2c_stuck": ("i2c-stuck {clocks}", None, 1),
    "servo_silent": ("servo-silent {i}", "servo-answer {i}", 2),
    "servo_hwerr": ("servo-hwerr {i}", None, 2),
    "saturate": ("saturate {k}", "field {k} 0 0 0", 1),
    "field_step": ("field {k} {fx} {fy} {fz}", "field {k} 0 0 0", 1),
    "magnet_missing": ("magnet-remove", "magnet-restore", 1),
    "out_of_reach": ("tendon-stiffness {i} 0.02", "tendon-stiffness {i} 50", 1),
    "bus_noise": ("bus-noise 0.001", "bus-noise {base_noise}", 1),
    "abort_console": ("raw !", None, 3),
    "host_ctrl_c": ("raw !\\r\\n", None, 1),
    "abort_button": ("longpress", None, 2),
    "watchdog": ("wdt-reset", None, 2),
    "ext_reset": ("ext-reset", None, 1),
    "power_cycle": ("power-cycle", None, 2),
    "console_storm": (None, None, 2),
}
RESETS = {"watchdog", "ext_reset", "power_cycle"}

# Console traffic: read-only commands (a calibration under way must go on),
# garbage, over-long lines, bad bytes and empty lines.
COMMANDS = ["help", "version", "status", "sensors", "servos", "servos pos", "servos err",
            "get", "get cal_tension", "table", "history", "", "VERSION", "get nosuch",
            "servos bogus", "cal 99", "reboot 999", "frobnicate", "set cal_tension",
            "learn 0", "cal 0.8 77"]


@dataclass
class Schedule:
    seed: int
    robot: str
    bench_seed: int
    base_noise: float
    lines: list[str] = field(default_factory=list)
    faults: list[tuple[str, str]] = field(default_factory=list)  # (type, phase)
    clean_steps: list[int] = field(default_factory=list)  # step numbers starting clean runs
    n_steps: int = 0
    injected_resets: int = 0
    limit_s: float = 0.0

    def script(self) -> str:
        head = [f"# chaos schedule {self.seed}: robot {self.robot}, bench seed "
                f"{self.bench_seed}, base bus noise {self.base_noise}",
                "# faults: " + ", ".join(f"{t}@{p}" for t, p in self.faults)]
        return "\n".join(head + self.lines) + "\n"


def _garbage(rng: random.Random) -> str:
    kind = rng.randrange(4)
    if kind == 0:  # printable junk
        return "".join(chr(rng.randint(0x21, 0x7E)) for _ in range(rng.randint(1, 30))
                       if True).replace("!", "?").replace("#", "%").replace("\\", "/") + "\\r\\n"
    if kind == 1:  # over-long line
        return "x" * rng.randint(49, 90) + "\\r\\n"
    if kind == 2:  # control bytes and 8-bit bytes inside a line
        return "st\\x01at\\xffus\\r\\n"
    return "\\n\\r\\n"  # empty lines, LF then CRLF


def _traffic(rng: random.Random, sch: Schedule, t0: float, t1: float) -> None:
    """Timed background traffic between t0 and t1 (absolute simulated s)."""
    t = t0 + rng.uniform(0.0, 2.0)
    while t < t1:
        r = rng.random()
        if r < 0.6:
            sch.lines.append(f"{t:.3f}s send {rng.choice(COMMANDS)}")
        elif r < 0.85:
            sch.lines.append(f"{t:.3f}s raw {_garbage(rng)}")
        else:  # a pipelined burst of one line
            cmd = rng.choice(["version", "help", "status", "get cal_tension"])
            n = rng.randint(3, 120 // (len(cmd) + 4))  # an event's text: 127 characters
            sch.lines.append(f"{t:.3f}s raw " + (cmd + "\\r\\n") * n)
        t += rng.expovariate(1.0 / 1.5)


def _step(sch: Schedule, text: str) -> int:
    """Appends a step line; returns its number in the chain."""
    sch.lines.append("step " + text)
    sch.n_steps += 1
    return sch.n_steps - 1


def _start(rng: random.Random) -> str:
    return "press 100" if rng.random() < 0.6 else "send cal"


def _disturbance(rng, sch: Schedule, robot, kind: str) -> None:
    """Steps of one disturbed calibration: start it, hit a phase, wait for
    the attempt's end, put the world right."""
    phase = rng.choice(list(PHASES))
    tendon = rng.randrange(robot.tendons)
    regex, lo, hi = PHASES[phase]
    # the phase, or the attempt's end when it never comes (an earlier fault)
    regex = f"({regex.format(k=tendon)})|(^<(fault|released))"
    delay_ms = rng.uniform(lo, hi) * 1000.0
    sch.faults.append((kind, phase))
    _step(sch, f"+{rng.uniform(0.2, 1.2):.3f}s {_start(rng)}")
    if kind == "console_storm":
        # help/status lines every 20-80 ms, or pipelined, through the phase
        _step(sch, f"on {regex} within {run_within(robot)} +{delay_ms:.1f}ms nop")
        period = rng.uniform(20.0, 80.0)
        for _ in range(rng.randint(8, 25)):
            cmd = rng.choice(["help", "status", "version", "sensors", "servos pos"])
            if rng.random() < 0.3:
                _step(sch, f"+{period:.1f}ms raw " + (cmd + "\\r\\n") * 4)
            else:
                _step(sch, f"+{period:.1f}ms send {cmd}")
    else:
        event, heal, _ = FAULTS[kind]
        args = dict(k=rng.randrange(robot.sensors), i=tendon, clocks=rng.randint(1, 12),
                    fx=round(rng.uniform(-30, 30), 1), fy=round(rng.uniform(-30, 30), 1),
                    fz=round(rng.uniform(-30, 30), 1), base_noise=sch.base_noise)
        _step(sch, f"on {regex} within {run_within(robot)} +{delay_ms:.1f}ms "
                         + event.format(**args))
        if kind in RESETS:
            sch.injected_resets += 1
            _wait_boot(sch, robot, f"+{rng.uniform(0.05, 0.5):.3f}s nop")
            return
        # after the EEPROM save the attempt has ended already
        wait = "" if phase == "eeprom_save" else f"on {RUN_END} within {run_within(robot)} "
        _step(sch, f"{wait}+{rng.uniform(0.1, 0.6):.3f}s " + (heal.format(**args) if heal else "nop"))
        if kind == "abort_button":
            _step(sch, "+2.6s nop")  # the long press (2.5 s) is over before the next step
        return
    if phase != "eeprom_save":
        _step(sch, f"on {RUN_END} within {run_within(robot)} +{rng.uniform(0.1, 0.6):.3f}s nop")


def _wait_boot(sch: Schedule, robot, then: str) -> None:
    """After a reset: the boot report, then the end of the bring-up (a
    `servos` scan reports `<ready` too, so the boot comes first)."""
    # not anchored: a reset in the middle of a report leaves that line
    # unfinished and the boot report follows on it (seed 1034 waited 26 s)
    _step(sch, f"on <boot.name= within {run_within(robot)} nop")
    _step(sch, f"on ^<ready within {run_within(robot)} {then}")


def _clean_run(rng, sch: Schedule, robot) -> None:
    sch.clean_steps.append(_step(sch, f"+{rng.uniform(0.2, 1.5):.3f}s {_start(rng)}"))
    _step(sch, f"on {RUN_END} within {run_within(robot)} +1.5s nop")


def generate(seed: int, robots: list) -> tuple[Schedule, object]:
    rng = random.Random(seed * 7919 + 17)
    robot = robots[rng.randrange(len(robots))]
    sch = Schedule(seed, robot.name, rng.randrange(1, 2**31 - 1),
                   rng.choice([0.0, 0.0, 1e-4, 1e-3]))
    if sch.base_noise:
        sch.lines.append(f"0 bus-noise {sch.base_noise}")
    _step(sch, f"on ^<ready within {run_within(robot)} +{rng.uniform(0.05, 0.6):.3f}s nop")
    kinds = list(FAULTS)
    weights = [FAULTS[k][2] for k in kinds]
    for _ in range(rng.randint(1, 2)):
        for _ in range(rng.randint(1, 3)):
            _disturbance(rng, sch, robot, rng.choices(kinds, weights)[0])
        _clean_run(rng, sch, robot)
    # the records: a power cycle, the boot's report of the stored homes,
    # the newest history entry, asked twice: the background traffic may
    # overrun the console as the first goes, and the bytes lost (reported
    # with <overrun>) may take its line end, so that it and every line up to
    # the next line end are one line too long (seed 21148); the second goes
    # after a bare line end, which ends any such line first
    _step(sch, "+0.5s power-cycle")
    _wait_boot(sch, robot, "+0.2s send history")
    _step(sch, "+1s raw \\r\\n")
    _step(sch, "+0.1s send history")
    _step(sch, "+2s quit")
    sch.injected_resets += 1
    # a generous bound: every step waits at most run_within()
    n_wait = sum(1 for ln in sch.lines if " within " in ln)
    sch.limit_s = (8.0 + 2.0 * robot.tendons) * n_wait + 30.0
    _traffic(rng, sch, 0.0, 20.0 * (len(sch.faults) + len(sch.clean_steps)))
    return sch, robot
