"""`hallhome console`: the board's console with line editing on a terminal,
or a script runner when standard input is a file or a pipe."""

from __future__ import annotations

import os
import sys
import threading
import time
from pathlib import Path
from typing import List

import click
from rich.markup import escape

from hallhome import protocol, runlog
from hallhome.client import (BoardError, BoardReset, Client, HallhomeError, LocalError, Report,
                             ReplyTimeout)
from hallhome.op_common import R, ends_motion, operator_command, out, port_options, session

HISTORY_FILE = Path(os.environ.get("HALLHOME_HISTORY", Path.home() / ".hallhome_history"))
# Commands whose `ok` only starts something that ends with a report later;
# a script waits for that end before its next line.
WAITS_FOR_END = ("cal", "rehome", "home", "release")
FAULT_GRACE = 1.5  # seconds for the release report that follows a fault


def help_text(r: Report) -> str:
    """One `<help cmd=... args="..." text="...">` report as a line of text."""
    return f"  {str(r.get('cmd')):<9} {str(r.get('args', '')):<34} {r.get('text', '')}".rstrip()


def explain(e: BoardError, c: Client) -> str:
    """A board error with the range that applies, from the declarations or
    the board's own `version`/`table`."""
    base = f"error:{e.code} {e.text} ({e.name})"
    try:
        if e.name == "SETTING_RANGE":
            name = e.line.split()[1]
            s = protocol.SETTINGS_BY_NAME.get(name)
            if s is not None:
                return base + f": {name} takes {s.min}..{s.max} {s.unit}"
        if e.name == "BAD_TENDON":
            n = c.command("version").first(R.VERSION).get("tendons")
            return base + f": this board has tendons 0..{int(n) - 1}"
        if e.name == "TENSION_RANGE":
            grid = str(c.command("table").first(R.TABLE).get("grid_mN")).split(",")
            return base + f": the table's grid spans {int(grid[0]) / 1000:g}..{int(grid[-1]) / 1000:g} N"
    except (HallhomeError, AttributeError, ValueError, IndexError):
        pass
    return base


@click.command("console")
@click.option("--run-timeout", type=click.FloatRange(min=1.0), default=600.0, show_default=True,
              help="In a script: longest to wait for a started run to end (s).")
