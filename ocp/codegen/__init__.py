"""C code generation: export, build and run the generated solvers."""

from .checks import DriverCheckError
from .export import (
    CompilerNotFound,
    ExportResult,
    build_exported,
    daqp_available,
    default_functions,
    duty_qp_function,
    export_c,
    patch_daqp_failure,
    patch_daqp_static,
    patch_daqp_warm_start,
    patch_minmax,
    patch_qrqp,
    run_driver,
)

__all__ = [
    "CompilerNotFound",
    "DriverCheckError",
    "ExportResult",
    "build_exported",
    "daqp_available",
    "default_functions",
    "duty_qp_function",
    "export_c",
    "patch_daqp_failure",
    "patch_daqp_static",
    "patch_daqp_warm_start",
    "patch_minmax",
    "patch_qrqp",
    "run_driver",
]
