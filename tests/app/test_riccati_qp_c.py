"""The Riccati active set in C (``ocp/mpc/rqp/rqp.c``) against its numpy
twin (`benchmarks.riccati_active_set`): the same answers and iterations
on the condensed step's QPs kept stage by stage, capped points that keep
every box, float close to double, C99 without heap on the host and both
Cortex-M cores, and the emulated M7 giving the host's answers."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from benchmarks import riccati_qp_c as rc
from benchmarks.horizon_qps import collect
from benchmarks.riccati_active_set import solve
from benchmarks.emulated_solver import compile_object, undefined_symbols
from ocp.codegen.target import CORES, toolchain_missing


@pytest.fixture(scope="module", params=[None, (11, 4)],
                ids=["any-size", "fixed-size"])
def lib(request, tmp_path_factory):
    """rqp.c for any size, and compiled for the demo craft's n_x = 11,
    n_u = 4 (its loops unrolled), as the benchmark builds it."""
    return rc.host_library(tmp_path_factory.mktemp("rqp"),
                           sizes=request.param)


@pytest.fixture(scope="module")
def probs():
    c = collect(horizon=5, draws=1, steps=12, seed=0, stagewise=True)
    return rc.problems(c, 3)


def test_c_takes_the_twins_path(lib, probs):
    constrained = 0
    for p in probs:
        for cap in (1, 3, rc.NO_CAP):
            got = rc.solve_c(lib, p["qp"], p["warm"], cap)
            ref = solve(p["qp"], p["warm"], max_iter=cap)
            assert got["iterations"] == ref["iterations"]
            assert got["stages"] == ref["factored"]
            np.testing.assert_allclose(got["U"], ref["U"], atol=1e-12)
            assert got["status"] == ("optimal" if ref["optimal"] else
                                     "iteration limit")
            if ref["optimal"]:
                lam = np.zeros_like(got["lam"])
                for (k, b), v in ref["lam"].items():
                    lam[k, b] = v
                np.testing.assert_allclose(got["lam"], lam, atol=1e-9)
                constrained += bool(ref["working"])
    assert constrained >= 5


def test_generated_stage_products_take_the_same_path(tmp_path, probs):
    """rqp.c with the stage products as CasADi straight-line code for
    the QPs' patterns (-DRQP_PRODUCTS) makes the twin's decisions."""
    masks = rc.common_masks([p["qp"] for p in probs])
    gen = rc.host_library(tmp_path, sizes=(11, 4), products=masks)
    for p in probs:
        for cap in (2, rc.NO_CAP):
            got = rc.solve_c(gen, p["qp"], p["warm"], cap, masks=masks)
            ref = solve(p["qp"], p["warm"], max_iter=cap)
            assert got["iterations"] == ref["iterations"]
            np.testing.assert_allclose(got["U"], ref["U"], atol=1e-12)


def test_capped_points_keep_every_box(lib, probs):
    for p in probs:
        qp = p["qp"]
        got = rc.solve_c(lib, qp, p["warm"], 1)
        v = qp.values(got["U"], qp.rollout(got["U"]))
        assert np.all(v <= qp.hi + 1e-9) and np.all(v >= qp.lo - 1e-9)
        np.testing.assert_allclose(got["X"], qp.rollout(got["U"]),
                                   atol=1e-12)


def _cost(qp, U) -> float:
    """The stage-wise QP's cost at the inputs U (states rolled out)."""
    X = qp.rollout(U)
    return float(sum(0.5 * x @ Q @ x + q @ x + 0.5 * u @ (qp.R * u) + g @ u
                     for x, Q, q, u, g in zip(X, qp.Q, qp.q, U, qp.g)))


def test_a_full_pool_of_rows_stops_at_a_feasible_descent(tmp_path):
    """The rows passed back share a pool (``RQP_POOL_ROWS``). Built with
    no room in it, on the chain x_{k+1} = x_k + u_k started at u = (0, 1,
    0), x = (0, 1, 1), where u_1 and x_2 at their upper bounds pass a
    row back to x_1: the solve stops where that row would go, status
    "rows full", at a point that keeps every box and costs no more than
    the start, without multipliers; the default build reaches the twin's
    optimum."""
    from tests.app.test_riccati_active_set import _chain

    qp = replace(_chain(3), u0=np.array([[0.0], [1.0], [0.0]]),
                 x0=np.array([[0.0], [1.0], [1.0]]))
    warm = {(1, 0): 1}          # x_2's box joins as the step's block
    small = rc.host_library(tmp_path, defines=("-DRQP_POOL_ROWS(N,nx)=0",))
    got = rc.solve_c(small, qp, warm, rc.NO_CAP)
    assert got["status"] == "rows full"
    v = qp.values(got["U"], qp.rollout(got["U"]))
    assert np.all(v <= qp.hi + 1e-12) and np.all(v >= qp.lo - 1e-12)
    assert _cost(qp, got["U"]) <= _cost(qp, qp.u0) + 1e-12
    assert not got["lam"].any()
    ref = solve(qp, warm, max_iter=rc.NO_CAP)
    full = rc.solve_c(rc.host_library(tmp_path), qp, warm, rc.NO_CAP)
    assert full["status"] == "optimal" and ref["optimal"]
    np.testing.assert_allclose(full["U"], ref["U"], atol=1e-12)
    assert _cost(qp, ref["U"]) < _cost(qp, got["U"])