@port_options
@operator_command
def console_cmd(run_timeout, port, timeout) -> None:
    """Interactive console: type commands (`help` lists them), with line
    editing and history; `!` alone sends the realtime abort; Ctrl-C clears
    the line, Ctrl-D or `exit` leaves. Lines are checked against the
    firmware's declarations before they are sent. With standard input from
    a file or a pipe, runs the lines as a script: `cal`, `rehome`, `home`
    and `release` wait for the board's end report, and the exit code is
    non-zero when a line failed."""
    tty = sys.stdin.isatty()
    readline = None
    con = out()
    lock = threading.Lock()
    stop = threading.Event()
    ended = threading.Event()
    end_reports: List[Report] = []
    lost: List[HallhomeError] = []
    failures: List[int] = []  # exit codes of the lines that failed
    if tty:
        try:
            import readline
            try:
                readline.read_history_file(HISTORY_FILE)
            except OSError:
                pass
        except ImportError:  # no GNU readline on this platform: plain input()
            pass
    with session(port, timeout) as c:
        b = c.boot
        con.print(f"connected to {c.port}" + (f" ({escape(b.raw)})" if b else "") +
                  "; `help` lists the commands")
        table_id = None

        def show(r: Report) -> None:
            nonlocal table_id
            if r.kind == R.BOOT:
                con.print(f"[yellow]{escape(r.raw)}  <- the board reset; the console re-synchronises[/]")
            elif r.kind == R.HELP:
                click.echo(help_text(r))
            else:
                click.echo(r.raw)
            if r.kind in (R.VERSION, R.READY) and r.get("table_id") is not None:
                table_id = r.get("table_id")
            if r.kind == R.DONE and r.get("count") is not None and table_id is not None:
                runlog.record(table_id, r.get("count"), r.get("tension_mN"), r.get("mode"))
            if ends_motion(r) or r.kind == R.BOOT:
                end_reports.append(r)
                ended.set()

        prompt = "hallhome> " if tty else ""
        at_prompt = threading.Event()

        def show_async(r: Report) -> None:
            """A report between commands: on a terminal, above the prompt
            and the half-typed line, which are drawn again."""
            if not (tty and at_prompt.is_set()):
                show(r)
                return
            buf = readline.get_line_buffer() if readline is not None else ""
            sys.stdout.write("\r\x1b[K")
            sys.stdout.flush()
            show(r)
            sys.stdout.write(prompt + buf)
            sys.stdout.flush()

        def reader() -> None:
            while not stop.is_set():
                with lock:
                    try:
                        r = c.event(0.05)
                    except HallhomeError as e:
                        lost.append(e)
                        stop.set()
                        import _thread
                        _thread.interrupt_main()
                        return
                if r is not None:
                    show_async(r)
                else:
                    time.sleep(0.02)

        def wait_end(name: str) -> None:
            """Script mode: the run just started must end before the next line."""
            deadline = time.monotonic() + run_timeout
            while not ended.wait(0.1):
                if lost:
                    return
                if time.monotonic() > deadline:
                    con.print(f"[yellow]`{name}` did not end within {run_timeout:g} s[/]")
                    failures.append(ReplyTimeout.exit_code)
                    return
            last = end_reports[-1]
            if last.kind == R.FAULT:
                grace = time.monotonic() + FAULT_GRACE
                while time.monotonic() < grace and end_reports[-1].kind != R.RELEASED:
                    time.sleep(0.05)
                failures.append(1)
            elif last.kind == R.BOOT:
                failures.append(BoardReset.exit_code)
            elif last.kind == R.RELEASED and name != "release":
                failures.append(1)

        th = threading.Thread(target=reader, daemon=True)
        th.start()
        try:
            while True:
                at_prompt.set()
                try:
                    line = input(prompt)
                except EOFError:
                    if tty:
                        click.echo()
                    break
                except KeyboardInterrupt:
                    if lost or not tty:
                        raise
                    click.echo("^C")  # an idle prompt: drop the line, keep the session
                    continue
                finally:
                    at_prompt.clear()
                if not tty:
                    click.echo(f"> {line}")
                line = line.strip()
                if line in ("exit", "quit"):
                    break
                if line == "!":
                    with lock:
                        c.abort()
                    con.print("[yellow]abort sent[/]")
                    continue
                name = line.split()[0].lower() if line else ""
                ended.clear()
                del end_reports[:]
                try:
                    with lock:
                        rep = c.command(line, timeout=timeout)
                    for r in rep.reports:
                        show(r)
                    click.echo("ok")
                    if not tty and name in WAITS_FOR_END:
                        wait_end(name)
                except LocalError as e:
                    con.print(f"[red]{escape(str(e))}[/]")
                    failures.append(e.exit_code)
                except BoardError as e:
                    for r in e.reports:
                        show(r)
                    with lock:
                        con.print(f"[red]{escape(explain(e, c))}[/]")
                    failures.append(e.exit_code)
                except (ReplyTimeout, BoardReset) as e:
                    con.print(f"[yellow]{escape(str(e))}[/]")
                    failures.append(e.exit_code)
            if not tty:
                time.sleep(0.3)  # trailing reports of the last command
        except KeyboardInterrupt:
            if not lost:
                raise
        finally:
            stop.set()
            th.join(timeout=1.0)
            if tty and readline is not None:
                try:
                    readline.write_history_file(HISTORY_FILE)
                except OSError:
                    pass
        if lost:
            raise lost[0]
    if failures and not tty:
        sys.exit(failures[0])
