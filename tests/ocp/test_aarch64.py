"""The aarch64 Linux target of the C export (a Cortex-A flight computer).

Skipped without aarch64-linux-gnu-gcc and qemu-aarch64 (Debian:
``apt-get install gcc-aarch64-linux-gnu libc6-dev-arm64-cross
qemu-user``; `.ci/run` installs them).
"""

import shutil
import subprocess

import numpy as np
import pytest

from ocp.codegen.export import export_c, run_driver
from ocp.codegen.linux_target import (AARCH64_CC, AARCH64_QEMU,
                                      linux_toolchain_missing)

pytestmark = [
    pytest.mark.slow,
    pytest.mark.skipif(linux_toolchain_missing() is not None,
                       reason=str(linux_toolchain_missing())),
]

LOOP = "closed_loop:mpc_cond_rti_step"


@pytest.mark.parametrize("precision", ["double", "single"])
def test_aarch64_closed_loop_equals_the_host(tmp_path, precision):
    """The condensed RTI step's closed loop, built for aarch64 (static,
    no warnings under -Wall -Wextra) and run under qemu-aarch64, ends in
    the host driver's final state (1e-9; both C99, so neither contracts
    a product and a sum into one rounding), every call returning 0."""
    kw = dict(mpc_variants=("mpc_cond_rti_step",), repeats=3,
              precision=precision)
    a64 = export_c(tmp_path / "a64", "demo", target="aarch64", build=True,
                   **kw)
    assert a64.extras["warnings"] == 0, a64.extras["warning_text"]
    assert a64.shared_library is None
    assert a64.extras["runner"] == [AARCH64_QEMU]
    arch = subprocess.run(["file", str(a64.executable)], capture_output=True,
                          text=True).stdout if shutil.which("file") else ""
    assert not arch or "aarch64" in arch, arch
    host = export_c(tmp_path / "host", "demo", build=True, **kw)
    ta, th = run_driver(a64), run_driver(host)
    assert ta[LOOP]["loop_ok"] == 1 and ta[LOOP]["flag"] == 0
    for name, rec in ta.items():
        if not name.startswith("_"):
            assert rec["flag"] == 0, name
    np.testing.assert_allclose(ta[LOOP]["state"], th[LOOP]["state"],
                               rtol=0, atol=1e-9)
    assert ta[LOOP]["final_error_deg"] == pytest.approx(
        th[LOOP]["final_error_deg"], abs=1e-9)


def test_the_folder_cross_builds_with_its_own_makefile(tmp_path):
    """The export folder, copied alone, builds its driver for aarch64 with
    its Makefile (CC overridden) under -Wall -Wextra -Werror."""
    res = export_c(tmp_path / "src", "demo", mpc_variants=(), repeats=3)
    folder = shutil.copytree(res.out_dir, tmp_path / "copy")
    run = subprocess.run(["make", "-C", str(folder), f"CC={AARCH64_CC}",
                          "adcs_driver"],
                         capture_output=True, text=True, timeout=600)
    assert run.returncode == 0, run.stdout + run.stderr
    assert "warning" not in run.stdout + run.stderr
    exe = folder / "adcs_driver"     # dynamic: the cross libc's loader
    out = subprocess.run([AARCH64_QEMU, "-L", "/usr/aarch64-linux-gnu",
                          str(exe)], capture_output=True, text=True,
                         timeout=300)
    assert out.returncode == 0 and "TIME wheel_qp " in out.stdout


def test_cli_export_aarch64_runs_the_driver(tmp_path, capsys):
    from adcs.cli import main

    assert main(["export", "--target", "aarch64", "--mpc", "",
                 "--out", str(tmp_path), "--run"]) == 0
    text = capsys.readouterr().out
    assert "aarch64-linux-gnu-gcc -static (-Wall -Wextra): 0 warnings" \
        in text
    assert "qemu-aarch64" in text and "wheel_qp" in text