def _chain_started_where_both_boxes_hold():
    from tests.app.test_riccati_active_set import _chain
    return replace(_chain(), u0=np.array([[1.0], [0.0]]),
                   x0=np.ones((2, 1)))


def test_a_dependent_warm_box_is_held_out(tmp_path):
    lib = rc.host_library(tmp_path)
    at = _chain_started_where_both_boxes_hold()
    got = rc.solve_c(lib, at, {(0, 0): 1, (0, 1): 1})
    assert got["status"] == "optimal"
    np.testing.assert_array_equal(got["side"], [[1, 0], [0, 1]])
    np.testing.assert_allclose(got["U"].ravel(), [1.0, 0.0], atol=1e-12)


def test_a_start_beyond_a_box_or_nan_is_refused(lib, probs):
    """No phase one yet: a start that breaks a box is refused, and a NaN
    start or bound is invalid input."""
    qp = probs[0]["qp"]
    hi = qp.hi.copy()
    v = qp.values(qp.u0, qp.x0)
    hi[0, 0] = v[0, 0] - 1e-3                # the start beyond it
    got = rc.solve_c(lib, replace(qp, hi=hi))
    assert got["status"] == "infeasible start" and got["iterations"] == 0
    u0 = qp.u0.copy()
    u0[1, 0] = np.nan
    assert rc.solve_c(lib, replace(qp, u0=u0))["status"] == "invalid input"
    lo = qp.lo.copy()
    lo[2, 3] = np.nan
    assert rc.solve_c(lib, replace(qp, lo=lo))["status"] == "invalid input"


def test_a_build_for_one_size_refuses_another(tmp_path):
    lib = rc.host_library(tmp_path, sizes=(11, 4))
    got = rc.solve_c(lib, _chain_started_where_both_boxes_hold())
    assert got["status"] == "invalid input" and got["iterations"] == 0


def test_a_box_on_no_component_is_refused(lib, probs):
    qp = probs[0]["qp"]
    N, nx, nu, nb = qp.dims
    box = rc.boxes(qp)[0]
    for wrong in (-1, nx + nu):
        bad = box.copy()
        bad[0] = wrong
        got = rc.solve_c(lib, qp, box=bad)
        assert got["status"] == "invalid input" and got["iterations"] == 0


def test_single_precision_is_close_to_double(tmp_path, probs):
    single = rc.host_library(tmp_path, "single")
    for p in probs:
        got = rc.solve_c(single, p["qp"], p["warm"], rc.NO_CAP, "single")
        assert got["status"] == "optimal"
        np.testing.assert_allclose(got["U"], p["U_ref"], atol=1e-4)


@pytest.mark.skipif(toolchain_missing(run=False) is not None,
                    reason=str(toolchain_missing(run=False)))
@pytest.mark.parametrize("target", sorted(CORES))
@pytest.mark.parametrize("precision", ["double", "single"])
def test_target_build_is_clean_and_heap_free(tmp_path, target, precision):
    obj = tmp_path / "rqp.o"
    proc = compile_object(rc.RQP_DIR / "rqp.c", target, precision,
                          rc.RQP_SINGLE, obj)
    assert proc.returncode == 0 and not proc.stderr, proc.stderr
    undefined = undefined_symbols(obj)
    assert not {"malloc", "calloc", "realloc", "free"} & undefined
    mem = rc.solver_memory(target, precision)
    assert mem["bounded"] and 0 < mem["stack"] <= 2048
    library = {f for f in mem["library"] if not f.startswith("__aeabi_")}
    assert library <= {"memset", "memcpy", "memmove", "sqrt", "sqrtf"}


@pytest.mark.skipif(toolchain_missing() is not None,
                    reason=str(toolchain_missing()))
@pytest.mark.parametrize("generated", [False, True],
                         ids=["loops", "generated-products"])
def test_emulated_m7_gives_the_host_answers(probs, generated):
    rows = rc.run_target(probs[:4], [1, 0], "cortex-m7", "double",
                         generated=generated)
    assert len(rows) == 3 * 4
    for i in range(4):
        got = {r["cap"]: r for r in rows if r["qp"] == i}
        assert got[rc.NO_CAP]["status"] == "optimal"
        assert got[rc.NO_CAP]["err"] <= 1e-12
        assert got[-1]["stages"] == 5           # the warm set: one recursion
        assert 0 < got[-1]["instructions"] <= got[1]["instructions"] <= \
            got[rc.NO_CAP]["instructions"]
