"""The servo models of sim/devices/xl430_model.c on a pseudo-terminal
(``build/native/hh_xl430_pty``, built by ``make unit``), opened with
ROBOTIS's own PortHandler at 1 Mbps: the peer the SDK-driven tests talk to."""

import contextlib
import subprocess
from pathlib import Path

import pytest

from dynamixel_sdk import PortHandler

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
