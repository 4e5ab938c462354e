"""The primal active set in C (benchmarks/pqp) against its numpy twin.

The C solver and `benchmarks.primal_active_set` take the same decisions
on the same QP (Hessian I), so they reach the same point in the same
iterations; capped, the C point keeps every bound and lowers the cost;
it is C99 without heap, clean under -Wall -Wextra -Werror on the host
and both Cortex-M cores, and the target build gives the host's answers.
"""

from __future__ import annotations


import numpy as np
import pytest

from benchmarks import primal_active_set
from benchmarks import primal_qp_c as pc
from benchmarks.emulated_solver import compile_object, undefined_symbols
from ocp.codegen.target import CORES, toolchain_missing


def _qp(rng: np.random.Generator, stages: int = 6, wheels: int = 2,
        dt: float = 0.5) -> dict:
    """A QP shaped as the step's: rows ``[L; dt·S·L]`` (L lower
    triangular, S the per-wheel prefix sums), y = 0 strictly feasible,
    and a gradient that drives it into its bounds."""
    n = stages * wheels
    L = np.tril(rng.normal(size=(n, n))) + 3 * np.eye(n)
    S = np.zeros((n, n))
    for k in range(stages):
        for i in range(wheels):
            S[k * wheels + i, i:(k + 1) * wheels:wheels] = dt
    C = np.vstack([L, S @ L])
    lo = -rng.uniform(0.5, 1.5, 2 * n)
    hi = rng.uniform(0.5, 1.5, 2 * n)
    return {"C": C, "lo": lo, "hi": hi, "f": 20 * rng.normal(size=n)}


def _twin(q: dict, warm: dict[int, int] | None = None) -> dict:
    n = q["C"].shape[1]
    return primal_active_set.solve(np.eye(n), q["f"], q["C"], q["lo"],
                                   q["hi"], np.zeros(n), warm or {})


def _sides(m: int, warm: dict[int, int]) -> np.ndarray:
    side = np.zeros(m, dtype=int)
    side[list(warm)] = list(warm.values())
    return side


@pytest.fixture(scope="module")
def lib(tmp_path_factory):
    return pc.host_library(tmp_path_factory.mktemp("pqp"))


@pytest.fixture(scope="module")
def qps():
    rng = np.random.default_rng(7)
    return [_qp(rng) for _ in range(20)]


def test_c_takes_the_twins_path(lib, qps):
    """Cold: the same optimum, multipliers and iterations as numpy's."""
    for q in qps:
        ref = _twin(q)
        m, n = q["C"].shape
        r = pc.solve_c(lib, q["C"], q["lo"], q["hi"], q["f"], np.zeros(n),
                       np.zeros(m))
        assert r["status"] == "optimal"
        assert r["iterations"] == ref["iterations"]
        assert np.max(np.abs(r["y"] - ref["x"])) <= 1e-9
        assert np.max(np.abs(r["lam"] - ref["lam"])) <= 1e-8
        assert ref["working"], "the QPs must have active bounds"


def test_warm_start_from_the_optimum_takes_one_iteration(lib, qps):
    """Started at the optimum's working set (and point), one KKT solve
    proves it optimal; the multipliers are the optimum's."""
    for q in qps:
        ref = _twin(q)
        m = q["C"].shape[0]
        r = pc.solve_c(lib, q["C"], q["lo"], q["hi"], q["f"], ref["x"],
                       _sides(m, ref["working"]))
        assert (r["status"], r["iterations"]) == ("optimal", 1)
        assert np.max(np.abs(r["lam"] - ref["lam"])) <= 1e-8


def _vertex(rng: np.random.Generator, C: np.ndarray) -> dict:
    """A QP whose optimum y* is the vertex of C's first n rows at their
    upper bounds, with multipliers λ > 0 (f = -y* - C_Wᵀλ); the other
    rows hold well inside their bounds."""
    m, n = C.shape
    y = rng.normal(size=n)
    lam = rng.uniform(0.5, 2.0, n)
    cy = C @ y
    hi = np.r_[cy[:n], cy[n:] + 5.0]
    lo = np.minimum(cy, 0.0) - 5.0
    return {"C": C, "lo": lo, "hi": hi, "f": -y - C[:n].T @ lam, "y": y,
            "lam": np.r_[lam, np.zeros(m - n)]}


