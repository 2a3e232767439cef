"""Constrained conjugate gradient with FFT products (Polonsky & Keer 1999).

Minimises ``1/2 p.A p + z.p`` over ``p >= 0`` subject to the load constraints
``h^2 B^T p = target`` (:mod:`twoscale.reference._problem`): conjugate gradient on the
cells that carry pressure, where the gradient (the gap) is projected orthogonally to the
constraint basis ``B`` (Polonsky & Keer subtract its mean for load control; with tilt the
least-squares plane ``d - beta x - alpha y`` is subtracted), cells whose gap turns
negative re-enter, and the constraints are restored after each step by multiplying ``p``
with a constant (load control: Polonsky & Keer's rescaling) or, with tilt, with a plane
``c0 + c1 (x - px) + c2 (y - py)`` fitted so that the load and both moments are exact.

Every product ``A p`` goes through ``provider.grid_operator(grid)``: for the
half-space a zero-padded real FFT convolution of size ``next_fast_len(2 ny - 1) x
next_fast_len(2 nx - 1)``. The cost is two such products per iteration; the number of
iterations grows like the square root of the condition number, i.e. roughly linearly with
the number of cells across the contact (about 10 n_contact_diameter for 1e-10). So time
~ iterations x grid-size x log(grid-size): keep the grid tight around the cells that can
touch (cells with ``inf`` height are free but still pay for the FFT).
"""
from __future__ import annotations

import time

import numpy as np

from ..indenters import Surface
from ..influence.base import InfluenceProvider
from ..results import ContactResult
from ._problem import ContactProblem, build_result, initial_active_set, make_problem, trivial_result


def _restore_constraints(p: np.ndarray, B: np.ndarray, target: np.ndarray, sweeps: int = 4) -> None:
    """Make ``B^T p = target`` by ``p <- p * (B c)`` (in place), keeping ``p >= 0``."""
    k = B.shape[1]
    if k == 0:
        return
    if k == 1:
        s = float(B[:, 0] @ p)
        if s > 0:
            p *= target[0] / s
        return
    for _ in range(sweeps):
        on = p > 0
        Bp = B[on]
        M = Bp.T @ (Bp * p[on, None])
        c = np.linalg.lstsq(M, target, rcond=1e-13)[0]
        lam = Bp @ c
        p[on] *= lam
        if np.all(lam >= 0):
            return
        np.maximum(p, 0.0, out=p)


def _project(v: np.ndarray, B: np.ndarray, on: np.ndarray) -> np.ndarray:
    """Remove from ``v`` (in place) its least-squares fit by the columns of B over ``on``;
    return the fit coefficients."""
    k = B.shape[1]
    if k == 0:
        return np.zeros(0)
    if k == 1:
        c = np.array([v[on].mean()]) if np.any(on) else np.zeros(1)
        v -= c[0]
        return c
    c = np.linalg.lstsq(B[on], v[on], rcond=1e-13)[0]
    v -= B @ c
    return c


def _initial_pressure(problem: ContactProblem, op, z: np.ndarray, B: np.ndarray, target: np.ndarray,
                      E_star: float) -> np.ndarray:
    shape = problem.grid.shape
    if problem.mode == "penetration":
        # cells without indenter material (z set to 0 by the caller) start unloaded
        v = np.where(problem.candidates.ravel(), np.maximum(problem.penetration - z, 0.0), 0.0)
        Av = op.apply(v.reshape(shape)).ravel()
        return v * (v @ (problem.penetration - z)) / (v @ Av)
    p = initial_active_set(problem, E_star).ravel().astype(float)
    _restore_constraints(p, B, target)
    return p


