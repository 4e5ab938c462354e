"""`adcs`: the application: command line, report, studies, benchmarks."""

from .provenance import version

__version__ = version()

__all__ = ["__version__"]
