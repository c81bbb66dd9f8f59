"""Lane helpers of the effects' compiled block laws (``spec.compiled``).

A block holds the state of L chains as an (ny, L) array, chains innermost, and every loop
runs over the lanes innermost, so that LLVM vectorises across chains. A law is called per
lane; its branches become selects (a lane-dependent ``if`` is written as ``a if cond else
b`` on values computed for every lane, and a lane's discarded value, e.g. the sqrt of a
negative overlap of an open contact, never reaches the state). The arithmetic of a lane is
that of one chain alone, operation for operation (no fastmath), so a chain's trajectory
does not depend on its lane or block.

Work whose result is exactly nothing for every lane is skipped: a contact open in every
lane (no normal force, no friction), a sphere exactly at rest with a zero history in
every lane. The skipped work would only add zeros (to sums that are never -0.0), so
skipping it does not change a bit; most contacts are open and most spheres ahead of the
wave at rest.
"""
from __future__ import annotations

import math

from .spec import compiled, touching


@compiled
def overlap(y, ox, G, k, l):
    """Overlap (m) of inner contact k in lane l: x_k - x_{k+1} - G_GAP_k."""
    return y[ox + k, l] - y[ox + k + 1, l] - G[k, l]


@compiled
def wall_overlap(y, ox, G, n, l):
    """Overlap (m) of the end wall's contact (contact n-1) in lane l: x_n - G_{n-1}."""
    return y[ox + n - 1, l] - G[n - 1, l]


@compiled
def contact_overlap(y, ox, G, n, k, l):
    """Overlap (m) of contact k in lane l: an inner contact's (k < n-1) or the end wall's."""
    return overlap(y, ox, G, k, l) if k < n - 1 else wall_overlap(y, ox, G, n, l)


@compiled
def closing_speed(y, ov, n, k, l):
    """Closing speed (m/s) of contact k in lane l: v_k - v_{k+1}, or at the end wall
    (k = n-1) the last sphere's velocity."""
    return y[ov + k, l] - y[ov + k + 1, l] if k < n - 1 else y[ov + n - 1, l]


@compiled
def clip_to_cap(x, cap):
    """A force or moment x held to its Coulomb cap: sgn(x) cap where |x| exceeds cap >= 0,
    else x (at |x| = cap the two are the same number)."""
    return math.copysign(cap, x) if abs(x) > cap else x


@compiled
def bit(mask, k):
    """Is bit k (k < 63) of mask set?"""
    return k < 63 and (mask >> k) & 1 != 0


@compiled
def any_contact(y, ox, G, k, L):
    """Is inner contact k closed in any of the L lanes?"""
    c = 0
    for l in range(L):
        c += 1 if overlap(y, ox, G, k, l) > 0.0 else 0
    return c > 0


@compiled
def any_touching(y, ox, LO, G, P, FL, on, n, k, L):
    """Is inner contact k touching in any of the L lanes (``spec.touching``: closed, or
    held closed in tension by its law)? ox: the offset of the positions in y."""
    c = 0
    for l in range(L):
        c += 1 if touching(overlap(y, ox, G, k, l), y, LO, G, P, FL, on, n, k, l) else 0
    return c > 0


@compiled
def moving(a, r, L):
    """Is row r of a non-zero in any of the L lanes?"""
    c = 0
    for l in range(L):
        c += 1 if a[r, l] != 0.0 else 0
    return c > 0
