"""The iteration of Kohout, Kellnhofer & Martelli (2012), eq. 11, for comparison."""

from __future__ import annotations

import numpy as np

from .._typing import FloatArray
from ..mesh import mean_rows, volume, volume_gradient
from ._result import Solved

__all__ = ["PaperSteps", "solve_paper"]


class PaperSteps:
    """The paper's iteration as a method of `Deformer` (``method="paper"``).

    A mixin: it reads the deformer's muscle, ``_diag``, ``_solve`` and ``energy``.
    """

    def solve_paper(
        self,
        x_ls: FloatArray,
        b: FloatArray,
        d_L: FloatArray,
        s_cur: FloatArray,
        *,
        max_iterations: int = 200,
        alpha: float | None = None,
        switch: float = 1e-3,
        eps: float = 1e-9,
    ) -> Solved:
        """Gauss-Newton with one Lagrange multiplier (eq. 11 of the paper).

        Starting from the rest cage, each step is
        ``h = -(J^T J)^{-1} (J^T f + J_g^T lambda)`` with ``f = H x - b``,
        ``J = H = A^T A``; ``lambda`` cancels the linearised volume error divided
        by ``alpha`` (section 5.2). The volume is first the cage's, scaled by the
        rest fine/cage volume ratio, and, once the step falls below ``switch``
        (relative to the cage size), the fine mesh's through the coordinates.

        Parameters
        ----------
        self : Deformer
            The bound muscle.
        x_ls : (m, 3) float64 array
            Unconstrained least-squares solution ``H^{-1} b``.
        b : (m, 3) float64 array
            ``A^T d``.
        d_L, s_cur : arrays
            Rotated differential coordinates and skeleton targets (for the energy).
        max_iterations : int, optional
            Iteration limit (the paper used 100 to 200).
        alpha : float, optional
            Fixed step; default adaptive: 0.5, halved (down to 0.025) whenever the
            step stops shrinking.
        switch : float, optional
            Relative step below which the fine volume replaces the cage volume.
        eps : float, optional
            Relative step below which the iteration stops (with the fine volume
            error below 1e-9).

        Returns
        -------
        x, V, iterations, converged, reason, history

        Notes
        -----
        ``(J^T J)^{-1} J^T f = H^{-1} f = x - x_ls`` and ``(J^T J)^{-1} = H^{-2}``
        are applied with two solves by the Cholesky factor of ``H`` instead of
        forming ``H^2`` (same iterates, squared condition number avoided). The
        multiplier uses the exact linearisation ``lambda = (dv/alpha - J_g e) /
        (J_g H^{-2} J_g^T)``; the paper prints ``+ J_g e``, a sign that does not
        cancel the residual term.
        """
        mu = self.muscle
        C0, CF = mu.cage.C, mu.cage.CF
        ratio = mu.volume_rest / volume(C0, CF)
        diag = self._diag
        x = C0.copy()
        a = 0.5 if alpha is None else float(alpha)
        fine = False
        hist: list[tuple[float, float]] = []
        prev_step = np.inf
        reason = f"iteration limit {max_iterations} reached"
        converged = False
        its = 0
        V = mu.W @ x
        for its in range(1, max_iterations + 1):
            if fine:
                # mean value coordinates sum to one: W (x - c) = W x - c, and V = W x is current
                c = mean_rows(x)
                P = V - c
                dv = volume(P, mu.F, center=np.zeros(3)) - mu.volume_rest
                g = mu.W_T @ volume_gradient(P, mu.F)
            else:
                dv = (volume(x, CF) - volume(C0, CF)) * ratio
                g = volume_gradient(x, CF) * ratio
            e = x - x_ls
            y = self._solve(g)
            z = self._solve(y)
            lam = (dv / a - np.sum(g * e)) / np.sum(g * z)
            h = -e - lam * z
            x = x + a * h
            step = float(np.abs(a * h).max()) / diag
            V = mu.W @ x
            err = volume(V, mu.F) / mu.volume_rest - 1
            hist.append((self.energy(x, d_L, s_cur), err))
            if alpha is None and step > 0.9 * prev_step:
                a = max(a * 0.5, 0.025)
            prev_step = step
            if not fine and step < switch:
                fine = True
            elif fine and step < eps and abs(err) <= 1e-9:
                converged, reason = True, "converged"
                break
        return Solved(x, V, its, converged, reason, hist)


#: the paper's iteration called on a deformer: ``solve_paper(deformer, x_ls, b, d_L, s_cur)``
solve_paper = PaperSteps.solve_paper
