"""hallhome host toolkit: robot model, field model, table generator, serial client."""

from hallhome.paths import project_version

__version__ = project_version()
