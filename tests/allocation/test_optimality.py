"""Success means optimal: the scale α, the least-squares point and every
backend's torques, each against an independent reference (HiGHS's LP,
scipy's bounded least squares, quadprog's QP)."""

import numpy as np
import pytest
from scipy.optimize import linprog, lsq_linear

from adcs_common.qp import QP, certify, make_backend
from allocation import QPAllocator, WheelArray
from allocation.qp import available_solvers
from allocation.qp.problem import torque_bounds

W4 = WheelArray.pyramid(h_max=4.0, m_max=0.2)


def lp_alpha(arr, lo, hi, M):
    """Largest α in [0, 1] with α M attainable (HiGHS), or None."""
    A = arr.axes * arr.active
    n = A.shape[1]
    res = linprog(np.r_[np.zeros(n), -1.0],
                  A_eq=np.hstack([A, -np.asarray(M, float)[:, None]]),
                  b_eq=np.zeros(3), bounds=list(zip(lo, hi)) + [(0, 1)],
                  method="highs")
    return float(res.x[-1]) if res.status == 0 else None


# -- finding 1: a flat attainable set kept the least-squares fallback ------
def test_scale_when_the_free_wheels_span_a_plane():
    """Wheel 1 past its momentum bound is pinned; wheels 2-3 span a plane
    that still holds α M for α = 0.5 (was least squares, α 0.619, 19°)."""
    arr = WheelArray.from_axes(np.eye(3), h_max=1, m_max=1)
    res = QPAllocator(arr).allocate([-2, 1, 0.5], wheel_momentum=[3, 0, 0],
                                    dt=1.0)
    assert res.mode == "scale" and res.status == "saturated"
    assert res.alpha == pytest.approx(0.5, abs=1e-9)
    np.testing.assert_allclose(res.achieved, [-1, 0.5, 0.25], atol=1e-9)


def test_scale_on_the_pyramid_with_two_wheels_pinned():
    arr, M = W4, np.array([0, 0, -0.45886])
    h = np.array([-4.65385, 1.94867, -3.94566, 4.97636])
    res = QPAllocator(arr).allocate(M, h, 0.5)
    lo, hi, _ = torque_bounds(arr, h, 0.5)
    assert res.mode == "scale"
    assert res.alpha == pytest.approx(lp_alpha(arr, lo, hi, M), abs=1e-8)
    assert res.alpha == pytest.approx(0.7717, abs=1e-4)


# -- finding 2: a huge demand got a torque opposite to it ------------------
def test_a_huge_demand_never_gets_an_opposite_torque_called_scale():
    arr = W4.with_failed(2)
    M = np.array([4.454e10, 3.011e11, -3.474e11])
    h = np.array([4.06873, 2.13943, 0, 0.26657])
    res = QPAllocator(arr).allocate(M, h, 0.5)
    lo, hi, _ = torque_bounds(arr, h, 0.5)
    ref = lp_alpha(arr, lo, hi, M)
    if res.mode == "scale":
        assert ref is not None and res.alpha == pytest.approx(ref, abs=1e-9)
        assert res.achieved @ M >= 0.0
    else:       # no α >= 0 is attainable: the closest torque, said so
        assert ref is None or ref < 1e-12
        assert res.mode == "least_squares"


@pytest.mark.parametrize("scale", [1e-6, 1.0, 1e6, 1e11])
def test_alpha_times_demand_does_not_depend_on_the_demand_size(scale):
    """The scale test runs along M/|M|: α |M| is the same at every |M|."""
    u = np.array([0.3, -0.8, 0.52]) / np.linalg.norm([0.3, -0.8, 0.52])
    ref = QPAllocator(W4).allocate(u * 10.0)
    res = QPAllocator(W4).allocate(u * 10.0 * scale)
    if scale >= 1.0:
        assert res.alpha * scale == pytest.approx(ref.alpha, rel=1e-9)
        np.testing.assert_allclose(res.achieved, ref.achieved, atol=1e-12)


# -- finding 3: qrqp's least-squares point was not the closest -------------
@pytest.mark.parametrize("solver", ["casadi:qrqp", "daqp", "osqp"])
def test_least_squares_is_the_closest_attainable_torque(solver):
    """300 random arrays of 3-8 wheels (one failed beyond 4), unequal
    weights, momenta up to 1.1 h_max: the distance |A m - M| equals
    scipy's bounded least squares (qrqp was up to 0.099 N·m farther)."""
    rng = np.random.default_rng(5)
    worst = 0.0
    for _ in range(300):
        n = int(rng.integers(3, 9))
        arr = WheelArray.from_axes(rng.normal(size=(3, n)), h_max=1.0,
                                   m_max=0.1, normalize=True)
        if n > 4:
            arr = arr.with_failed(int(rng.integers(n)))
        w = rng.uniform(0.5, 2.0, n)
        try:
            q = QPAllocator(arr, w, solver=solver,
                            saturation="least_squares")
        except Exception:           # a random array without full rank
            continue
        A = arr.axes * arr.active
        h = arr.h_max * rng.uniform(-1.1, 1.1, n)
        M = rng.normal(size=3) * 0.3
        res = q.allocate(M, h, 0.5)
        lo, hi, _ = torque_bounds(arr, h, 0.5)
        lo, hi = lo * arr.active, hi * arr.active
        free = lo < hi
        b = M - A[:, ~free] @ lo[~free]
        ref = lsq_linear(A[:, free], b, bounds=(lo[free], hi[free]),
                         tol=1e-14)
        worst = max(worst, abs(np.linalg.norm(M - res.achieved)
                               - np.sqrt(2 * ref.cost)))
    assert worst <= 1e-7


