"""The C export as flight code: a folder that builds alone, and no heap.

Issue #28 items 1-2: every solver source travels in the export folder
(DAQP, vendored, with its licence), nothing names the build machine's
paths, the folder builds with a C compiler and libm alone (make or
CMake, -Wall -Wextra -Werror), and no exported function reaches malloc,
calloc, realloc or free (checked on the objects' symbol tables and by a
driver linked against a heap that aborts): the condensed steps with
DAQP, and the stage-wise and robust steps (host, and the Cortex-M7's
symbols).
"""

import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import casadi as ca
import pytest

from adcs_common.exceptions import AdcsError
from allocation import WheelArray
from ocp.codegen.daqp_static import (
    DAQP_HEADERS,
    DAQP_SOURCES,
    patch_daqp_static,
    vendored_daqp,
)
from ocp.codegen.export import daqp_available, export_c
from ocp.codegen.target import toolchain_missing
from thrusters import six_thruster_unit

from export_build import (HEAP, SYSTEM_ENV, driver_on_a_trapping_heap,
                          undefined_symbols)

pytestmark = [
    pytest.mark.slow,
    pytest.mark.skipif(shutil.which("cc") is None
                       or shutil.which("make") is None,
                       reason="needs cc and make"),
]

@pytest.fixture(scope="module")
def exported(tmp_path_factory):
    """A DAQP-heavy export: wheel_qp's conic, duty_qp, condensed MPC."""
    if not daqp_available():
        pytest.skip("needs casadi's daqp plugin")
    out = tmp_path_factory.mktemp("flight") / "adcs-c"
    return export_c(out, wheels=WheelArray.pyramid(h_max=0.2, m_max=0.05),
                    thrusters=six_thruster_unit(),
                    mpc_variants=("mpc_cond_rti_step", "mpc_cond_step"),
                    wheel_qp_fast_path=False, repeats=50)


@pytest.fixture(scope="module")
def built(exported, tmp_path_factory):
    """The folder copied elsewhere and built there by make alone."""
    dst = tmp_path_factory.mktemp("elsewhere") / "copy"
    shutil.copytree(exported.out_dir, dst)
    run = subprocess.run(["make", "-j2"], cwd=dst, env=SYSTEM_ENV,
                         capture_output=True, text=True, timeout=600)
    assert run.returncode == 0, run.stderr[-3000:]
    return dst, run


def _objects(folder: Path) -> list[Path]:
    return [folder / "adcs_codegen.o"] + [
        folder / "daqp" / n.replace(".c", ".o") for n in DAQP_SOURCES]


def test_every_daqp_function_uses_the_vendored_sources(exported):
    r = exported
    assert set(r.extras["daqp_static"]) and r.extras["daqp_static_bytes"]
    text = r.source.read_text()
    assert '#include "daqp/api.h"' in text and "<daqp/" not in text
    assert "setup_daqp(" not in text and "free_daqp_" not in text
    for name in (*DAQP_SOURCES, *DAQP_HEADERS, "LICENSE", "README.md"):
        assert (r.out_dir / "daqp" / name).is_file(), name
    assert "MIT License" in (r.out_dir / "daqp" / "LICENSE").read_text()
    for name in ("Makefile", "CMakeLists.txt"):
        body = (r.out_dir / name).read_text()
        assert all(f"daqp/{s}" in body for s in DAQP_SOURCES), name


def test_nothing_names_the_build_machines_paths(exported):
    import ocp

    machine = {sys.prefix, sys.base_prefix, sys.exec_prefix,
               str(Path(ca.__file__).parent),
               str(Path(ocp.__file__).resolve().parents[1]),
               str(exported.out_dir), str(exported.out_dir.resolve()),
               str(Path.home()), os.getcwd(), "site-packages",
               "libdaqpstat"}
    for path in exported.out_dir.rglob("*"):
        if path.is_file():
            text = path.read_text(encoding="utf-8")
            for p in machine:
                assert p not in text, (path.name, p)
    # no absolute path in what the build reads
    for name in ("Makefile", "CMakeLists.txt"):
        body = (exported.out_dir / name).read_text()
        assert not re.search(r"(^|[\s=\"'(])/\w", body, re.M), name


def test_the_folder_builds_alone_warning_free_and_runs(built):
    """Copied elsewhere: make with the system cc, -Wall -Wextra -Werror."""
    dst, run = built
    assert "-Wall -Wextra -Werror" in run.stdout
    assert "warning" not in run.stderr
    drv = subprocess.run(["./adcs_driver"], cwd=dst, env=SYSTEM_ENV,
                         capture_output=True, text=True, timeout=300)
    assert drv.returncode == 0, drv.stdout[-2000:] + drv.stderr[-2000:]
    times = [ln for ln in drv.stdout.splitlines() if ln.startswith("TIME")]
    for name in ("wheel_qp", "duty_qp", "mpc_cond_rti_step",
                 "mpc_cond_step", "closed_loop:mpc_cond_rti_step"):
        assert any(ln.startswith(f"TIME {name} ") for ln in times), name
    assert all("flag=0" in ln for ln in times if "flag=" in ln)


