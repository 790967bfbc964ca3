"""The §III-D QP of Jo & Oh solved by a QP library, the oracle of the compiled active set.

A test oracle, not part of the package: the controller solves the QP exactly with ξ̈ and the
equality rows eliminated (``walkrepro.papers.jo_oh.condensed``); the tests hand the same
problem, as :func:`walkrepro.papers.jo_oh.centroidal_qp.build_qp` assembles it, to
``qpsolvers`` (ProxQP's dense backend, or OSQP) and compare the answers.
"""

from __future__ import annotations

import numpy as np
import qpsolvers
from scipy import sparse

from walkrepro.papers.jo_oh.centroidal_qp import QPProblem

#: The library solvers the tests check the active set against.
LIBRARY_SOLVERS = ("proxqp", "osqp")


def solve_with_library(
    problem: QPProblem, solver: str, initvals: np.ndarray | None = None, **options: object
) -> np.ndarray | None:
    """min ½ xᵀPx + qᵀx s.t. A x = b, lb ≤ x ≤ ub through ``qpsolvers``; None when no solution.

    Args:
        problem: the assembled QP.
        solver: a ``qpsolvers`` backend (``proxqp`` runs dense, ``osqp`` gets sparse matrices).
        initvals: a primal start, for the solvers that take one.
        options: the solver's settings (``eps_abs`` …).
    """
    if solver not in qpsolvers.available_solvers:
        raise ValueError(
            f"QP solver {solver!r} is not installed; installed: "
            f"{', '.join(qpsolvers.available_solvers)} (pip install qpsolvers[{solver}])"
        )
    p, a = problem.P, problem.A
    if solver == "proxqp":
        options = {"backend": "dense", **options}  # the matrices are dense
    elif solver == "osqp":  # OSQP takes sparse matrices; converting here avoids a warning
        p, a = sparse.csc_matrix(p), sparse.csc_matrix(a)
    qp = qpsolvers.Problem(p, problem.q, None, None, a, problem.b, problem.lb, problem.ub)
    solution = qpsolvers.solve_problem(qp, solver=solver, initvals=initvals, **options)
    return solution.x if solution.found else None
