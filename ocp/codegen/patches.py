"""Small exact edits of CasADi-generated C (DAQP failures, fmax/fmin,
braces)."""

from __future__ import annotations

import re

import numpy as np

#: CasADi's generated DAQP conic aborts the whole Function on a failed
#: solve (its ``error_on_fail`` option is not generated), before the
#: caller's certificate can read the point.
_DAQP_ABORT = "  if (!d_qp.success) {\n    return -1;\n  }\n"
_DAQP_CHECKED = ("  /* a failed solve is judged by the caller's certificate "
                 "(ocp.codegen.patch_daqp_failure) */\n")


def patch_daqp_failure(source: str) -> tuple[str, int]:
    """Let generated DAQP conics return their point when a solve fails.

    Every Function of the toolbox that calls DAQP checks the point
    (``wheel_qp``'s violation, ``duty_qp``'s KKT certificate and status),
    as the Python Functions built with ``error_on_fail=False`` do; the
    generated C would instead return 1 from the whole call and leave the
    outputs unwritten. This edit removes that early return.

    Parameters
    ----------
    source : str
        Generated C text.

    Returns
    -------
    text : str
        The edited text.
    count : int
        DAQP conics edited (0: none in the source, or a CasADi version
        whose text differs).
    """
    count = source.count(_DAQP_ABORT)
    return source.replace(_DAQP_ABORT, _DAQP_CHECKED), count


#: CasADi's C99 min/max helpers call libm's fmax/fmin, which gcc does not
#: inline (their NaN rules); the same rules written as comparisons let it.
_MINMAX_EDITS = (
    ("  return fmax(x, y);\n#endif",
     "  return x != x ? y : (y != y || x > y) ? x : y;\n#endif"),
    ("  return fmin(x, y);\n#endif",
     "  return x != x ? y : (y != y || x < y) ? x : y;\n#endif"),
)


def patch_minmax(source: str) -> tuple[str, int]:
    """Write the generated ``casadi_fmax``/``casadi_fmin`` inline.

    Same results as C99 ``fmax``/``fmin``, NaN rules included (a NaN
    argument gives the other one); the compiler can then inline them
    (about 10 % off the certified duty QP, which takes many maxima).

    Returns
    -------
    text : str
        The edited text.
    count : int
        Helpers edited (0 to 2).
    """
    count = 0
    for old, new in _MINMAX_EDITS:
        if source.count(old) == 1:
            source = source.replace(old, new)
            count += 1
    return source, count


_DEFINITION = re.compile(r"^[A-Za-z_][\w\s\*]*?\b\w+\((?P<params>[^;{]*)\)"
                         r"\s*\{\s*$", re.S)
_PARAM_NAME = re.compile(r"(\w+)\s*(?:\[\s*\w*\s*\])?\s*$")


def patch_unused_parameters(source: str) -> tuple[str, int]:
    """Mark every parameter of every generated function as used.

    CasADi's generated functions share one calling convention, so many
    leave ``mem``, ``iw`` or ``w`` unused, and ``gcc -Wall -Wextra``
    warns about each (flight builds use ``-Werror``). After the opening
    brace of each definition this adds ``(void)name;`` per parameter (no
    code is generated for it).

    Returns
    -------
    text : str
        The edited text.
    count : int
        Definitions edited.
    """
    lines = source.split("\n")
    out: list[str] = []
    count = 0
    i = 0
    while i < len(lines):
        line = lines[i]
        if line[:1].isalpha() or line[:1] == "_":
            j = i
            head = line
            # a signature may span lines; it ends at "{" (definition) or
            # ";" (declaration)
            while not head.rstrip().endswith(("{", ";", "}")) and \
                    j + 1 < len(lines) and j - i < 6:
                j += 1
                head += "\n" + lines[j]
            m = _DEFINITION.match(head)
            if m and not head.lstrip().startswith(("typedef", "struct ",
                                                   "#")):
                names = []
                for p in m.group("params").split(","):
                    p = p.strip()
                    if not p or p == "void" or p == "...":
                        continue
                    name = _PARAM_NAME.search(p)
                    if name:
                        names.append(name.group(1))
                out.extend(lines[i:j + 1])
                if names:
                    out.append("  " + " ".join(f"(void){n};" for n in names))
                    count += 1
                i = j + 1
                continue
        out.append(line)
        i += 1
    return "\n".join(out), count


