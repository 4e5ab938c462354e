"""The polish cascade of the stage-wise interior point, and its branches.

`ocp.mpc.stagewise_polish` solves the QP on a guess of the active set;
this module chains up to four such polishes from one interior-point
iterate, each a step of an active-set method on the guess before it
(`cascade`; the last two only when needed, `polish_more`), and wraps
what is needed only when the others fail as branches that the
generated C skips (`cascade_function`): a CasADi
``Function.if_else`` whose other branch passes its arguments through
(`passing`).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import casadi as ca
import numpy as np

from .stagewise_polish import (POLISH_ACCEPT, POLISH_TIGHT, broken,
                               clear_active, next_active, polish,
                               reduced_active)

#: ``residual(point, data) -> kkt``: the KKT residual of a point
#: (`stagewise_ipm`'s, +inf for a point with a NaN).
Residual = Callable[[list, list], Any]


def passing(name: str, like: list, pick: Callable[[list], list]
            ) -> ca.Function:
    """A branch that passes some of its arguments through: ``pick`` of
    fresh MX symbols shaped as ``like``.

    MX, so that the generated C copies whole arrays in loops: an SX
    Function writes each element on a line of its own (34,000 lines for
    a skipped chunk's state on a tree of 9 scenarios, and four times the
    compile time). Its work is the largest array it passes, not a slot
    per argument.
    """
    args = [ca.MX.sym(a.name(), a.sparsity()) for a in like]
    return ca.Function(name, args, pick(args))


def _symbols(lay: Any, tree: Any, dims: tuple, data: list) -> tuple:
    """Fresh MX symbols of a point (6 arrays) and of the QP data."""
    nx, nu = dims
    nb, C = lay.nb, tree.C
    sym = ca.MX.sym
    point = [sym("dU", nu, C), sym("dX", nx, C)] + [
        sym(n, nb, C) for n in ("Sl", "Su", "Ll", "Lu")]
    return point, [sym(f"d{i}", v.sparsity()) for i, v in enumerate(data)]


def cascade(kern: dict, lay: Any, tree: Any, dims: tuple,
            flags: np.ndarray, sweeps: dict, residual: Residual,
            more: Callable[..., list], point: list, data: list,
            kkt_ref: Any
            ) -> tuple[list, Any]:
    """``(polished point, its residual)``: the best of up to four polishes
    from the interior-point iterate ``point``.

    The first on the boxes with λ > s. The second: when the first met
    its equalities, without the rows whose multiplier came out with the
    wrong sign (dependent boxes), from the first's point; when it could
    not (an inconsistent guess: nearly parallel boxes not yet decided),
    on the clearly active boxes, from ``point``. The third, only when
    neither met `POLISH_ACCEPT` and ``kkt_ref`` (the iterate's own
    residual) misses it too: the second's guess less its wrong-signed
    rows, with the boxes its point breaks (`next_active`), and a fourth
    the same way when the third's misses `POLISH_ACCEPT` too: ``more``
    (`polish_more`, built once per solve so that the generated C holds
    its code once).
    """
    pol = list(polish(kern, lay, tree, dims, flags, point, data, sweeps))
    kkt_p = residual(pol, data)
    met = broken(pol) <= POLISH_TIGHT
    again = [ca.if_else(met, a, b) for a, b in zip(pol, point)]
    act = [ca.if_else(met, a, b) for a, b in
           zip(reduced_active(pol), clear_active(point))]
    pol2 = list(polish(kern, lay, tree, dims, flags, again, data, sweeps,
                       tuple(act)))
    kkt_2 = residual(pol2, data)
    second = kkt_2 < kkt_p
    pol = [ca.if_else(second, a, b) for a, b in zip(pol2, pol)]
    kkt_p = ca.fmin(kkt_p, kkt_2)
    *pol3, kkt_3 = more(ca.fmin(kkt_ref, kkt_p) > POLISH_ACCEPT, *pol2,
                        *act, *data)
    third = kkt_3 < kkt_p
    pol = [ca.if_else(third, a, b) for a, b in zip(pol3, pol)]
    kkt_p = ca.if_else(third, kkt_3, kkt_p)     # a NaN kkt_3 is not taken
    return pol, kkt_p


def _active_step(kern: dict, lay: Any, tree: Any, dims: tuple,
                 flags: np.ndarray, sweeps: dict, residual: Residual,
                 data: list) -> ca.Function:
    """``step(c, point…, act_l, act_u, data…) -> (point…, act_l, act_u,
    kkt)``: one step of the active-set method when ``c``.

    The polish on the masks less the rows whose multiplier came out with
    the wrong sign at ``point`` and with every box it breaks
    (`next_active`), those masks and its residual; otherwise ``point``,
    the masks and an infinite residual (the generated C skips it).
    """
    point, d = _symbols(lay, tree, dims, data)
    act = [ca.MX.sym("act_l", point[2].sparsity()),
           ca.MX.sym("act_u", point[2].sparsity())]
    nxt = list(next_active(point, tuple(act)))
    pol = list(polish(kern, lay, tree, dims, flags, point, d, sweeps,
                      tuple(nxt)))
    args = point + act + d
    run = ca.Function("sw_polish_step", args,
                      pol + nxt + [residual(pol, d)])
    skip = passing("sw_polish_enough", args,
                   lambda a: a[:8] + [ca.MX(ca.inf)])
    return ca.Function.if_else("sw_polish_next", run, skip)


def polish_more(kern: dict, lay: Any, tree: Any, dims: tuple,
                flags: np.ndarray, sweeps: dict, residual: Residual,
                data: list) -> Callable[..., list]:
    """``more(c, point…, act_l, act_u, data…) -> [point…, kkt]``.

    When ``c``: a step of the active-set method from the polished
    ``point`` (`_active_step`), and a second one when the first's point
    misses `POLISH_ACCEPT` (it still breaks a box, or a box it added
    came out with the wrong sign: on a tree of 17 scenarios a cruise at
    the rate bound took two steps), the better of the two and its
    residual; otherwise ``point`` and an infinite residual (the
    generated C skips both). The step is one Function,
    built once per solve and called twice, in the caller's own graph
    (its code is in the C once, and no Function level more reserves the
    QP's data in the work vector).
    """
    step = _active_step(kern, lay, tree, dims, flags, sweeps, residual,
                        data)

    def more(c: Any, *args: Any) -> list:
        point, act, d = args[:6], args[6:8], args[8:]
        *pol, al, au, kkt = step(c, *point, *act, *d)
        *pol2, _, _, kkt2 = step(
            ca.logic_and(c, kkt > POLISH_ACCEPT), *pol, al, au, *d)
        second = kkt2 < kkt                  # a NaN kkt2 is not taken
        return ([ca.if_else(second, a, b) for a, b in zip(pol2, pol)]
                + [ca.if_else(second, kkt2, kkt)])

    return more


def cascade_function(kern: dict, lay: Any, tree: Any, dims: tuple,
                     flags: np.ndarray, sweeps: dict, residual: Residual,
                     more: Callable[..., list], data: list
                     ) -> ca.Function:
    """``again(c, point…, kkt_ref, data…) -> (point…, kkt)``: when ``c``,
    the `cascade` from ``point`` and its residual; otherwise ``point``
    and an infinite residual (the generated C skips it)."""
    point, d = _symbols(lay, tree, dims, data)
    ref = ca.MX.sym("kkt_ref")
    pol, kkt_p = cascade(kern, lay, tree, dims, flags, sweeps, residual,
                         more, point, d, ref)
    args = point + [ref] + d
    run = ca.Function("sw_polish_cascade", args, pol + [kkt_p])
    skip = passing("sw_polish_kept", args,
                   lambda a: a[:6] + [ca.MX(ca.inf)])
    return ca.Function.if_else("sw_polish_again", run, skip)
