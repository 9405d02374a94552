"""The `hallhome` command. Each subcommand lives in its own module and is
registered here with `main.add_command`."""

import click

from hallhome import __version__


@click.group(context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(__version__, prog_name="hallhome")
def main() -> None:
    """hallhome: tension calibration for tendon-driven continuum robots.

    Host side of the hallhome calibrator: robot descriptions, the static and
    magnetic models, the lookup-table generator and the serial client for the
    Arduino Mega firmware.
    """
