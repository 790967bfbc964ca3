"""Paper III's QP solvers compared on the QPs of its own runs (docs/performance.md, "Paper III's
QP solver, chosen by measurement").

For each experiment: run it once (the solver the spec names), keep every 10th tick's built
§III-D QP (P, q, A, b, lb, ub, and the tick's warm start), then solve each kept QP with the
compiled active set (the exact minimiser, the reference) and with each ``qpsolvers`` backend
through ``qpsolvers.solve_problem``, in both forms (the full problem,
:func:`.centroidal_qp.solve_with_qpsolvers`; ξ̈ eliminated, as the controller does,
:func:`.centroidal_qp.eliminate_accelerations` then
:func:`.centroidal_qp.solve_bounded_with_qpsolvers`), at ``qp_tolerance`` 1e-9 for the
iterative ones, and report µs per solve (median, p99), the largest relative KKT residual, and
the largest distance to the exact solution (ξ̈ [m/s², rad/s²]; β relative to the largest β).

    python benchmarks/jo_oh_qp_solvers.py obstacle_4cm walk_flat_kist tilted_step_5cm
"""

from __future__ import annotations

import json
import sys
import tempfile
import time

import numpy as np

import walkrepro
from walkrepro.papers.jo_oh import centroidal_qp as cq

EVERY = 10  # keep every 10th tick's QP
LIBRARIES = ("daqp", "proxqp", "osqp", "quadprog")


def capture(name: str, out: str) -> list[dict]:
    """The built QPs of every EVERY-th tick of a run of ``name``."""
    kept: list[dict] = []
    original, ticks = cq.CentroidalQP.solve, [0]

    def solve(self: cq.CentroidalQP, warm: bool) -> bool:
        ticks[0] += 1
        if ticks[0] % EVERY == 0:
            problem = self.build()
            kept.append(
                {key: np.array(value) for key, value in problem._asdict().items()}
                | {"nv": self.nv, "x0": self.solution.x.copy(), "warm": warm}
            )
        return original(self, warm)

    cq.CentroidalQP.solve = solve
    try:
        walkrepro.run(name, out=out)
    finally:
        cq.CentroidalQP.solve = original
    return kept


def kkt(problem: cq.QPProblem, x: np.ndarray, nv: int) -> float:
    """The largest of the equality, bound, stationarity and complementarity residuals of x,
    relative to the problem's scale (ν fitted on the free ξ̈ rows, μ = Px + q − Aᵀν on β)."""
    p, q, a, b = problem.P, problem.q, problem.A, problem.b
    scale = max(1.0, np.abs(b).max(), np.abs(q).max())
    grad = p @ x + q
    nu = np.linalg.lstsq(a[:, :nv].T, grad[:nv], rcond=None)[0]
    dual = grad - a.T @ nu
    beta, mu = x[nv:], dual[nv:]
    return max(
        np.abs(a @ x - b).max() / scale,
        max(0.0, -beta.min()),
        max(np.abs(dual[:nv]).max(), max(0.0, -mu.min())) / scale,
        np.abs(mu * beta).max() / scale,
    )


def compare(kept: list[dict]) -> dict[str, dict[str, float]]:
    """µs per solve, KKT and the distance to the active set's exact solution, per solver."""
    problems = [cq.QPProblem(**{k: r[k] for k in cq.QPProblem._fields}) for r in kept]
    exact, times = [], []
    for problem, r in zip(problems, kept, strict=True):
        x, nv = r["x0"].copy(), r["nv"]
        start = time.perf_counter()
        assert cq.solve_active_set(problem, nv, problem.P[nv, nv], x) >= 0
        times.append(time.perf_counter() - start)
        exact.append(x)
    result = {
        "active_set": _summary(
            times, [kkt(p, x, r["nv"]) for p, x, r in zip(problems, exact, kept, strict=True)]
        )
    }
    for solver in LIBRARIES:
        for form in ("full", "eliminated"):
            result[f"{solver} ({form})"] = _library(solver, form, problems, kept, exact)
    return result


def _library(
    solver: str, form: str, problems: list, kept: list[dict], exact: list[np.ndarray]
) -> dict[str, float]:
    """One backend on every kept problem, in one form (``full`` or ``eliminated``)."""
    options = cq.solver_options(solver, 1e-9)
    times, residuals, accel, beta, failed = [], [], [], [], 0
    for problem, r, x_exact in zip(problems, kept, exact, strict=True):
        nv, warm = r["nv"], r["warm"]
        start = time.perf_counter()
        if form == "full":
            x = cq.solve_with_qpsolvers(
                problem, solver, r["x0"].copy() if warm else None, **options
            )
        else:
            eliminated = cq.empty_eliminated(nv, problem.q.size - nv)
            cq.eliminate_accelerations(problem, nv, problem.P[nv, nv], eliminated)
            start_beta = r["x0"][nv:].copy() if warm else None
            b = cq.solve_bounded_with_qpsolvers(eliminated, solver, start_beta, **options)
            x = None if b is None else np.r_[eliminated.offset + eliminated.sensitivity @ b, b]
        times.append(time.perf_counter() - start)
        if x is None:
            failed += 1
            continue
        residuals.append(kkt(problem, x, nv))
        accel.append(np.abs(x[:nv] - x_exact[:nv]).max())
        beta.append(np.abs(x[nv:] - x_exact[nv:]).max() / max(1.0, np.abs(x_exact[nv:]).max()))
    return _summary(times, residuals) | {
        "accel_diff_max": float(max(accel)),
        "beta_rel_diff_max": float(max(beta)),
        "failures": failed,
    }


def _summary(times: list[float], residuals: list[float]) -> dict[str, float]:
    return {
        "us_median": 1e6 * float(np.median(times)),
        "us_p99": 1e6 * float(np.percentile(times, 99)),
        "kkt_max": float(max(residuals)),
        "n": len(times),
    }


if __name__ == "__main__":
    report = {}
    with tempfile.TemporaryDirectory() as out:
        for name in sys.argv[1:]:
            report[name] = compare(capture(name, out))
            print(name, json.dumps(report[name], indent=1), flush=True)
