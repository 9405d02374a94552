"""Operator subcommands: the bench tools a lab member runs with a laptop on
the Arduino Mega (docs/operator.md).

`register(main)` adds them to the `hallhome` command group. Each group of
commands lives in its own module; what they share (the report vocabulary,
the session, option ranges from the firmware's declarations, output) is in
hallhome.op_common.
"""

from __future__ import annotations

import click

from hallhome.op_console import console_cmd
from hallhome.op_history import export_cmd, history_cmd
from hallhome.op_learn import forget_cmd, learn_cmd, learned_cmd
from hallhome.op_monitor import monitor_cmd
from hallhome.op_run import calibrate_cmd, home_cmd, rehome_cmd, release_cmd
from hallhome.op_status import ports_cmd, status_cmd

COMMANDS = (ports_cmd, console_cmd, status_cmd, calibrate_cmd, rehome_cmd, home_cmd, release_cmd,
            learn_cmd, learned_cmd, forget_cmd, history_cmd, monitor_cmd, export_cmd)


def register(main: click.Group) -> None:
    """Adds the operator subcommands to the `hallhome` group."""
    for c in COMMANDS:
        main.add_command(c)
