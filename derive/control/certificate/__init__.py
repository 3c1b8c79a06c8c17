"""Observer certificate for n joints: the appendix's Lyapunov argument (proof of theorem 2), generalised.

With the observer error e' = B d - dhat' (a1, a5): e'' = -W J^-1(theta) e'. For
V = e'^T W^-T J(theta) W^-1 e' (a7) and x = W^-1 e',

    dV/dt = -x^T (W + W^T - J'(theta, theta')) x,   J' = sum_k theta'_k dJ/dtheta_k,

so V decays at least as exp(-2 beta t) (the estimate converges exponentially at rate beta) when

    N(theta, theta') = W + W^T - J'(theta, theta') - 2 beta J(theta)  is positive definite     (*)

for every theta (within joint limits where the arm has them) and every theta' in the box
|theta'_k| <= v s_k (s: the box's shape, v its scale). J' is linear in theta', so N is affine in
theta' and its smallest eigenvalue is concave there: the box is covered exactly by its 2^m
vertices (m: the joints whose angle J depends on; the others' speeds do not enter J').

Over theta the claim is decided by branch and bound, sound for every theta: on a cell with centre
c and half-widths r, each entry of N moves by at most sum_k r_k sup |dN_ij/dtheta_k| (mean value
theorem), where the supremum is bounded symbolically: dN/dtheta_k is a polynomial in cos, sin of
the angles (and in the coordinates of prismatic joints, bounded by their limits), and the sum of
the absolute values of its coefficients bounds it (|cos|, |sin| <= 1). With R the matrix of these
entry bounds, ||N(theta) - N(c)||_2 <= ||R||_2 (R is nonnegative), so Weyl's inequality gives
lambda_min(N(theta)) >= lambda_min(N(c)) - ||R||_2 on the whole cell. A cell where that is above
a floating-point margin is proved; otherwise it is split along its widest contribution. A centre
where N itself is not positive definite refutes (*) at that point. A cell budget bounds the work:
past it the claim is ``unproven`` with the numeric evidence.
"""
from __future__ import annotations

import itertools
import math
import time
from dataclasses import replace

import numpy as np

from derive.control.certificate.decision import (FLOAT_MARGIN, MAX_ENUMERATED, CellBounds, Decision,  # noqa: F401
                                                  Verdict, _cholesky_passes, _positive_definite, _spectral_norm,
                                                  halve_cells)
from derive.control.certificate.inertia import Coordinate, InertiaModel, joint_coordinates
from derive.control.certificate.norm_bound import MAX_VERTEX_DEPS, norm_lower_bound, sample_count, sign_patterns
from derive.control.certificate.suprema import Suprema
from derive.control.certificate.split import MAX_INNER, SplitModel, split_model

__all__ = ["Coordinate", "Decision", "InertiaModel", "ObserverCertificate", "Verdict", "joint_coordinates"]

DEFAULT_BUDGET = 20_000   # cells per decision
EXACT_SAMPLES = 512         # points where a split certificate looks for a refutation of N itself
CELL_ELEMENTS = 1 << 22     # numbers of the largest per-batch array of a decision (the Hessian term)


