"""`hallhome monitor`: the live field of each sensor."""

from __future__ import annotations

import math
import time
from typing import Dict, List, Tuple

import click
from rich.live import Live
from rich.markup import escape
from rich.table import Table

from hallhome.client import BoardError, BoardReset, Client
from hallhome.op_common import R, cmd, err, operator_command, out, port_options, session

SPARK = "▁▂▃▄▅▆▇█"


def sparkline(values: List[float], width: int = 40) -> str:
    v = values[-width:]
    if not v:
        return ""
    lo, hi = min(v), max(v)
    span = hi - lo or 1.0
    return "".join(SPARK[min(len(SPARK) - 1, int((x - lo) / span * (len(SPARK) - 1) + 0.5))] for x in v)


def sample_fields(c: Client) -> List[Tuple[int, bool, float, Tuple[float, float, float]]]:
    out_ = []
    for r in c.command(cmd("sensors")).of(R.SENSOR):
        b = tuple(r.num(k, 0.0) for k in ("bx_uT", "by_uT", "bz_uT"))
        out_.append((int(r.get("index")), r.get("ok") == 1, math.sqrt(sum(x * x for x in b)), b))
    return out_


@click.command("monitor")
@click.option("--samples", "-n", type=click.IntRange(min=0), default=0,
              help="Stop after this many samples (default: until Ctrl-C).")
@click.option("--interval", type=click.FloatRange(min=0.05), default=0.2, show_default=True,
              help="Seconds between samples.")
@click.option("--plot", "plot_path", type=click.Path(dir_okay=False), default=None,
              help="Also write a PNG of |B| over time per sensor at the end.")
@port_options
@operator_command
def monitor_cmd(samples, interval, plot_path, port, timeout) -> None:
    """Live field of each sensor: |B| and its change since the start, with a
    terminal chart (one line per sample when the output is not a terminal)."""
    con = out()
    hist: Dict[int, List[float]] = {}
    times: List[float] = []
    t0 = time.monotonic()
    with session(port, timeout) as c:
        live = con.is_terminal

        def render() -> Table:
            t = Table("sensor", "ok", "|B| uT", "change uT", "last samples", title="field (Ctrl-C to stop)")
            for k in sorted(hist):
                v = hist[k]
                t.add_row(str(k), "yes" if ok.get(k) else "[red]NO[/]", f"{v[-1]:.2f}", f"{v[-1] - v[0]:+.2f}",
                          sparkline(v))
            return t

        ok: Dict[int, bool] = {}
        count = 0
        try:
            ctx = Live(render(), console=con, refresh_per_second=8) if live else None
            if ctx:
                ctx.__enter__()
            try:
                while samples == 0 or count < samples:
                    tick = time.monotonic()
                    try:
                        data = sample_fields(c)
                    except BoardReset as e:
                        err().print(f"[yellow]{escape(str(e))}; monitoring goes on[/]")
                        continue
                    except BoardError as e:
                        if e.name != "BUSY":
                            raise
                        time.sleep(interval)  # still booting after a reset
                        continue
                    times.append(tick - t0)
                    for k, okk, mag, _ in data:
                        hist.setdefault(k, []).append(mag)
                        ok[k] = okk
                    count += 1
                    if ctx:
                        ctx.update(render())
                    else:
                        con.print(f"{tick - t0:8.2f} s  " + "  ".join(
                            f"s{k}={mag:.2f}uT" + ("" if okk else "(fault)") for k, okk, mag, _ in data))
                    time.sleep(max(0.0, interval - (time.monotonic() - tick)))
            finally:
                if ctx:
                    ctx.__exit__(None, None, None)
        except KeyboardInterrupt:
            pass
    if plot_path and times:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
        fig, ax = plt.subplots(figsize=(8, 4.5))
        for k, v in sorted(hist.items()):
            ax.plot(times[-len(v):], v, label=f"sensor {k}")
        ax.set_xlabel("time (s)")
        ax.set_ylabel("|B| (uT)")
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize="small")
        fig.tight_layout()
        fig.savefig(plot_path, dpi=100)
        plt.close(fig)
        con.print(f"plot: {plot_path}")
