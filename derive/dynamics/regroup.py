"""Base inertial parameters: moving what a joint cannot see onto its parent body.

W. Khalil, F. Bennis, "Symbolic calculation of the base inertial parameters
of closed-loop robots" (1995) and Khalil, Dombre, *Modeling, identification
and control of robots* (2002), section 12.5, for any serial chain:

* revolute joint j with axis e_k (a coordinate axis of its own frame): the
  part of body j's inertia that rotation about e_k leaves unchanged and that
  has no moment about e_k, namely the mass m, the first moment h_k e_k and
  diag(K, K, 0) in the (e_i, e_j, e_k) axes with K = I_jj, moves with the
  joint's parent as if rigidly attached to it. It is moved onto body j-1
  (through joint j's fixed origin), and body j keeps m = 0, h_k = 0,
  I_ii - I_jj, I_jj = 0 (7 parameters instead of 10);
* prismatic joint j: its rotational inertia about F_j's origin with no mass
  (translation leaves it unchanged and it needs no force) moves onto body
  j-1; body j keeps m and h only.

Tip to base, so what body j receives is regrouped in turn. What reaches the
base (from joint 1) is dropped: the base does not move. J(q), the bias and
g(q) are unchanged as functions (the kinetic and potential energies are, for
every motion), with fewer terms; a joint about a general (non-coordinate)
axis is left as it is.
"""
from __future__ import annotations

from collections.abc import Sequence

from derive.dynamics.crba import Composite, body_composite
from derive.dynamics.spatial import (ZERO, ZERO_VEC, add, congruence, keep_sums, mat, mat_add, matvec, scale,
                                     shift_inertia, unit_axis, vec)
from derive.model.chain import Body, Joint


def _split(body: Composite, joint: Joint) -> tuple[Composite, Composite | None]:
    """(what body keeps, what moves to the parent in body's frame), or (body, None)."""
    axis = vec(joint.axis)
    if not joint.type.rotates:
        zero = ((ZERO,) * 3,) * 3
        return Composite(body.M, body.h, zero), Composite(ZERO, ZERO_VEC, body.I)  # type: ignore[arg-type]
    k = unit_axis(axis)
    if k is None:
        return body, None
    i, j = (k + 1) % 3, (k + 2) % 3
    K = body.I[j][j]
    keep_I = [list(r) for r in body.I]
    keep_I[i][i] = body.I[i][i] - K
    keep_I[j][j] = ZERO
    keep_h = tuple(ZERO if t == k else body.h[t] for t in range(3))
    moved_h = tuple(body.h[t] if t == k else ZERO for t in range(3))
    moved_I = tuple(tuple(K if (r == c and r != k) else ZERO for c in range(3)) for r in range(3))
    return (Composite(ZERO, keep_h, tuple(tuple(r) for r in keep_I)),  # type: ignore[arg-type]
            Composite(body.M, moved_h, moved_I))  # type: ignore[arg-type]


def _onto_parent(parent: Composite, moved: Composite, joint: Joint) -> Composite:
    """parent + moved, moved given in F_j and carried by joint j's fixed origin (q_j = 0)."""
    R0, p0 = mat(joint.origin.R), vec(joint.origin.p)
    h = matvec(R0, moved.h)
    I = shift_inertia(congruence(R0, moved.I), moved.M, h, p0)
    return Composite(parent.M + moved.M, add(parent.h, add(h, scale(moved.M, p0))), mat_add(parent.I, I))


@keep_sums
def base_parameters(bodies: Sequence[Body], joints: Sequence[Joint]) -> tuple[Composite, ...]:
    """The bodies with every regroupable parameter moved towards the base (same dynamics)."""
    work = [body_composite(b) for b in bodies]
    for j in reversed(range(len(work))):
        keep, moved = _split(work[j], joints[j])
        work[j] = keep
        if moved is not None and j > 0:
            work[j - 1] = _onto_parent(work[j - 1], moved, joints[j])
    return tuple(work)
