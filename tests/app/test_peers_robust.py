"""do-mpc's multi-stage MPC and RobustMPC: the same first command.

do-mpc (optional, ``pip install do-mpc``) writes the scenario tree over
the principal-inertia scale factors as one NLP for IPOPT, with its own
RK4 (`benchmarks.peers_robust`); RobustMPC solved to convergence gives
the same first command from the same state, and the same tree.
"""

import warnings

import numpy as np
import pytest

pytest.importorskip("do_mpc", reason="do-mpc is a peer, not a dependency")

from benchmarks.peers import _mpc_problem  # noqa: E402
from benchmarks.peers_robust import (_plan_difference,  # noqa: E402
                                     do_mpc_robust_model, our_scenarios,
                                     scale_sets)
from ocp.mpc import RobustMPC  # noqa: E402


def test_do_mpc_multi_stage_gives_robust_mpc_s_first_command():
    model, qf = _mpc_problem()
    # a state mid-slew: rate and wheel momenta not zero
    x = model.state([0.97, 0.17, 0.17, 0.0], [0.02, 0.03, -0.01],
                    [0.05, -0.1, 0.08, 0.02])
    scales = scale_sets()[9]
    lam = np.sort(np.linalg.eigvalsh(model.inertia))
    for s, f in zip(our_scenarios(model, 9), scales):
        np.testing.assert_allclose(np.sort(np.linalg.eigvalsh(s.inertia)),
                                   np.sort(lam * f), rtol=1e-14)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        ctl = do_mpc_robust_model(model, qf, scales)
    ctl.x0 = x
    ctl.set_initial_guess()
    u_do = np.asarray(ctl.make_step(x)).ravel()
    mpc = RobustMPC(model, our_scenarios(model, 9), rti=False)
    step = mpc.step(x, qf)
    np.testing.assert_allclose(step.u, u_do, rtol=0, atol=1e-5)
    assert np.abs(step.u).max() > 1e-3
    # the whole tree: every scenario's states and commands (do-mpc's
    # branch b is our scenario b)
    d = _plan_difference(ctl, mpc.scenario_plans(step.plan), model.nx,
                         model.nu, 20)
    assert d < 1e-4
    # a mismatched order would be far off
    plans = mpc.scenario_plans(step.plan)
    assert _plan_difference(ctl, plans[::-1], model.nx, model.nu, 20) > 1e-2