#: CasADi's generated DAQP sets its initial working set from equal bounds
#: only; the edits add the bounds and rows whose warm-start multiplier
#: (``lam_x0``, ``lam_a0``) is non-zero (DAQP's sense: 1 active at the
#: upper bound, 3 at the lower; CasADi's sign: negative at the lower
#: bound). A working set with a dependent row makes DAQP's setup fail:
#: the third edit then restarts it cold, and writes NaN if that fails.
_DAQP_SENSE = (
    ("    d->daqp.sense[i] = d_qp->lbx[i]==d_qp->ubx[i] ? 5 : 0;\n",
     "    d->daqp.sense[i] = d_qp->lbx[i]==d_qp->ubx[i] ? 5 : "
     "!d_qp->lam_x0 ? 0 : d_qp->lam_x0[i] > 0 ? 1 : "
     "d_qp->lam_x0[i] < 0 ? 3 : 0;\n"),
    ("    d->daqp.sense[p_qp->nx+i] = d_qp->lba[i]==d_qp->uba[i] ? 5 : 0;\n",
     "    d->daqp.sense[p_qp->nx+i] = d_qp->lba[i]==d_qp->uba[i] ? 5 : "
     "!d_qp->lam_a0 ? 0 : d_qp->lam_a0[i] > 0 ? 1 : "
     "d_qp->lam_a0[i] < 0 ? 3 : 0;\n"),
    ("  flag = setup_daqp(&d->daqp,&d->work,&(d->res.setup_time));\n"
     "  if (flag<0) return 1;\n",
     "  flag = setup_daqp(&d->daqp,&d->work,&(d->res.setup_time));\n"
     "  if (flag<0) {  /* a dependent warm start: start cold */\n"
     "    free_daqp_workspace(&d->work);\n"
     "    free_daqp_ldp(&d->work);\n"
     "    for (i=0;i<p_qp->nx+p_qp->na;++i)\n"
     "      if (!(d->daqp.sense[i]&4)) d->daqp.sense[i] &= ~3;\n"
     "    flag = setup_daqp(&d->daqp,&d->work,&(d->res.setup_time));\n"
     "  }\n"
     "  if (flag<0) {  /* no point: NaN, never a stale one */\n"
     "    for (i=0;i<p_qp->nx;++i) d_qp->x[i] = NAN;\n"
     "    return 1;\n"
     "  }\n"),
)


def patch_daqp_warm_start(source: str) -> tuple[str, int]:
    """Start generated DAQP conics from the active set of the warm start.

    A bound or row whose warm-start multiplier (``lam_x0``, ``lam_a0``) is
    non-zero enters DAQP's initial working set (at the bound its sign
    names); a dependent set restarts cold. DAQP drops the
    ones the solution does not need, so the solution is the same and
    only the iterations change (the condensed MPC passes the previous
    step's shifted multipliers: fewer iterations through a saturated
    slew). Conics called with zero multipliers run as before.

    Returns
    -------
    text : str
        The edited text.
    count : int
        Edits made (3 per DAQP runtime; 0 when CasADi's text differs).
    """
    count = 0
    for old, new in _DAQP_SENSE:
        count += source.count(old)
        source = source.replace(old, new)
    return source, count


_ZEROS = re.compile(r"static const casadi_real casadi_zeros\[(\d+)\] = \n"
                    r"  \{0\.\};")
_SIGNATURE = re.compile(r"^/\* \w+:\((.*)\)->.*\*/\n"
                        r"static int casadi_f(\d+)\(", re.M)
_NULL_ARG = re.compile(r"^\s*arg\d*\[(\d+)\]=0;$", re.M)
_CALL = re.compile(r"casadi_f(\d+)\(arg\d*,")