def test_no_exported_function_reaches_the_heap(built):
    """Symbol tables: no allocator; a driver linked to a trapping heap."""
    dst, _ = built
    undefined = undefined_symbols(_objects(dst))
    assert undefined & set(HEAP) == set(), undefined & set(HEAP)
    assert "sqrt" in undefined          # nm did read the objects
    drv = driver_on_a_trapping_heap(dst, _objects(dst))
    assert drv.stdout.count("TIME ") >= 10
    # the trap springs: a call of malloc from the same objects aborts
    (dst / "uses_heap.c").write_text(
        "#include <stdlib.h>\nint main(void) { void* p = malloc(8); "
        "free(p); return p == 0; }\n")
    subprocess.run(["cc", "-O0", "-o", "uses_heap", "trap_heap.c",
                    "uses_heap.c"], cwd=dst, env=SYSTEM_ENV, check=True)
    bad = subprocess.run(["./uses_heap"], cwd=dst, capture_output=True,
                         text=True, timeout=60)
    assert bad.returncode != 0 and "heap trap: malloc" in bad.stderr


#: The stage-wise and robust MPC steps (their own runtimes: the Riccati
#: interior point with its polish, the scenario tree of 9 plants) at the
#: smallest horizon, 2, whose code is the horizon-20 code with shorter
#: loops: 1.7 MB of C, a few seconds to build at -O1.
SW_ROBUST = ("mpc_sw_step", "mpc_sw_rti_step", "mpc_robust_rti_step")


def _sw_robust_export(out: Path, **kw):
    return export_c(out, wheels=WheelArray.pyramid(h_max=0.2, m_max=0.05),
                    horizon=2, mpc_variants=SW_ROBUST, repeats=5, **kw)


def test_stagewise_and_robust_steps_never_reach_the_heap(tmp_path):
    """The stage-wise and robust exports (host build, the folder copied
    elsewhere): no allocator in the symbol table, and the driver, linked
    to a heap that aborts, flies each step's 86-step closed loop to its
    target with every call returning 0."""
    res = _sw_robust_export(tmp_path / "adcs-c")
    dst = tmp_path / "copy"
    shutil.copytree(res.out_dir, dst)
    run = subprocess.run(["make", "-j2", "adcs_codegen.o",
                          "CFLAGS=-O1 -std=c99"], cwd=dst, env=SYSTEM_ENV,
                         capture_output=True, text=True, timeout=600)
    assert run.returncode == 0, run.stderr[-3000:]
    objects = [dst / "adcs_codegen.o"]
    undefined = undefined_symbols(objects)
    assert undefined & set(HEAP) == set(), undefined & set(HEAP)
    assert "sqrt" in undefined          # nm did read the object
    drv = driver_on_a_trapping_heap(dst, objects)
    loops = {ln.split()[1]: ln for ln in drv.stdout.splitlines()
             if ln.startswith("LOOP ")}
    for name in SW_ROBUST:
        line = loops[f"closed_loop:{name}"]
        assert "steps=86" in line and " flag=0 " in line, line
        assert line.endswith(" ok=1"), line


@pytest.mark.skipif(toolchain_missing() is not None,
                    reason=str(toolchain_missing()))
def test_stagewise_and_robust_steps_have_no_heap_on_the_m7(tmp_path):
    """The same steps cross-compiled for the Cortex-M7 (-O3): no
    allocator in the object's symbol table, nor among the library calls
    of any function linked alone (the memory report)."""
    res = _sw_robust_export(tmp_path / "m7", target="cortex-m7",
                            build=True)
    obj = res.out_dir / "adcs_codegen_cortex-m7.o"
    undefined = undefined_symbols([obj], "arm-none-eabi-nm")
    assert undefined & set(HEAP) == set(), undefined & set(HEAP)
    assert "sqrt" in undefined
    functions = res.extras["memory"]["functions"]
    for name in SW_ROBUST:
        rec = functions[name]
        assert rec["heap"] is False and rec["flash"] > 100_000, (name, rec)
        assert not set(rec["library_calls"]) & set(HEAP), rec


@pytest.mark.skipif(shutil.which("cmake") is None, reason="needs cmake")
def test_cmake_builds_the_folder(exported, tmp_path):
    src = tmp_path / "adcs-c"
    shutil.copytree(exported.out_dir, src)
    build = tmp_path / "build"
    env = {**SYSTEM_ENV, "CC": "cc"}
    for cmd in (["cmake", "-S", str(src), "-B", str(build),
                 "-DCMAKE_BUILD_TYPE=Release"],
                ["cmake", "--build", str(build), "-j2"]):
        run = subprocess.run(cmd, env=env, capture_output=True, text=True,
                             timeout=600)
        assert run.returncode == 0, run.stdout[-2000:] + run.stderr[-2000:]
    drv = subprocess.run([str(build / "adcs_driver")], env=SYSTEM_ENV,
                         capture_output=True, text=True, timeout=300)
    assert drv.returncode == 0 and "TIME duty_qp " in drv.stdout


def test_vendored_daqp_is_the_api_casadi_generates_for():
    """The vendored headers are the casadi wheel's (DAQP 0.5.1)."""
    ours = vendored_daqp()
    theirs = Path(ca.__file__).parent / "include" / "daqp"
    if not (theirs / "api.h").is_file():
        pytest.skip("this casadi ships no DAQP headers")
    for name in DAQP_HEADERS:
        assert (ours / name).read_bytes() == (theirs / name).read_bytes(), \
            name
    api = (ours / "api.c").read_text()
    for gone in ("malloc", "free(", "setup_daqp(", "allocate_daqp_"):
        assert gone not in api.split("*/", 1)[1], gone


def test_static_patch_refuses_a_runtime_it_does_not_know():
    text = ("#include <daqp/api.h>\nint casadi_daqp_solve(void) "
            "{ return setup_daqp(0, 0, 0); }\n")
    with pytest.raises(AdcsError, match="would allocate"):
        patch_daqp_static(text)
    plain = "int main(void) { return 0; }\n"
    assert patch_daqp_static(plain) == (plain, {})

