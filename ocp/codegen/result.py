"""What an export wrote: file names, build flags, the result record."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
import casadi as ca
import numpy as np
from adcs_common.results import ResultMixin


#: Base name of the generated source and header.
SOURCE = "adcs_codegen"


#: Optimisation flags of the builds (driver, object, shared library).
OPT_FLAGS = ("-O3",)


@dataclass(frozen=True, eq=False, repr=False)
class ExportResult(ResultMixin):
    """What `export_c` wrote (and built).

    Attributes
    ----------
    out_dir : pathlib.Path
        The output folder.
    functions : dict of str to casadi.Function
        The exported Functions by C name (the Python reference of each).
    samples : dict of str to list of numpy.ndarray
        The sample inputs compiled into the driver (by C name; keys
        ``"name:label"`` are extra cases of ``name`` the driver also times,
        e.g. ``"wheel_qp:saturated"``).
    source, header, driver, makefile, readme : pathlib.Path
        The files written.
    executable : pathlib.Path or None
        The built driver (None unless ``build=True``).
    shared_library : pathlib.Path or None
        The built shared library (None unless ``build=True``).
    extras : dict
        ``wheel_qp_plugin`` (conic of ``wheel_qp``), ``wheel_qp_method``
        (`allocation.qp.conic_function.wheel_qp_method`: ``"closed
        form"``, ``"min-norm check + conic"`` or ``"conic"``),
        ``solver_sources`` (the C sources written beside the source:
        DAQP's in ``daqp/``, empty without DAQP), ``daqp_static`` (C name
        of each DAQP conic -> reals and ints of its static workspace,
        `ocp.codegen.patch_daqp_static`), ``daqp_static_bytes`` (their
        sum), ``cflags``/``ldflags`` (``["-DDAQP_SINGLE_PRECISION"]`` in
        single precision with DAQP, else ``[]``; ``["-lm"]``: the folder
        builds alone), ``qrqp_patched`` (`patch_qrqp` was
        applied); after a build ``warnings``, ``warning_text`` and
        ``objects``; a Cortex-M export adds ``target``, ``c_sources`` /
        ``c_include`` (extra C the target build compiles: DAQP's, when
        the folder carries it) and, built, ``memory``
        (`ocp.codegen.memory.memory_report`).
    """

    out_dir: Path
    functions: dict[str, ca.Function]
    samples: dict[str, list[np.ndarray]]
    source: Path
    header: Path
    driver: Path
    makefile: Path
    readme: Path
    executable: Path | None = None
    shared_library: Path | None = None
    extras: dict = field(default_factory=dict)