def solve_cg(provider: InfluenceProvider, surface: Surface, *, penetration: float | None = None,
             total_load: float | None = None, tilt: bool = False, pivot=(0.0, 0.0),
             tol: float = 1e-10, max_iter: int = 20_000) -> ContactResult:
    """Full-grid contact by Polonsky & Keer's constrained conjugate gradient.

    Parameters
    ----------
    provider : InfluenceProvider
        The elastic body; only ``grid_operator`` is used (one operator per call).
    surface : Surface
        Indenter heights on the grid (mm); ``inf`` cells never touch.
    penetration : float, optional
        Rigid approach d, mm (penetration control).
    total_load : float, optional
        Total load W >= 0, N (load control). Exactly one of the two.
    tilt : bool, default False
        With ``total_load``: also solve the tilt angles (alpha about x, beta about y,
        rad) of a ball-and-socket joint at ``pivot`` so that both moments vanish.
    pivot : (float, float), default (0, 0)
        Joint position, mm.
    tol : float, default 1e-10
        Stop when the gap on the loaded cells and the interpenetration elsewhere are
        both below ``tol`` times the largest displacement.
    max_iter : int, default 20000
        Most CG iterations (two grid products each).

    Returns
    -------
    ContactResult
        ``method="cg"``; ``iterations={"cg": n}``; ``residuals={"gap": history}``
        (relative KKT residual per iteration).
    """
    t0 = time.perf_counter()
    problem = make_problem(surface, penetration=penetration, total_load=total_load, tilt=tilt, pivot=pivot)
    trivial = trivial_result(problem, "cg", {"total": time.perf_counter() - t0})
    if trivial is not None:
        return trivial
    op = provider.grid_operator(problem.grid)
    t_op = time.perf_counter()
    state = _iterate(problem, op, provider.material.E_star, tol, max_iter)
    p, u, m, it, hist, converged, message = state
    d, tilt_angles = problem.rigid_motion(m)
    shape = problem.grid.shape
    t_end = time.perf_counter()
    timings = {"operator": t_op - t0, "solve": t_end - t_op, "total": t_end - t0}
    return build_result(problem, "cg", p.reshape(shape), u.reshape(shape), d, tilt_angles, converged, message,
                        {"cg": it}, {"gap": hist}, timings)


def _iterate(problem: ContactProblem, op, E_star: float, tol: float, max_iter: int):
    shape = problem.grid.shape
    cand = problem.candidates.ravel()
    z = np.where(cand, problem.surface.height.ravel(), 0.0)
    B = problem.basis()
    target = problem.target()
    p = _initial_pressure(problem, op, z, B, target, E_star)
    t = np.zeros_like(p)
    G_old, conjugate = 1.0, False
    hist: list[float] = []
    m = np.zeros(B.shape[1])
    for it in range(max_iter + 1):
        u = op.apply(p.reshape(shape)).ravel()
        g = z + u
        on = p > 0
        if problem.mode == "penetration":
            g -= problem.penetration
        else:
            m = _project(g, B, on)
        scale = max(float(np.max(np.abs(u))), np.finfo(float).tiny)
        off = cand & ~on
        res = max(float(np.max(np.abs(g[on]), initial=0.0)), float(-np.min(g[off], initial=0.0))) / scale
        hist.append(res)
        if res <= tol:
            return p, u, m, it, hist, True, f"KKT residual {res:.2e} <= tol after {it} iterations"
        if it == max_iter:
            break
        G = float(g[on] @ g[on])
        beta = G / G_old if conjugate else 0.0
        t = np.where(on, g + beta * t, 0.0)
        G_old = G
        r = op.apply(t.reshape(shape)).ravel()
        if B.shape[1]:
            _project(r, B, on)
        denom = float(r[on] @ t[on])
        if not denom > 0:
            return p, u, m, it, hist, False, f"CG breakdown (t.A t = {denom:.3e}) after {it} iterations"
        tau = float(g[on] @ t[on]) / denom
        p -= tau * t
        np.maximum(p, 0.0, out=p)
        reenter = cand & (p == 0.0) & (g < 0.0)
        conjugate = not np.any(reenter)
        p[reenter] -= tau * g[reenter]
        _restore_constraints(p, B, target)
    return p, u, m, it, hist, False, f"KKT residual {hist[-1]:.2e} > tol={tol:g} after max_iter={max_iter}"
