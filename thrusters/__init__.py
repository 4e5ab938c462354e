"""`thrusters`: six-thruster unit, duty-cycle laws and allocator.

Citations: [1]–[4] are the source papers and "theory §N" the sections of
the project's docs (docs/references.md and docs/theory.md in the
repository; the misprints the code corrects are in docs/errata.md).
"""

from adcs_common.version import version as _version
from .exceptions import (
    AdcsError,
    InfeasibleError,
    InvalidValueError,
    ShapeError,
    SolverError,
    SolverNotFound,
)
from .laws import (
    THRUST_AXIS,
    TORQUE_AXES,
    LawResult,
    pair_forces,
    reorientation_law,
    unloading_law,
)
from .qp import (
    DUTY_STATUS,
    DutyAllocation,
    DutyCycleAllocator,
    DutyCycleQP,
    MinOnTimeCarry,
    available_solvers,
    build_qp,
    certified_duty_function,
)
from .scenarios import (
    ScenarioResult,
    burn_scenario,
    reorientation_scenario,
)
from .symbolic import force_torque_function, six_unit_function
from .tables import (
    burn_table,
    format_table,
    table_frame,
    plot_scenario,
    reorientation_table,
)
from .unit import (
    G0,
    KGF_PER_CM2,
    SIX_UNIT_PAIRS,
    ThrusterSet,
    six_thruster_unit,
)

#: The toolbox's version (one source: `adcs_common.version`).
__version__ = _version()

__all__ = [
    "AdcsError",
    "DUTY_STATUS",
    "DutyAllocation",
    "DutyCycleAllocator",
    "DutyCycleQP",
    "G0",
    "InfeasibleError",
    "InvalidValueError",
    "KGF_PER_CM2",
    "LawResult",
    "MinOnTimeCarry",
    "SIX_UNIT_PAIRS",
    "ScenarioResult",
    "ShapeError",
    "SolverError",
    "SolverNotFound",
    "THRUST_AXIS",
    "TORQUE_AXES",
    "ThrusterSet",
    "available_solvers",
    "build_qp",
    "burn_scenario",
    "burn_table",
    "certified_duty_function",
    "force_torque_function",
    "format_table",
    "table_frame",
    "pair_forces",
    "plot_scenario",
    "reorientation_law",
    "reorientation_scenario",
    "reorientation_table",
    "six_thruster_unit",
    "six_unit_function",
    "unloading_law",
]