class ObserverCertificate(Suprema):
    """Decides (*) for an arm's J: give W, the box shape s (n), its scale v and the rate beta."""

    def __init__(self, model: InertiaModel, shape=None, inner: int = MAX_INNER, wider: bool = False,
                 grouped: bool = False) -> None:
        """``shape``: the speed box's shape the split (derive.control.certificate.split) is chosen for (ones
        when None); the split is used past MAX_ENUMERATED angles when J is a trigonometric
        polynomial, with ``inner`` angles decided by branch and bound. With ``wider`` such a
        certificate also holds ``wider``: the same with one inner angle more (when an outer angle
        is left), which :meth:`decide` tries when the first is unproven: four angles branched
        instead of three, slower cells but a majorant of fewer terms (the Panda's synthesised W,
        make bench: the box proved grows from 26 % to 34 % of the numeric supremum, and the
        search's CPU time from seconds to about a minute, which is why it is not the default). With
        ``grouped`` such a certificate also holds the grouped stage (derive.control.certificate.grouped_union:
        the outer angles' terms bounded group by group, four inner angles on cells shared by the
        speed vertices), which :meth:`decide` tries last at rate 0 on the box shape it was made for
        (the Panda's synthesised W: above 80 % of the numeric supremum in under a minute, make bench);
        not on a shape that holds a joint J depends on at rest (0: the stage weighs the vertices by
        1 / shape)."""
        self.model = model
        self._exact = None   # _decide's samples of N itself (with a split) and J's derivatives there
        m = model.m
        self.split: SplitModel | None = None
        self.wider: ObserverCertificate | None = None
        self.grouped = None
        if m > MAX_ENUMERATED and model.fourier is not None and not model.unbounded:
            box = np.ones(model.n) if shape is None else np.asarray(shape, dtype=float)
            self.split = split_model(model, box, inner)
            if wider and m > inner + 1:
                self.wider = ObserverCertificate(model, shape, inner + 1)
            if grouped and np.all(box[[c.index for c in model.deps]] > 0):   # a joint at rest: no vertex weights
                from derive.control.certificate.grouped_union import GroupedStage   # imported when asked for
                self.grouped = GroupedStage(model, box)
        self.target = self.split if self.split is not None else model
        self.inner = list(self.split.inner) if self.split is not None else list(range(m))
        # many coordinates without J's series: one matrix bound (derive.control.certificate.norm_bound), sampled vertices
        self.norm = (self.split is None and m > MAX_VERTEX_DEPS and not model.unbounded
                     and getattr(model, "bounded_by", "") == "degrees")
        self.all_signs = sign_patterns(m)
        if self.norm:
            self.inner = []
        # the vertices the decision ranges over: every dep's sign, or the inner ones' with a split
        self.signs = np.ones((2 ** len(self.inner), m))
        self.signs[:, self.inner] = np.array(list(itertools.product((1.0, -1.0), repeat=len(self.inner))))
        if self.norm:
            self.signs = self.all_signs

    # -- numbers at points -------------------------------------------------------------------
    def speeds(self, shape, v: float, exact: bool = False) -> np.ndarray:
        """The box's vertices over every dep (scale v included): V x m [rad/s]; with a split and
        not ``exact``, the inner deps' 2^m_inner sign patterns (outer columns: the half-width)."""
        signs = self.all_signs if exact or self.split is None else self.signs
        return v * signs * np.array([shape[c.index] for c in self.model.deps])[None, :]

    def matrices(self, W: np.ndarray, shape: np.ndarray, v: float, beta: float, q: np.ndarray,
                 exact: bool = False, jets: tuple[np.ndarray, np.ndarray] | None = None) -> np.ndarray:
        """N at every box vertex for points q: N x 2^m x n x n. With a split and not ``exact``: the
        sound lower bound N_A - U(v) of derive.control.certificate.split at inner points q (N x m_inner); else
        N itself at points q (N x m). ``jets``: (dJ, J) of the model at q when the caller has them."""
        split = None if exact else self.split
        md = self.model if split is None else split
        S = W + W.T
        speeds = self.speeds(shape, v, exact)
        dJ, J = (md.dJ(q), md.J(q)) if jets is None else jets
        P, n = dJ.shape[0], dJ.shape[-1]
        lead = speeds[:, self.inner] if split is not None else speeds
        Jdot = (lead @ dJ.reshape(P, lead.shape[1], n * n)).reshape(P, -1, n, n)   # einsum's loop: 0.08 s of 576 x 64
        N = S[None, None] - Jdot - 2.0 * beta * J[:, None]
        return N if split is None else N - split.majorant(speeds, beta, self.scale_for(W, shape))[None]

    def scale_for(self, W: np.ndarray, shape) -> str:
        """The split's majorant for this W (derive.control.certificate.split: "J", absolute values in J's scale, or
        "I", in the identity's; both are sound): the one whose largest eigenvalue relative to
        W + W^T on the box is smaller ("I" when W + W^T is not positive definite). A function of W
        and the box only, so every decision on the same W (init's, derive check's) takes the same."""
        if self.split is None:
            return "J"
        S = np.asarray(W, dtype=float) + np.asarray(W, dtype=float).T
        try:
            Li = np.linalg.inv(np.linalg.cholesky(S))
        except np.linalg.LinAlgError:
            return "I"
        speeds = self.speeds(np.asarray(shape, dtype=float), 1.0)
        top = {key: np.linalg.eigvalsh(Li @ self.split.majorant(speeds, 0.0, key) @ Li.T)
               [:, -1].max() for key in ("J", "I")}
        return min(top, key=lambda key: (top[key], key))

    def lowest(self, W, shape, v, beta, q, exact: bool = False) -> tuple[np.ndarray, np.ndarray]:
        """Smallest eigenvalue of N over the vertices at each point, and the worst vertex index."""
        lam = np.linalg.eigvalsh(self.matrices(W, shape, v, beta, q, exact))[..., 0]
        return lam.min(axis=1), lam.argmin(axis=1)

    def samples(self, count: int, seed: int = 0, exact: bool = False) -> np.ndarray:
        """A grid over the spans (at most ``count`` points) plus as many random points: of the
        inner angles with a split (unless ``exact``), of every dep otherwise."""
        md = self.model if exact else self.target
        if md.m == 0:
            return np.zeros((1, 0))
        per = max(2, int(count ** (1.0 / md.m)))
        if md.m <= 2:
            per = max(4, per - per % 4)   # holds the quarter turns, where sin is +-1
        axes = [np.linspace(*span, per, endpoint=not periodic) for span, periodic in zip(md.spans, md.periodic)]
        if per ** md.m > 2 * count:   # 2^m corners alone past the count: random points only
            axes = [np.array([(lo + hi) / 2]) for lo, hi in md.spans]
        grid = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, md.m)
        rng = np.random.default_rng(seed)
        lo = np.array([span[0] for span in md.spans])
        hi = np.array([span[1] for span in md.spans])
        return np.vstack([grid, lo + (hi - lo) * rng.random((count, md.m))])

    def project(self, q: np.ndarray) -> np.ndarray:
        """Points over every dep (N x m) as points of :meth:`samples`' coordinates."""
        return q[:, self.inner] if self.split is not None else q

    # -- the sound decision ------------------------------------------------------------------
    def decide(self, W: np.ndarray, shape, v: float, beta: float = 0.0, budget: int = DEFAULT_BUDGET,
               batch: int = 512) -> Decision:
        """(*) for W (n x n, N m s/rad) on the box |theta'_k| <= v shape_k (rad/s) at rate beta
        (1/s): :meth:`_decide`, then, when unproven, the ``wider`` split's (each with ``budget``
        cells; the decision counts the cells and the time of both)."""
        first = self._decide(W, shape, v, beta, budget, batch)
        if first.verdict is not Verdict.UNPROVEN or self.wider is None:
            result = first
        else:
            second = self.wider._decide(W, shape, v, beta, budget, batch)
            both = {"cells": first.cells + second.cells, "seconds": first.seconds + second.seconds}
            result = replace(second if second.verdict is Verdict.PROVED else first, **both)
        if result.verdict is not Verdict.UNPROVEN or not self._grouped_for(shape, beta):
            return result
        third = self.grouped.decide(W, v)
        every = {"cells": result.cells + third.cells, "seconds": result.seconds + third.seconds}
        return replace(third if third.verdict is Verdict.PROVED else result, **every)

    def _decide(self, W: np.ndarray, shape, v: float, beta: float = 0.0, budget: int = DEFAULT_BUDGET,
                batch: int = 512) -> Decision:
        """Branch and bound over the deps' spans: proved, refuted or unproven (module docstring).

        On a cell (centre c, half-widths r), for each box vertex: Taylor's theorem per entry gives
        N(c + delta) = N(c) + sum_k delta_k dN/dq_k(c) + E with |E| <= 1/2 sum_jk r_j r_k T_jk
        (T_jk: the symbolic bounds of |d^2 N/dq_j dq_k|), so by Weyl lambda_min(N) >= (the smallest
        eigenvalue of the affine part, concave in delta, so least at a vertex of the cell) - ||E||_2.
        A cheaper lower bound of the affine part is tried first:
        lambda_min(N(c)) - || sum_k r_k |dN/dq_k(c)| ||_2. When the model has fourth-derivative
        bounds (J's series), the remainder is also bounded to second order, 1/2 || sum_jk r_j r_k
        |H_jk(c)| ||_2 (H: N's Hessian at the centre) + 1/6 || sum_ijk r_i r_j r_k T3_ijk ||_2 (T3:
        the bounds of |d^3 N|), and the smaller of the two remainders is used: O(r^3) instead of
        O(r^2), so far fewer cells on large spans.
        """
        start = time.perf_counter()
        md, split = self.target, self.split
        W = np.asarray(W, dtype=float)
        shape = np.asarray(shape, dtype=float)
        tol = FLOAT_MARGIN * (1 + np.linalg.norm(W + W.T, 2))

        def done(verdict, cells, margin=None, point=None, low=math.nan):
            return Decision(verdict, cells, margin, point, low, time.perf_counter() - start)

        if self.model.unbounded:
            return done(Verdict.UNPROVEN, 0)
        if self.norm:
            return self._decide_norm(W, shape, v, beta, done)
        if md.m == 0 and split is None:
            lam, _ = self.lowest(W, shape, v, beta, np.zeros((1, 0)))
            ok = lam[0] > tol
            return done(Verdict.PROVED if ok else Verdict.REFUTED, 1, float(lam[0]) if ok else None,
                        None if ok else ((), ()), float(lam[0]))
        exact_point = None
        if split is not None:   # the split refutes nothing: N itself at samples may
            if self._exact is None:   # the samples and J's derivatives there, the same for every decision
                q = self.samples(EXACT_SAMPLES, exact=True)
                self._exact = (q, (self.model.dJ(q), self.model.J(q)))
            q, jets = self._exact

            def exact_point(A=None):   # the sample and vertex of N's smallest eigenvalue, and that eigenvalue
                lam = np.linalg.eigvalsh(self.matrices(W, shape, v, beta, q, True, jets) if A is None else A)[..., 0]
                i, vi = np.unravel_index(int(lam.argmin()), lam.shape)
                where = tuple(float(x) for x in self.speeds(shape, v, True)[vi])
                return (tuple(float(x) for x in q[i]), where), lam[i, vi]

            # a Cholesky test above the floating-point margin first (7 times cheaper than the eigenvalues): where it
            # passes every eigenvalue is positive, and the smallest is wanted only for an unproven claim's point
            A = self.matrices(W, shape, v, beta, q, True, jets)
            if not _positive_definite(A - tol * np.eye(A.shape[-1])).all():
                point, least = exact_point(A)
                if least <= 0:
                    return done(Verdict.REFUTED, 0, None, point, float(least))
            del A
        m, n = md.m, md.n
        cb = self.cell_bounds(W, shape, v, beta)
        speeds, sc, S = cb.speeds, cb.sc, cb.S
        tol = FLOAT_MARGIN * (1 + np.linalg.norm(S, 2))
        deltas = np.array(list(itertools.product((1.0, -1.0), repeat=m)))      # 2^m x m
        lo = np.array([span[0] for span in md.spans])
        hi = np.array([span[1] for span in md.spans])
        centres, halves = ((lo + hi) / 2)[None, :], ((hi - lo) / 2)[None, :]
        cells, margin, low, worst = 0, math.inf, math.inf, None
        lead = cb.lead

        # cells per batch: the Hessian's P x V' x m^2 x n^2 numbers within CELL_ELEMENTS (an 8-joint chain's
        # 512 cells x 64 vertices x 7^2 x 8^2 were 0.8 GB an array, 2.3 GB in check); the cells examined are
        # the same (each cell's fate is its own), only the budget's test comes at other batch boundaries
        batch = int(min(batch, max(16, CELL_ELEMENTS // max(1, lead * max(m, 1) ** 2 * n * n))))

        while centres.shape[0]:
            c, h = centres[:batch], halves[:batch]
            centres, halves = centres[batch:], halves[batch:]
            cells += c.shape[0]
            N, dN, floor, state = cb.centre(c, h)
            lam = np.linalg.eigvalsh(N)[..., 0]                                           # P x V
            i, vi = np.unravel_index(int(lam.argmin()), lam.shape)
            if lam[i, vi] < low:
                low, worst = float(lam[i, vi]), (c[i], vi)
            if lam[i, vi] <= 0:
                if split is not None:
                    return done(Verdict.UNPROVEN, cells, None, exact_point()[0], low)
                theta = tuple(float(x) for x in c[i])
                own = float(np.linalg.eigvalsh(N[i, vi] / sc)[0])   # N itself, unscaled, for the message
                return done(Verdict.REFUTED, cells, None, (theta, tuple(float(x) for x in speeds[vi])), own)
            # the second-order remainder and the linear term only in cells the remainder's lower bound leaves
            # alive: elsewhere a vertex fails for sure (lam - rem <= tol), so rem's first form (an upper bound) and
            # lin = inf stand in, and no vertex of the cell is enumerated
            rem = np.broadcast_to(state[5][:, None], lam.shape).copy()
            lin = np.full(lam.shape, np.inf)
            rows = np.flatnonzero(lam.min(axis=1) > floor + tol)
            if rows.size:
                rem[rows], lin[rows] = cb.finish(state, rows)
            bound = lam - lin                                                                  # P x V
            # the vertices' minimum of the affine part is at most its value at the centre (concave): enumerate
            # them only where the cheap bound fails and the centre's own eigenvalue could still succeed, in cells
            # where no vertex fails for sure (lam - rem <= tol: such a cell is split whatever the others give)
            alive = lam - rem > tol
            hard = np.argwhere((bound - rem <= tol) & alive & alive.all(axis=1, keepdims=True)) \
                if m <= MAX_ENUMERATED else np.zeros((0, 2), int)
            # there, first a Cholesky test at each vertex (9 times cheaper than its eigenvalues), shifted by half
            # the centre's slack (an upper bound of the vertices'); the eigenvalues of those that fail it
            step = max(1, 2 ** 21 // (deltas.shape[0] * n * n))
            for chunk in range(0, hard.shape[0], step):
                pv = hard[chunk:chunk + step]
                corners = ((deltas[None] * h[pv[:, 0]][:, None, :]) @ dN[pv[:, 0], pv[:, 1]].reshape(-1, m, n * n)) \
                    .reshape(-1, deltas.shape[0], n, n)                                       # B x 2^m x n x n
                centre = N[pv[:, 0], pv[:, 1]]                                                # B x n x n
                r = rem[pv[:, 0], pv[:, 1]]
                shift = r + np.maximum(2.0 * tol, 0.5 * (lam[pv[:, 0], pv[:, 1]] - r))
                # A - shift I at every corner, A = N + corners, written n x n x B x 2^m for the Cholesky test
                X = np.empty((n, n) + corners.shape[:2])
                np.add(centre.transpose(1, 2, 0)[..., None], corners.transpose(2, 3, 0, 1), out=X)
                X[np.arange(n), np.arange(n)] -= shift[:, None]
                passed = _cholesky_passes(X.reshape(n, n, -1)).reshape(corners.shape[:2]).all(axis=1)
                bound[pv[passed, 0], pv[passed, 1]] = shift[passed]
                pv, A = pv[~passed], centre[~passed][:, None] + corners[~passed]
                if pv.shape[0]:   # the few near the edge: their vertices' eigenvalues, the margin exact there
                    bound[pv[:, 0], pv[:, 1]] = np.linalg.eigvalsh(A)[..., 0].min(axis=1)
            slack = (bound - rem).min(axis=1)
            ok = slack > tol
            if ok.any():
                margin = min(margin, float(slack[ok].min()))
            todo = ~ok
            if todo.any():
                if cells + centres.shape[0] + 2 * int(todo.sum()) > budget:
                    point = exact_point()[0] if split is not None else (
                        tuple(float(x) for x in worst[0]), tuple(float(x) for x in speeds[worst[1]]))
                    return done(Verdict.UNPROVEN, cells, None, point, low)
                kids, kid_halves = halve_cells(c[todo], h[todo], cb.axis(dN[todo], h[todo]))
                centres, halves = np.vstack([centres, kids]), np.vstack([halves, kid_halves])
        return done(Verdict.PROVED, cells, margin, None, low)

    def cell_bounds(self, W: np.ndarray, shape, v: float, beta: float) -> CellBounds:
        """The bounds :meth:`_decide` takes on its cells for W (n x n) on the box of scale v (the
        speeds of its coordinates; with a split the majorant of the rest) at rate beta, every matrix
        in J's diagonal scale D^-1 N D^-1 (D^2: J's diagonal at the middle of the spans): positive
        definiteness is the same, an entrywise bound scales entry by entry, and a light wrist's small
        eigenvalues are no longer measured against the base's large variation."""
        md, split = self.target, self.split
        W, shape = np.asarray(W, dtype=float), np.asarray(shape, dtype=float)
        all_speeds = self.speeds(shape, v)                                      # V x m_full
        sc = np.outer(self.model.scale, self.model.scale)
        offset = (split.majorant(all_speeds, beta, self.scale_for(W, shape)) if split is not None
                  else np.zeros((1, md.n, md.n))) * sc
        return CellBounds(md, all_speeds[:, self.inner], (W + W.T) * sc, offset, beta, sc)

    def _decide_norm(self, W: np.ndarray, shape: np.ndarray, v: float, beta: float, done) -> Decision:
        """(*) by one matrix bound for every theta and speed (derive.control.certificate.norm_bound); a refutation
        only from N itself at seeded samples and sampled vertices. One cell."""
        sc = np.outer(self.model.scale, self.model.scale)
        tol = FLOAT_MARGIN * (1 + np.linalg.norm((W + W.T) * sc, 2))
        q = self.samples(sample_count(self.all_signs.shape[0], self.model.n, EXACT_SAMPLES), exact=True)
        lam = np.linalg.eigvalsh(self.matrices(W, shape, v, beta, q, exact=True))[..., 0]
        i, vi = np.unravel_index(int(lam.argmin()), lam.shape)
        worst = (tuple(float(x) for x in q[i]), tuple(float(x) for x in self.speeds(shape, v, True)[vi]))
        if lam[i, vi] <= 0:
            return done(Verdict.REFUTED, 1, None, worst, float(lam[i, vi]))
        bound = norm_lower_bound(self.model, W, shape, v, beta)
        if bound > tol:
            return done(Verdict.PROVED, 1, bound, None, float(lam[i, vi]))
        return done(Verdict.UNPROVEN, 1, None, worst, float(lam[i, vi]))

    def _grouped_for(self, shape, beta: float) -> bool:
        """Whether the grouped stage applies: it exists, rate 0, and the box has its shape."""
        return self.grouped is not None and beta == 0.0 and np.array_equal(
            np.asarray(shape, dtype=float)[[c.index for c in self.model.deps]], self.grouped.model.shape)

    # -- numeric suprema ---------------------------------------------------------------------


