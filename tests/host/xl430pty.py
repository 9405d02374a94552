"""The servo models of sim/devices/xl430_model.c on a pseudo-terminal
(``build/native/hh_xl430_pty``, built by ``make unit``), opened with
ROBOTIS's own PortHandler at 1 Mbps: the peer the SDK-driven tests talk to."""

import contextlib
import subprocess
from pathlib import Path

import pytest

from dynamixel_sdk import PortHandler
from dynamixel_sdk import port_handler

# The SDK waits 2 x LATENCY_TIMER (16 ms, a USB adapter's latency) plus the
# packet's bytes for a reply. The models here are a process on a machine that
# runs other tests beside them (make host-test uses pytest -n): a reply late
# by a scheduling delay is not a servo that did not answer. 50 ms each way.
port_handler.LATENCY_TIMER = 50

ROOT = Path(__file__).resolve().parents[2]
TOOL = ROOT / "build" / "native" / "hh_xl430_pty"


@contextlib.contextmanager
def xl430_port(ids, boot_ms: int):
    """Yields an open PortHandler on models with these IDs, each booting for
    boot_ms; closes the port and ends the models afterwards."""
    if not TOOL.exists():
        pytest.fail(f"{TOOL} is missing: run `make unit` first (it builds hh_xl430_pty)")
    proc = subprocess.Popen([str(TOOL), "--boot-ms", str(int(boot_ms)), *map(str, ids)],
                            stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
    line = proc.stdout.readline()
    assert line.startswith("pty: "), line
    handler = PortHandler(line.split()[1])
    assert handler.openPort()
    assert handler.setBaudRate(1000000)
    try:
        yield handler
    finally:
        handler.closePort()
        proc.stdin.close()
        proc.wait(timeout=10)
