"""`adcs`: the application: command line, report, studies, benchmarks."""

from adcs_common.version import version

#: The toolbox's version (one source: `adcs_common.version`).
__version__ = version()

__all__ = ["__version__"]
