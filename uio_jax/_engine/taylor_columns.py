"""Compressed gradient columns for the Taylor engine (:mod:`.taylor`): coordinates that no
instruction depends on together share one tangent column (Curtis, Powell and Reid's
compression of a sparse Jacobian).

The *support* of an instruction is the set of coordinates whose initial values its series
depends on at some order: a coordinate's is itself and, closed under the flow, every
coordinate its field entries read; an operation's is the union of its operands'. Every
instruction feeds a root (an output or a field entry), and its support is inside that root's,
so two coordinates *conflict* when one root's support holds both. A greedy colouring of the
coordinates without two conflicting ones of one colour gives the columns: the forward-mode
tangent seeded with the sum of the unit vectors of one colour is, for an instruction, its
partial derivative along the one coordinate of that colour in its support (the others do not
move it). A model of many outputs on few coordinates each (range-and-bearing SLAM: 403
coordinates, 6 colours) computes 7 columns per coefficient instead of 404; a model whose
coordinates all meet (a chain) keeps one column per coordinate.
"""

import numpy as np

#: supports and colouring are abandoned (one column per coordinate) beyond this much work
#: (bitset operations of the closure; coordinate pairs of the colouring)
WORK = 4_000_000


def bits(mask) -> list[int]:
    """The positions of the set bits of an integer, increasing."""
    return [j for j, ch in enumerate(reversed(bin(mask)[2:])) if ch == "1"]


def _supports(ins, seed):
    """Per instruction, the bitset of the coordinates it depends on (``seed[j]``: coordinate
    ``j``'s own)."""
    supp = [0] * len(ins)
    for i, (op, a, param) in enumerate(ins):
        if op == "x":
            supp[i] = seed[param]
        elif op == "free":
            key, pairs, kind, operands = param
            s = supp[a[0]]
            for c, u in pairs:
                s |= supp[c] | supp[u]
            for u in operands:
                s |= supp[u]
            supp[i] = s
        else:
            s = 0
            for b in a:
                s |= supp[b]
            supp[i] = s
    return supp


def _closure(ins, fields, n):
    """The coordinates' supports closed under the flow (None: too much work)."""
    once = _supports(ins, [1 << j for j in range(n)])
    direct = [[] for _ in range(n)]
    for field in fields:
        for j, s in enumerate(field):
            if s is not None:
                direct[j] += bits(once[s])
    reach = [1 << j for j in range(n)]
    work = 0
    changed = True
    while changed:
        changed = False
        for j in range(n):
            new = reach[j]
            for k in direct[j]:
                new |= reach[k]
            work += len(direct[j])
            if new != reach[j]:
                reach[j], changed = new, True
        if work > WORK:
            return None
    return reach


def colouring(ins, fields, roots, n):
    """``(colours (n,), count)``: the column of each coordinate's tangent (the identity when
    the coordinates all meet or the work is too large) and their number; and the support
    of every instruction as a bitset (None with the identity)."""
    identity = (np.arange(n, dtype=np.int64), n, None)
    reach = _closure(ins, fields, n)
    if reach is None:
        return identity
    supp = _supports(ins, reach)
    members = [bits(supp[r]) for r in set(roots)]
    if sum(len(m) ** 2 for m in members) > WORK or max((len(m) for m in members), default=0) > 0.9 * n:
        return identity
    meets = [[] for _ in range(n)]
    for m in members:
        for j in m:
            meets[j].append(m)
    colour = np.full(n, -1, dtype=np.int64)
    for j in range(n):
        used = {int(colour[k]) for m in meets[j] for k in m if colour[k] >= 0}
        c = 0
        while c in used:
            c += 1
        colour[j] = c
    count = int(colour.max()) + 1 if n else 0
    return (colour, count, supp) if count < 0.9 * n else identity


__all__ = ["colouring", "bits"]