def _input_nnz(signature: str) -> list[int]:
    """Nonzeros of each input of a generated signature comment, e.g.
    ``x[11],A[11x11,69nz],q[],t`` -> [11, 69, 0, 1]."""
    out = []
    for entry in re.findall(r"\w+(?:\[[^\]]*\])?", signature):
        dims = re.search(r"\[([^\]]*)\]", entry)
        if dims is None:
            out.append(1)
        elif not dims.group(1):
            out.append(0)
        elif dims.group(1).endswith("nz"):
            out.append(int(dims.group(1).split(",")[1][:-2]))
        else:
            out.append(int(np.prod([int(v) for v in
                                    dims.group(1).split("x")])))
    return out


def patch_zeros(source: str, public_nnz: int) -> tuple[str, int]:
    """Size ``casadi_zeros`` for the NULL arguments that can occur.

    A generated function reads a NULL argument from ``casadi_zeros``,
    which CasADi sizes for the largest input of any function in the file
    (the condensed MPC's stacked QP rows: 6,720 reals, 53 kB of flash).
    NULL reaches a function only from its caller: the user, for a public
    function's input (``public_nnz``, the largest), or a generated call
    that passes ``arg[k]=0`` (CasADi does for absent conic inputs, all
    empty). The array keeps the largest of those sizes; a call whose
    callee's signature cannot be read leaves the file unchanged.

    Returns
    -------
    text : str
        The edited text.
    size : int
        The new size (0: unchanged).
    """
    m = _ZEROS.search(source)
    if m is None:
        return source, 0
    nnz = {int(f): _input_nnz(sig) for sig, f in _SIGNATURE.findall(source)}
    need = int(public_nnz)
    for null in _NULL_ARG.finditer(source):
        call = _CALL.search(source, null.end())
        callee = nnz.get(int(call.group(1))) if call else None
        k = int(null.group(1))
        if callee is None or k >= len(callee):
            return source, 0
        need = max(need, callee[k])
    need = max(need, 1)
    if need >= int(m.group(1)):
        return source, 0
    return (source[:m.start()] + f"static const casadi_real casadi_zeros"
            f"[{need}] = \n  {{0.}};" + source[m.end():], need)


_CONTROL = re.compile(r"(if|for|while) \(")


def _braced(statement: str) -> str | None:
    """``if|for|while (…) body;`` with its one-statement body in braces
    (nested ones too), or None where it is not that plainly (a body with
    a ``;`` or a quote before its end, an ``else``, a brace)."""
    m = _CONTROL.match(statement)
    if not m:
        return None
    depth = 0
    for end in range(m.end() - 1, len(statement)):
        depth += {"(": 1, ")": -1}.get(statement[end], 0)
        if depth == 0:
            break
    else:
        return None
    head, body = statement[:end + 1], statement[end + 1:].strip()
    if (body == ";" or not body.endswith(";")          # a do-while's end
            or any(c in body for c in "{}\"'")
            or re.search(r"\belse\b", body)):
        return None
    if _CONTROL.match(body):
        inner = _braced(body)
        return None if inner is None else f"{head} {{{inner}}}"
    depth = 0
    for c in body[:-1]:
        depth += {"(": 1, ")": -1}.get(c, 0)
        if c == ";" and depth == 0:
            return None
    return f"{head} {{{body}}}"


def patch_braces(source: str) -> tuple[str, int]:
    """Put the one-statement bodies of ``if``/``for``/``while`` lines in
    braces (``if (res[0]!=0) res[0][3]=a2;`` → ``… {res[0][3]=a2;}``).

    The compiled code is the same. gcc's ``-Wmisleading-indentation``
    (in ``-Wall``) looks up the columns of every unbraced body in the
    source, at a cost that grows with the file: the default export's
    4.3 MB source took 57 s to compile with ``-O3 -Wall -Wextra``, 27 s
    braced (gcc 12, the CI machine). Lines that are not that plain are left as they are.
    Returns the text and the number of lines braced.
    """
    out, count = [], 0
    for line in source.split("\n"):
        stripped = line.lstrip()
        if stripped.endswith(";") and _CONTROL.match(stripped):
            new = _braced(stripped)
            if new is not None:
                line = line[:len(line) - len(stripped)] + new
                count += 1
        out.append(line)
    return "\n".join(out), count
