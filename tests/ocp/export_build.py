"""What the export tests share: the heap's entry points, a build with
the system's tools alone, the symbols objects leave undefined and a
driver linked against a heap that traps."""

import shutil
import subprocess
from pathlib import Path

#: The allocator's entry points no exported function may reach.
HEAP = ("malloc", "calloc", "realloc", "free")

#: Only the system's tools: no virtual environment, no casadi folder.
SYSTEM_ENV = {"PATH": "/usr/bin:/bin", "LC_ALL": "C"}

#: A heap that aborts: linked before libc, it takes every allocation of
#: the program (C library calls included: the driver writes stdout
#: through a static buffer).
TRAP_HEAP = r"""
#include <stdlib.h>
#include <unistd.h>
static void trap(const char* what) {
  write(2, "heap trap: ", 11); write(2, what, 7); write(2, "\n", 1);
  abort();
}
void* malloc(size_t n) { (void)n; trap("malloc "); return 0; }
void* calloc(size_t n, size_t m) {
  (void)n; (void)m; trap("calloc "); return 0;
}
void* realloc(void* p, size_t n) {
  (void)p; (void)n; trap("realloc"); return 0;
}
void free(void* p) { if (p) trap("free   "); }
"""


def undefined_symbols(objects: list[Path], nm: str = "nm") -> set[str]:
    """Symbols the objects use but do not define (``nm -u``)."""
    out = subprocess.run([nm, "-u", *map(str, objects)],
                         capture_output=True, text=True, check=True).stdout
    return {ln.split()[-1] for ln in out.splitlines()
            if ln.strip() and not ln.endswith(":")}


def driver_on_a_trapping_heap(dst: Path, objects: list[Path]
                              ) -> subprocess.CompletedProcess:
    """The folder's driver linked to `TRAP_HEAP`, run; asserts it ran
    through without a heap call."""
    (dst / "trap_heap.c").write_text(TRAP_HEAP)
    subprocess.run(["cc", "-O2", "-std=c99", "-c", "-o", "main_trap.o",
                    "main.c"], cwd=dst, env=SYSTEM_ENV, check=True)
    link = ["cc", "-o", "driver_trap", "trap_heap.c", "main_trap.o",
            *[str(p.relative_to(dst)) for p in objects], "-lm"]
    subprocess.run(link, cwd=dst, env=SYSTEM_ENV, check=True)
    drv = subprocess.run(["./driver_trap"], cwd=dst, env=SYSTEM_ENV,
                         capture_output=True, text=True, timeout=300)
    assert drv.returncode == 0, drv.stderr[-2000:]
    assert "heap trap" not in drv.stderr
    return drv


def make_copy(folder: Path, dst: Path) -> subprocess.CompletedProcess:
    """The export ``folder`` copied to ``dst`` (stale objects removed)
    and built there by make alone, with the system's tools; asserts the
    build passed under -Werror without a warning."""
    shutil.copytree(folder, dst)
    for stale in dst.rglob("*.o"):
        stale.unlink()
    run = subprocess.run(["make", "-j2"], cwd=dst, env=SYSTEM_ENV,
                         capture_output=True, text=True, timeout=600)
    assert run.returncode == 0, run.stderr[-3000:]
    assert "-Werror" in run.stdout and "warning" not in run.stderr
    return run


def check_heap_free(dst: Path, objects: list[Path], loop: str) -> None:
    """No allocator among the symbols ``objects`` leave undefined; the
    copy's driver runs, and again linked (with DAQP's objects) against
    a heap that traps, each reaching the closed loop ``loop``."""
    assert not undefined_symbols(objects) & set(HEAP)
    drv = subprocess.run(["./adcs_driver"], cwd=dst, env=SYSTEM_ENV,
                         capture_output=True, text=True, timeout=300)
    assert drv.returncode == 0 and f"TIME {loop} " in drv.stdout
    trapped = driver_on_a_trapping_heap(
        dst, [*objects, *sorted((dst / "daqp").glob("*.o"))])
    assert f"TIME {loop} " in trapped.stdout
