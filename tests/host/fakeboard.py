"""A scripted stand-in for hallhome.client.Client, for the operator
commands' logic that the virtual bench cannot reach on demand (a saturated
sensor in the new report format, a board with another table, learn with
weights hung, history across power cycles). Not a model of the firmware:
each test says what the board answers."""

import collections
import time
from contextlib import contextmanager

from hallhome.client import BoardError, LocalError, Reply, Report
from hallhome.protocol import CommandError, check_command, parse_line


def rep(line: str) -> Report:
    m = parse_line(line)
    return Report(m["kind"], m["fields"], line, time.monotonic())


class FakeBoard:
    def __init__(self, answers=None, check=True):
        # line -> list of report lines, a callable(line) -> list, or an
        # "error:<code> <text>" string
        self.answers = dict(answers or {})
        self.sent = []
        self.events = collections.deque()
        self.motion = None
        self.garbled = 0
        self.garbled_last = None
        self.boot = None
        self.port = "fake"
        self.aborted = 0
        self.check = check

    def command(self, line, timeout=None):
        line = line.strip()
        if self.check:
            try:
                check_command(line)
            except CommandError as e:
                raise LocalError(line, e.code, str(e)) from None
        self.sent.append(line)
        a = self.answers.get(line)
        if a is None:
            a = self.answers.get(line.split()[0], [])
        if callable(a):
            a = a(line)
        if isinstance(a, str):
            m = parse_line(a)
            raise BoardError(line, m["code"], m["text"])
        reports = [rep(x) for x in a]
        if line.split()[0] in ("cal", "rehome", "home"):
            self.motion = line.split()[0]
        return Reply(line, reports)

    def event(self, timeout):
        if self.events:
            x = self.events.popleft()
            return rep(x) if isinstance(x, str) else x
        time.sleep(min(timeout, 0.01))
        return None

    def abort(self, wait=0.0, until=lambda r: False):
        self.aborted += 1
        self.motion = None
        return []

    def motion_ended(self):
        self.motion = None

    def reset_message(self, r, during):
        return f"the board reset {during}"

    def close(self):
        pass


def use(monkeypatch, board, *modules):
    """Every given operator module talks to `board` instead of a port."""
    @contextmanager
    def session(port, timeout):
        yield board
    for m in modules:
        monkeypatch.setattr(m, "session", session)
