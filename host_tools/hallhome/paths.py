"""Where the project's shared files live, found from this package's location."""

from pathlib import Path

PACKAGE_DIR = Path(__file__).resolve().parent
PROJECT_ROOT = PACKAGE_DIR.parent.parent
LIB_DIR = PROJECT_ROOT / "lib"
TABLES_DIR = PROJECT_ROOT / "lookup_tables"
ROBOTS_DIR = TABLES_DIR / "robots"
GENERATED_DIR = TABLES_DIR / "generated"


def project_version() -> str:
    """The single version string of the project (the VERSION file at the root)."""
    try:
        return (PROJECT_ROOT / "VERSION").read_text(encoding="ascii").strip()
    except OSError:
        return "0+unknown"
