"""The installed distribution's version: pyproject.toml is the one place it is written."""
from __future__ import annotations


def installed_version() -> str:
    """The version of the installed distribution (pyproject.toml, the one place it is written), or
    "unknown" when run from a source tree that was not installed."""
    from importlib import metadata

    try:
        return metadata.version("jointfem")
    except metadata.PackageNotFoundError:
        return "unknown"
