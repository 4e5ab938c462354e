"""Exported C on an emulated aarch64 Linux computer (Cortex-A53 class).

Flight computers of larger small satellites run Linux on Cortex-A cores.
``export_c(target="aarch64")`` writes the host export (the same
``main.c`` driver, ``casadi_int`` 64-bit) and builds its driver with the
cross compiler `AARCH64_CC` into a static executable, which `run_driver`
runs under qemu's user-mode emulator `AARCH64_QEMU`. The driver's
answers are the figures to read there: its closed loop ends in the
host's final state (to rounding: another compiler, another FPU); its
times are the emulator's on this machine, not the board's. No shared
library is built (the x86 Python cannot load it).
"""

from __future__ import annotations

import shutil

#: Cross compiler and user-mode emulator of ``target="aarch64"``.
AARCH64_CC = "aarch64-linux-gnu-gcc"
AARCH64_QEMU = "qemu-aarch64"

#: Linux targets: name -> (compiler, emulator prefix of the driver,
#: flags of the driver's link). aarch64's is static, so that the emulator
#: needs no aarch64 system libraries.
LINUX_TARGETS = {"aarch64": (AARCH64_CC, (AARCH64_QEMU,), ("-static",))}


#: How to install a Linux target's compiler and emulator.
LINUX_INSTALL = {"aarch64": "Debian: apt-get install gcc-aarch64-linux-gnu "
                            "libc6-dev-arm64-cross qemu-user"}


def linux_toolchain_missing(target: str = "aarch64", run: bool = True
                            ) -> str | None:
    """Why a Linux target cannot be built (or run) here, or None."""
    cc, runner, _ = LINUX_TARGETS[target]
    missing = [t for t in (cc, *(runner if run else ()))
               if shutil.which(t) is None]
    if missing:
        return f"needs {' and '.join(missing)} ({LINUX_INSTALL[target]})"
    return None