# -- finding 4: iterative backends' feasible, non-optimal torques ----------
def reference_torques(arr, w, target, lo, hi):
    """quadprog's optimum of min Σ w m² s.t. A m = target, lo <= m <= hi."""
    import quadprog

    A = arr.axes * arr.active
    n = arr.n_wheels
    fixed = lo >= hi
    free = ~fixed
    m = np.where(fixed, lo, 0.0)
    b = target - A[:, fixed] @ m[fixed]
    Af = A[:, free]
    # the equality rows the free wheels span (drop dependent ones)
    U, s, _ = np.linalg.svd(Af)
    r = int((s > 1e-10 * s.max()).sum())
    E = U[:, :r].T @ Af
    k = int(free.sum())
    C = np.vstack([E, np.eye(k), -np.eye(k)]).T
    bq = np.r_[U[:, :r].T @ b, lo[free], -hi[free]]
    m[free] = quadprog.solve_qp(2 * np.diag(w[free]), np.zeros(k), C, bq,
                                meq=r)[0]
    return m


ITERATIVE = [s for s in ("proxqp", "piqp", "clarabel", "osqp", "quadprog",
                         "casadi:osqp", "casadi:daqp", "casadi:qrqp")
             if s in available_solvers()]


@pytest.mark.parametrize("solver", ITERATIVE)
def test_every_backend_that_says_success_is_the_optimum(solver):
    """600 random saturated and momentum-bounded cases on six wheels with
    unequal weights and a failed wheel: within 1e-6 m_max of quadprog."""
    pytest.importorskip("quadprog")
    rng = np.random.default_rng(11)
    arr = WheelArray.from_axes(rng.normal(size=(3, 6)), h_max=1.0,
                               m_max=0.1, normalize=True).with_failed(2)
    w = np.array([1.0, 2.0, 1.0, 0.5, 3.0, 1.5])
    q = QPAllocator(arr, w, solver=solver)
    worst = 0.0
    for _ in range(600):
        m0 = arr.m_max * arr.active * rng.uniform(-1, 1, 6)
        M = arr.axes @ m0 * rng.choice([0.5, 1.0, 1.5])
        h = arr.h_max * rng.uniform(-0.95, 0.95, 6)
        res = q.allocate(M, h, 0.5)
        lo, hi, _ = torque_bounds(arr, h, 0.5)
        lo, hi = lo * arr.active, hi * arr.active
        if res.mode == "least_squares":
            continue
        ref = reference_torques(arr, w, res.achieved, lo, hi)
        worst = max(worst, np.abs(res.torques - ref).max() / 0.1)
    assert worst <= 1e-6


# -- the certificate itself -----------------------------------------------
def box_qp():
    """min ½|x - (2, -3)|² s.t. x1 + x2 = 0, |x| <= 1: optimum (1, -1)."""
    return QP(np.eye(2), np.array([-2.0, 3.0]), np.array([[1.0, 1.0]]),
              np.zeros(1), np.zeros(1), -np.ones(2), np.ones(2), 1)


def test_certificate_polishes_a_nearly_optimal_point_to_the_optimum():
    x, cert = certify(box_qp(), np.array([0.9999, -0.9999]))
    assert cert.certified and cert.polished
    np.testing.assert_array_equal(x, [1.0, -1.0])


def test_certificate_refuses_a_feasible_point_that_is_not_optimal():
    """(0, 0) is feasible; no active set near it is the optimum's after
    the allowed steps from its own guess... the polish finds (1, -1)."""
    qp = box_qp()
    x, cert = certify(qp, np.zeros(2))
    # polishing from the interior reaches the true optimum: never (0, 0)
    assert not np.allclose(x, 0.0)
    if cert.certified:
        np.testing.assert_allclose(x, [1.0, -1.0], atol=1e-12)


def test_certificate_refuses_a_wrong_point_it_cannot_repair():
    """A point breaking the equality row by far, on an infeasible QP."""
    qp = QP(np.eye(1), np.zeros(1), np.ones((1, 1)), np.array([5.0]),
            np.array([5.0]), -np.ones(1), np.ones(1), 1)
    x, cert = certify(qp, np.array([1.0]))
    assert not cert.certified


def test_a_backend_answer_that_fails_the_certificate_is_inaccurate():
    """The wrapper turns an uncertified point into status 'inaccurate'."""
    class Liar:
        name = "liar"

        def solve(self, qp):
            from adcs_common.qp import QPSolution
            return QPSolution(np.array([0.5, -0.5]), True, "solved")

    from adcs_common.qp.backends import CertifiedBackend

    qp = QP(np.eye(2), np.array([-2.0, 3.0]), np.array([[1.0, 1.0]]),
            np.zeros(1), np.zeros(1), -np.ones(2), np.ones(2), 1)
    # the liar's point is feasible; the certificate polishes it to (1, -1)
    sol = CertifiedBackend(Liar()).solve(qp)
    assert sol.success and np.allclose(sol.x, [1.0, -1.0])
    infeasible = QP(np.eye(1), np.zeros(1), np.ones((1, 1)),
                    np.array([5.0]), np.array([5.0]), -np.ones(1),
                    np.ones(1), 1)

    class Liar1(Liar):
        def solve(self, qp):
            from adcs_common.qp import QPSolution
            return QPSolution(np.array([1.0]), True, "solved")

    sol = CertifiedBackend(Liar1()).solve(infeasible)
    assert not sol.success and sol.status == "inaccurate"
    assert sol.extras["certificate"]["certified"] is False


def test_make_backend_certifies_by_default():
    b = make_backend("daqp", 2, 1, 1)
    sol = b.solve(box_qp())
    assert sol.success and sol.extras["certificate"]["certified"]
