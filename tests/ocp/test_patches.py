"""Exact edits of generated C: `casadi_zeros` sized for the NULLs that occur."""

from ocp.codegen.patches import _input_nnz, patch_zeros

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
