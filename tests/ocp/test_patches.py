"""Exact edits of generated C: `casadi_zeros` sized for the NULLs that
occur; one-statement bodies in braces."""

import shutil
import subprocess

import pytest

from ocp.codegen.patches import _input_nnz, patch_braces, patch_zeros

HEAD = "static const casadi_real casadi_zeros[500] = \n  {0.};\n"


def _source(call: str) -> str:
    return HEAD + (
        "/* conic:(h[3x3,3nz],g[3],a[160x80,6720nz],q[],p[])->(x[3]) */\n"
        "static int casadi_f7(const casadi_real** arg) {\n}\n"
        "static int casadi_f8(const casadi_real** arg) {\n"
        f"  arg1[0]=w0;\n{call}\n"
        "  if (casadi_f7(arg1, res1, iw, w, 0)) return 1;\n}\n")


def test_signature_nonzeros():
    assert _input_nnz("x[11],A[11x11,69nz],q[],t,h[4x3]") == [11, 69, 0,
                                                              1, 12]


def test_zeros_keep_the_public_inputs_and_the_null_arguments():
    # only the empty conic inputs are passed as NULL: the public inputs
    # set the size
    text, size = patch_zeros(_source("  arg1[3]=0;\n  arg1[4]=0;"), 311)
    assert size == 311
    assert "casadi_zeros[311] = \n  {0.};" in text
    # a NULL for the 3-element gradient needs no more
    assert patch_zeros(_source("  arg1[1]=0;"), 2)[1] == 3
    # a NULL for the 6,720-nonzero matrix: larger than the array, no edit
    assert patch_zeros(_source("  arg1[2]=0;"), 311) == (
        _source("  arg1[2]=0;"), 0)


def test_an_unreadable_callee_leaves_the_file_as_it_is():
    src = _source("  arg1[1]=0;").replace("/* conic:", "/* conic ")
    assert patch_zeros(src, 10) == (src, 0)
    assert patch_zeros("no zeros here", 10) == ("no zeros here", 0)


@pytest.mark.parametrize("line, braced", [
    ("  if (res[0]!=0) res[0][3]=a2;", "  if (res[0]!=0) {res[0][3]=a2;}"),
    ("for (i=0, rr=w1; i<4; ++i) *rr++ = *cs++;",
     "for (i=0, rr=w1; i<4; ++i) {*rr++ = *cs++;}"),
    ("for (rr=w2; rr!=w2+9; rr+=3) for (tt=rr; tt!=rr+3; ++tt) *tt = 0;",
     "for (rr=w2; rr!=w2+9; rr+=3) {for (tt=rr; tt!=rr+3; ++tt) "
     "{*tt = 0;}}"),
    ("if (casadi_f3(arg, res, iw, w, 0)) return 1;",
     "if (casadi_f3(arg, res, iw, w, 0)) {return 1;}"),
    ("while (n--) *y++ = (x ? *x++ : 0);",
     "while (n--) {*y++ = (x ? *x++ : 0);}"),
    # not plainly one statement: as it is
    ("if (a) x=1; else y=2;", None),
    ("if (a) x=1; y=2;", None),
    ('if (v) printf("a;b");', None),
    ("} while (k);", None),
    ("while (k);", None),                     # a do-while's end
    ("for (i=0; i<n; ++i) {", None),
])
def test_one_statement_bodies_are_braced(line, braced):
    text, count = patch_braces(line)
    assert text == (line if braced is None else braced)
    assert count == (braced is not None)


def test_braces_leave_the_compiled_code_as_it_was(tmp_path):
    """The same object code, braced or not (gcc -O2)."""
    cc = shutil.which("gcc")
    if cc is None:
        pytest.skip("no gcc")
    src = ("double f(const double* x, double* y, int n) {\n"
           "  int i; double s = 0;\n"
           "  for (i=0; i<n; ++i) s += x[i];\n"
           "  if (y) for (i=0; i<n; ++i) y[i] = s * x[i];\n"
           "  while (n--) if (x[n] < 0) return -1;\n"
           "  return s;\n}\n")
    braced, count = patch_braces(src)
    assert count == 3 and braced != src
    code = []
    for name, text in (("plain", src), ("braced", braced)):
        c = tmp_path / f"{name}.c"
        c.write_text(text)
        subprocess.run([cc, "-O2", "-std=c99", "-Wall", "-Wextra", "-Werror",
                        "-c", str(c), "-o", str(c.with_suffix(".o"))],
                       check=True)
        subprocess.run(["objcopy", "-O", "binary", "--only-section=.text",
                        str(c.with_suffix(".o")), str(c.with_suffix(".bin"))],
                       check=True)
        code.append(c.with_suffix(".bin").read_bytes())
    assert code[0] == code[1]