@pytest.mark.parametrize("rows", ["staircase", "dense"])
def test_warm_factor_by_reflections(lib, rows):
    """The warm working set's factor comes from Householder reflections
    of its rows: started at a vertex with its n rows, one KKT solve
    proves it optimal and gives its multipliers. Staircase rows (each
    ending at most a stage after the one before, as the step's) take
    every reflection; dense rows fill the reflections' room after a few
    and the rest go through the Gram matrix."""
    rng = np.random.default_rng(11)
    n = 12
    for _ in range(10):
        if rows == "dense":
            C = rng.normal(size=(2 * n, n))
        else:
            T = np.tril(rng.normal(size=(n, n))) + 3 * np.eye(n)
            pairs = np.kron(np.eye(n // 2), [[1.5, 0.5], [0.5, 1.5]])
            C = np.vstack([pairs @ T, T])   # rows ending two by two
        q = _vertex(rng, C)
        r = pc.solve_c(lib, q["C"], q["lo"], q["hi"], q["f"], q["y"],
                       np.r_[np.ones(n), np.zeros(n)])
        assert (r["status"], r["iterations"]) == ("optimal", 1)
        assert np.max(np.abs(r["lam"] - q["lam"])) <= 1e-9
        assert np.max(np.abs(r["y"] - q["y"])) <= 1e-12


def test_given_row_lengths_are_the_scanned_ones(lib, qps):
    """pqp_solve_rows with each row's length (its last nonzero + 1),
    the rows in place or packed one after the other, takes the same path
    as pqp_solve, which finds the lengths by scanning C."""
    for q in qps[:5]:
        m, n = q["C"].shape
        lens = [max((j + 1 for j in range(n) if c[j] != 0), default=0)
                for c in q["C"]]
        a = pc.solve_c(lib, q["C"], q["lo"], q["hi"], q["f"], np.zeros(n),
                       np.zeros(m))
        b = pc.solve_c(lib, q["C"], q["lo"], q["hi"], q["f"], np.zeros(n),
                       np.zeros(m), row_len=np.array(lens))
        c = pc.solve_c(lib, q["C"], q["lo"], q["hi"], q["f"], np.zeros(n),
                       np.zeros(m), row_len=np.array(lens), packed=True)
        for r in (b, c):
            assert a["iterations"] == r["iterations"]
            assert np.array_equal(a["y"], r["y"])
            assert np.array_equal(a["lam"], r["lam"])


def test_warm_rows_off_their_bound_or_dependent_are_left_out(lib, qps):
    """Warm sides whose row is not at its bound at the start, or whose
    normal repeats one before it, are dropped: from the optimum with its
    working set and those two, one KKT solve still proves it optimal."""
    q = qps[0]
    ref = _twin(q)
    m, n = q["C"].shape
    j = next(iter(ref["working"]))
    C = np.vstack([q["C"], q["C"][j:j + 1]])      # row m repeats row j
    lo, hi = np.r_[q["lo"], q["lo"][j]], np.r_[q["hi"], q["hi"][j]]
    side = _sides(m + 1, ref["working"])
    side[m] = side[j]
    free = next(i for i in range(m) if i not in ref["working"]
                and q["lo"][i] < q["C"][i] @ ref["x"] < q["hi"][i])
    side[free] = 1
    r = pc.solve_c(lib, C, lo, hi, q["f"], ref["x"], side)
    assert (r["status"], r["iterations"]) == ("optimal", 1)
    assert r["side"][m] == 0 and r["side"][free] == 0
    assert np.max(np.abs(r["y"] - ref["x"])) <= 1e-12


def test_rows_dropped_when_the_gradient_turns(lib, qps):
    """From one QP's optimum and working set, a new gradient: rows leave
    the working set (the factor and its solution rotated) and the C
    solver still walks the twin's path to the new optimum."""
    rng = np.random.default_rng(3)
    dropped = 0
    for q in qps:
        ref = _twin(q)
        m = q["C"].shape[0]
        q2 = {**q, "f": 20 * rng.normal(size=q["f"].size)}
        n = q["C"].shape[1]
        twin = primal_active_set.solve(np.eye(n), q2["f"], q["C"], q["lo"],
                                       q["hi"], ref["x"], ref["working"])
        r = pc.solve_c(lib, q["C"], q["lo"], q["hi"], q2["f"], ref["x"],
                       _sides(m, ref["working"]))
        assert r["status"] == "optimal"
        assert r["iterations"] == twin["iterations"]
        assert np.max(np.abs(r["y"] - twin["x"])) <= 1e-9
        dropped += len(set(ref["working"]) - set(twin["working"]))
    assert dropped >= 20


def test_capped_solve_is_feasible_and_lowers_the_cost(lib, qps):
    """Each cap returns the twin's point after that many iterations:
    inside every bound, its cost no higher than the start's."""
    for q in qps[:8]:
        ref = _twin(q)
        m, n = q["C"].shape
        for cap in range(1, ref["iterations"]):
            r = pc.solve_c(lib, q["C"], q["lo"], q["hi"], q["f"],
                           np.zeros(n), np.zeros(m), max_iter=cap)
            assert (r["status"], r["iterations"]) == ("iteration limit", cap)
            assert np.max(np.abs(r["y"] - ref["path"][cap - 1])) <= 1e-9
            v = q["C"] @ r["y"]
            assert np.all(v <= q["hi"] + 1e-12)
            assert np.all(v >= q["lo"] - 1e-12)
            assert 0.5 * r["y"] @ r["y"] + q["f"] @ r["y"] <= 0.0
            # no multipliers: the working set's sides, ±1 (a warm start)
            assert np.array_equal(r["lam"], r["side"])


def _broken(rng: np.random.Generator, q: dict, rows: int) -> dict:
    """``q`` with ``rows`` rows' bounds moved past 0, so that y = 0 breaks
    them (as a defect or a rate beyond its bound does at the step's
    start)."""
    lo, hi = q["lo"].copy(), q["hi"].copy()
    for j in rng.choice(len(lo), rows, replace=False):
        if rng.random() < 0.5:
            lo[j] = rng.uniform(0.05, 0.4)
            hi[j] = lo[j] + rng.uniform(0.2, 1.0)
        else:
            hi[j] = -rng.uniform(0.05, 0.4)
            lo[j] = hi[j] - rng.uniform(0.2, 1.0)
    return {**q, "lo": lo, "hi": hi}


def _daqp(q: dict) -> np.ndarray | None:
    """DAQP's optimum of ``q`` (None where it finds the rows infeasible)."""
    import daqp

    m, n = q["C"].shape
    x, _, flag, _ = daqp.solve(np.eye(n), q["f"], q["C"], q["hi"], q["lo"],
                               np.zeros(m, dtype=np.int32))
    assert flag in (1, -1), flag
    return x if flag == 1 else None


def test_phase_one_from_a_start_that_breaks_bounds(lib):
    """Started where y = 0 breaks one to five rows' bounds: phase one
    moves it onto them and the primal phase reaches DAQP's optimum (or
    both find no point that keeps every bound), over 120 QPs, along the
    numpy twin's path (its phase one, then its primal phase from there:
    the same iterations)."""
    rng = np.random.default_rng(3)
    found = {"optimal": 0, "infeasible": 0}
    for _ in range(120):
        q = _broken(rng, _qp(rng), int(rng.integers(1, 6)))
        m, n = q["C"].shape
        ref = _daqp(q)
        one = primal_active_set.phase_one(q["C"], q["lo"], q["hi"],
                                          np.zeros(n), {})
        r = pc.solve_c(lib, q["C"], q["lo"], q["hi"], q["f"], np.zeros(n),
                       np.zeros(m))
        found[r["status"]] += 1
        if ref is None:
            assert r["status"] == "infeasible" and not np.any(r["lam"])
            assert (one["status"], one["iterations"]) == \
                ("infeasible", r["iterations"])
        else:
            assert r["status"] == "optimal"
            assert np.max(np.abs(r["y"] - ref)) <= 1e-9
            twin = primal_active_set.solve(np.eye(n), q["f"], q["C"],
                                           q["lo"], q["hi"], one["y"],
                                           one["working"])
            assert r["iterations"] == one["iterations"] + twin["iterations"]
    assert min(found.values()) >= 5         # both kinds were met


def test_phase_one_is_the_starts_projection(lib):
    """With f = -y0 the QP's optimum is y0's projection onto the
    feasible set (0 inside it), which phase one reaches from y0 ≠ 0, its
    first three rows warm at their bound there (held while their
    multipliers allow): the primal phase then proves it at once."""
    rng = np.random.default_rng(5)
    for _ in range(30):
        q = _qp(rng)
        m, n = q["C"].shape
        y0 = rng.normal(size=n)
        cy = q["C"] @ y0
        side = np.zeros(m, dtype=int)
        side[:3] = np.sign(cy[:3])
        lo, hi = q["lo"].copy(), q["hi"].copy()
        for j in range(3):                      # at the bound, 0 inside
            (hi if cy[j] > 0 else lo)[j] = cy[j]
        p = {**q, "lo": lo, "hi": hi, "f": -y0}
        ref = _daqp(p)
        assert np.any(q["C"] @ y0 > hi) or np.any(q["C"] @ y0 < lo)
        r = pc.solve_c(lib, p["C"], lo, hi, p["f"], y0, side)
        assert r["status"] == "optimal"
        assert np.max(np.abs(r["y"] - ref)) <= 1e-9


def test_no_work_is_read_before_it_is_written(lib, qps):
    """Work arrays full of NaN (and ints of garbage) before the call give
    the answers of zeroed ones, bit for bit: the solver reads only what
    it wrote, warm, cold and through phase one with warm rows (whose
    multipliers once came from whatever the work held: an exported
    closed loop, its work shared with other functions, then stalled)."""
    rng = np.random.default_rng(8)
    cases = []
    for q in qps[:6]:
        m, n = q["C"].shape
        ref = _twin(q)
        cases += [(q, np.zeros(n), np.zeros(m)),
                  (q, ref["x"], _sides(m, ref["working"]))]
        b = _broken(rng, q, 3)
        y0 = rng.normal(size=n)
        cy = q["C"] @ y0
        side = np.zeros(m, dtype=int)
        side[:3] = np.sign(cy[:3])
        lo, hi = b["lo"].copy(), b["hi"].copy()
        for j in range(3):
            (hi if cy[j] > 0 else lo)[j] = cy[j]
        cases.append(({**b, "lo": lo, "hi": hi}, y0, side))
    for q, y0, side in cases:
        runs = [pc.solve_c(lib, q["C"], q["lo"], q["hi"], q["f"], y0, side,
                           fill=fill) for fill in (0.0, np.nan)]
        assert runs[0]["status"] == runs[1]["status"]
        assert runs[0]["iterations"] == runs[1]["iterations"]
        assert np.array_equal(runs[0]["y"], runs[1]["y"])
        assert np.array_equal(runs[0]["lam"], runs[1]["lam"])


def test_phase_one_limit_and_crossed_bounds(lib, qps):
    """Phase one stopped at max_iter before a feasible point, and a row
    whose bounds cross, are statuses of their own, without multipliers."""
    rng = np.random.default_rng(9)
    q = _broken(rng, qps[0], 5)
    m, n = q["C"].shape
    r = pc.solve_c(lib, q["C"], q["lo"], q["hi"], q["f"], np.zeros(n),
                   np.zeros(m), phase_one=1)
    assert (r["status"], r["iterations"]) == ("no feasible point", 1)
    assert not np.any(r["lam"])
    lo = q["lo"].copy()
    lo[4] = q["hi"][4] + 0.1
    r = pc.solve_c(lib, q["C"], lo, q["hi"], q["f"], np.zeros(n),
                   np.zeros(m))
    assert (r["status"], r["iterations"]) == ("infeasible", 0)
    assert not np.any(r["lam"])


def test_nan_start_gradient_or_bound_is_invalid_input(lib, qps):
    """A NaN in a bound, the gradient or the start is PQP_INVALID_INPUT
    before any iteration: the start returned as it came, no multipliers
    (a NaN bound was once a row left out: the answer kept the others)."""
    q = qps[0]
    m, n = q["C"].shape
    y0 = _twin(q)["x"]
    for what, j in (("lo", 3), ("hi", m - 1), ("f", 0), ("y", n - 1)):
        data = {"lo": q["lo"].copy(), "hi": q["hi"].copy(),
                "f": q["f"].copy(), "y": y0.copy()}
        data[what][j] = np.nan
        r = pc.solve_c(lib, q["C"], data["lo"], data["hi"], data["f"],
                       data["y"], np.zeros(m))
        assert (r["status"], r["iterations"]) == ("invalid input", 0), what
        assert not np.any(r["lam"])
        np.testing.assert_array_equal(r["y"], data["y"])


def test_single_precision_equals_double(tmp_path, lib, qps):
    """The float build reaches the double optimum to float accuracy."""
    lib32 = pc.host_library(tmp_path, "single")
    for q in qps:
        m, n = q["C"].shape
        r64 = pc.solve_c(lib, q["C"], q["lo"], q["hi"], q["f"], np.zeros(n),
                         np.zeros(m))
        r32 = pc.solve_c(lib32, q["C"], q["lo"], q["hi"], q["f"],
                         np.zeros(n), np.zeros(m), tol=pc.TOL["single"],
                         precision="single")
        assert r32["status"] == "optimal"
        scale = np.max(np.abs(r64["y"]))
        assert np.max(np.abs(r32["y"] - r64["y"])) <= 1e-4 * scale
    rng = np.random.default_rng(4)           # and through phase one
    for q in qps[:10]:
        b = _broken(rng, q, 2)
        m, n = q["C"].shape
        r64, r32 = (pc.solve_c(lb, b["C"], b["lo"], b["hi"], b["f"],
                               np.zeros(n), np.zeros(m), tol=pc.TOL[pr],
                               precision=pr)
                    for lb, pr in ((lib, "double"), (lib32, "single")))
        assert r32["status"] == r64["status"]
        if r64["status"] == "optimal":
            scale = np.max(np.abs(r64["y"]))
            assert np.max(np.abs(r32["y"] - r64["y"])) <= 1e-4 * scale


def test_the_steps_qps_match_the_twin(lib):
    """QPs of a short closed loop of the condensed step (horizon 5), from
    the step's start: the C answer is the numpy twin's."""
    from benchmarks.horizon_qps import collect, run_daqp

    c = collect(5, 1, 40, 0)
    problems, infeasible = pc.y_problems(c, run_daqp(c)["signs"])
    assert infeasible == 0 and sum(p["constrained"] for p in problems) >= 5
    for p in problems:
        r = pc.solve_c(lib, p["C"], p["lo"], p["hi"], p["f"],
                       np.zeros(p["C"].shape[1]), p["side"])
        assert r["status"] == "optimal"
        assert np.max(np.abs(r["y"] - p["y_ref"])) <= 1e-9
    # the float build: torques and bounds to float's accuracy (measured
    # 3.3e-5 of m_max and 1.1e-5 of the rows' scale here)
    acc = pc.host_accuracy(problems, c)
    assert acc["du"] <= 1e-3 and acc["violation"] <= 1e-4
    assert pc.host_accuracy(problems, c, "double")["du"] <= 1e-9


@pytest.mark.skipif(toolchain_missing(run=False) is not None,
                    reason=str(toolchain_missing(run=False)))
@pytest.mark.parametrize("target", sorted(CORES))
@pytest.mark.parametrize("precision", ["double", "single"])
def test_target_build_is_clean_and_heap_free(tmp_path, target, precision):
    """C99 under -Wall -Wextra -Werror for the core; the object calls no
    allocator."""
    obj = tmp_path / "pqp.o"
    proc = compile_object(pc.PQP_DIR / "pqp.c", target, precision,
                          pc.PQP_SINGLE, obj)
    assert proc.returncode == 0 and not proc.stderr, proc.stderr
    undefined = undefined_symbols(obj)
    assert not {"malloc", "calloc", "realloc", "free"} & undefined
    if precision == "single":
        assert "sqrt" not in undefined
    # flight-sized: a few kB of code, a bounded stack of a few hundred
    # bytes, no library call but the C library's copies and square root
    mem = pc.solver_memory(target, precision)
    assert mem["bounded"] and 0 < mem["stack"] <= 1024
    library = set(mem["library"])
    if (target, precision) == ("cortex-m4f", "double"):
        # double in software on the M4F's single-precision FPU: each
        # operation a call (8,228 bytes with phase one)
        library = {f for f in library if not f.startswith("__aeabi_")}
        assert 0 < mem["flash"] <= 10240
    else:
        assert 0 < mem["flash"] <= 8192     # 6.6 kB with phase one
    assert library <= {"memmove", "memcpy", "memset", "sqrt", "sqrtf"}


@pytest.mark.skipif(toolchain_missing() is not None,
                    reason=str(toolchain_missing()))
def test_emulated_m7_gives_the_host_answers(qps):
    """On the emulated Cortex-M7 (double) the solver reaches the twin's
    optimum, and its instruction counts grow with the cap."""
    problems = []
    for q in qps[:4]:
        ref = _twin(q)
        problems.append({**q, "side": np.zeros(q["C"].shape[0], int),
                         "y_ref": ref["x"], "iterations": ref["iterations"],
                         "constrained": True})
    rows = pc.run_target(problems, [2, 0], "cortex-m7", "double")
    assert len(rows) == 3 * len(problems)
    for i, p in enumerate(problems):
        got = {r["cap"]: r for r in rows if r["qp"] == i}
        assert got[pc.NO_CAP]["status"] == "optimal"
        assert got[pc.NO_CAP]["iterations"] == p["iterations"]
        assert got[pc.NO_CAP]["err"] <= 1e-9
        assert got[2]["status"] == "iteration limit"
        assert (0 < got[-1]["instructions"] < got[2]["instructions"]
                < got[pc.NO_CAP]["instructions"])


def test_nearly_dependent_rows_do_not_join(lib):
    """The pivot comes from the Gram matrix, so a row within 1e-8 of the
    working set's span (rounding, not a direction) is left out: joining
    it made the factor garbage and a QP of the 200-loop Monte Carlo end
    0.025 outside a bound."""
    rng = np.random.default_rng(11)
    n = 6
    r0, r1 = rng.normal(size=n), rng.normal(size=n)
    C = np.vstack([r0, r1, r0 + r1 + 1e-8 * rng.normal(size=n),
                   np.eye(n)])
    lo, hi = np.r_[-1.0, -1.0, -1.0, -np.ones(n)], np.r_[0.0, 0.0, 0.0,
                                                         np.ones(n)]
    side = np.zeros(C.shape[0], dtype=int)
    side[:3] = 1
    r = pc.solve_c(lib, C, lo, hi, np.zeros(n), np.zeros(n), side,
                   max_iter=0)
    assert list(r["side"][:3]) == [1, 1, 0]
    # and from there the solve stays feasible and reaches numpy's optimum
    f = 5 * rng.normal(size=n)
    r = pc.solve_c(lib, C, lo, hi, f, np.zeros(n), side)
    ref = primal_active_set.solve(np.eye(n), f, C, lo, hi, np.zeros(n),
                                  {0: 1, 1: 1})
    v = C @ r["y"]
    assert r["status"] == "optimal"
    assert np.all(v <= hi + 1e-9) and np.all(v >= lo - 1e-9)
    assert np.max(np.abs(r["y"] - ref["x"])) <= 1e-7


def test_packed_rows_need_their_lengths(lib):
    """Rows packed one after the other cannot be scanned for their
    lengths: pqp_solve_rows refuses them without ``row_len``."""
    import ctypes

    n, m = 2, 2
    C = np.ones(3)
    start = np.array([0, 1], dtype=np.int32)
    lo, hi, f = -np.ones(m), np.ones(m), np.zeros(n)
    y, lam = np.zeros(n), np.zeros(m)
    side = np.zeros(m, dtype=np.int8)
    w = np.zeros(lib.pqp_work_size(n, m))
    iw = np.zeros(lib.pqp_iwork_size(n, m), dtype=np.int32)
    its = ctypes.c_int(-1)

    def ptr(a):
        return a.ctypes.data_as(ctypes.c_void_p)

    status = lib.pqp_solve_rows(n, m, ptr(C), ptr(start), None, ptr(lo),
                                ptr(hi), ptr(f), ptr(y), ptr(side), ptr(lam),
                                10, 10, ctypes.c_double(1e-10), ptr(w),
                                ptr(iw), ctypes.byref(its))
    assert pc.STATUS[status] == "invalid input" and its.value == 0
