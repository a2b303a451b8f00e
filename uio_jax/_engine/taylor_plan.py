"""The schedule of a Taylor program (:mod:`.taylor_program`) for the engine (:mod:`.taylor`):
which instructions are constant along the flow, which keep their past orders, and in which
groups one order is computed.

* **Constant along the flow**: a parameter (a coordinate whose field entries are all None or
  the constant 0), a constant, and
  what is built from them only: their series stop at order 0, so a product with one of them
  is a scaling (``(c x)_k = c_0 x_k``), not a Cauchy sum, and they are not computed again.
* **History**: the instructions whose past orders a recurrence reads (the operands of a
  product, a quotient and its divisor, the circle pair and its argument, an exponential, a
  root, the fields of the known inputs, the roots asked for) keep every order in one array;
  the others only the order of the pass.
* **Levels**: an instruction's level is one more than its operands'; the instructions of one
  level are independent, so each level is computed as a few groups (one numpy operation for
  all sums, negations and scalings of the level; one call per product, quotient or
  generator).
"""

import numpy as np

#: the kinds computed as one numpy operation per group
VECTOR = ("add", "neg", "scale", "cmul", "mul")


def _refs(ins, i):
    """The instructions instruction ``i`` reads at the same pass."""
    op, a, param = ins[i]
    if op == "free":
        key, pairs, kind, operands = param
        return tuple(a) + tuple(v for pair in pairs for v in pair) + tuple(operands)
    return tuple(a)


class Plan:
    """The static schedule of a program.

    Args:
        ins: the instructions.
        fields: per field, the instruction of each coordinate's entry (None: zero).
        lagged: the lagged instructions.
        roots: the instructions asked for.
        inputs: whether some known input is nonzero (its fields keep their history).

    Attributes:
        constant: ``(n,)`` bool, constant along the flow.
        hist: instruction -> its row in the history array.
        first, steps: the groups of the first pass and of the later ones:
            ``(kind, lag, members, kept)`` with ``members`` a tuple of index arrays for a
            :data:`VECTOR` kind, a list of instructions otherwise, and ``kept`` the members
            that keep their history.
        coords: ``(instructions, coordinates)`` of the moving coordinates.
        sources: per moving coordinate, its entry in the drift (-1: none).
        input_terms: ``(position in coords, field, entry)`` of the known inputs' fields.
    """

    def __init__(self, ins, fields, lagged, roots, inputs: bool):
        self.ins, self.lagged = ins, set(lagged)
        n = len(ins)
        driven = {j for f in fields for j, s in enumerate(f) if s is not None and ins[s] != ("c", (), 0)}
        self.constant = np.zeros(n, dtype=bool)
        level = [0] * n
        for i, (op, a, param) in enumerate(ins):
            refs = _refs(ins, i)
            if op == "x":
                self.constant[i] = param not in driven
            elif op == "c":
                self.constant[i] = True
            elif i not in self.lagged:
                self.constant[i] = all(self.constant[j] for j in refs)
            if op not in ("x", "c"):
                level[i] = 1 + max((level[j] for j in refs), default=0)
        self.level = level
        keep = self._history(ins, fields, roots, inputs)
        self.hist = {i: h for h, i in enumerate(sorted(keep))}
        moving = [(i, param) for i, (op, a, param) in enumerate(ins) if op == "x" and not self.constant[i]]
        self.coords = (np.array([i for i, _ in moving], dtype=np.int64),
                       np.array([j for _, j in moving], dtype=np.int64))
        self.sources = np.array([-1 if fields[0][j] is None else fields[0][j] for _, j in moving], dtype=np.int64)
        self.input_terms = [(pos, f, field[j]) for f, field in enumerate(fields) if f
                            for pos, (_, j) in enumerate(moving) if field[j] is not None]
        self.const_rows = np.flatnonzero(self.constant)
        self.base = {int(i): b for b, i in enumerate(self.const_rows)}
        every = [i for i in range(n) if i not in self.lagged and ins[i][0] not in ("x", "c", "cos")]
        later = [i for i in range(n) if ins[i][0] not in ("x", "c", "cos") and
                 (i in self.lagged or not self.constant[i])]
        self.first = self._group(every)
        self.steps = self._group(later)

    def _history(self, ins, fields, roots, inputs):
        keep = set(roots)
        for i, (op, a, param) in enumerate(ins):
            if op == "mul" and not (self.constant[a[0]] or self.constant[a[1]]):
                keep.update(a)
            elif op == "div" and not self.constant[a[1]]:
                keep.update((i, a[1]))
            elif op == "sin":
                keep.update((i, param[0], a[0]))
            elif op in ("exp", "root"):
                keep.update((i, a[0]))
        if inputs:
            keep.update(s for field in fields[1:] for s in field if s is not None)
        return {i for i in keep if not self.constant[i]}

    def kind(self, i):
        """The group kind of instruction ``i``."""
        op, a, _ = self.ins[i]
        if op == "mul":
            if self.ins[a[0]][0] == "c" or self.ins[a[1]][0] == "c":
                return "scale"
            if self.constant[a[0]] or self.constant[a[1]]:
                return "cmul"
        return op

    def _group(self, members):
        groups = {}
        for i in members:
            key = (self.level[i], self.kind(i), 1 if i in self.lagged else 0)
            groups.setdefault(key, []).append(i)
        out = []
        for (_, kind, lag), group in sorted(groups.items()):
            kept = [i for i in group if i in self.hist] + \
                [self.ins[i][2][0] for i in group if kind == "sin" and self.ins[i][2][0] in self.hist]
            out.append((kind, lag, self._members(kind, group), np.array(kept, dtype=np.int64)))
        return out

    def _members(self, kind, group):
        ins = self.ins
        if kind not in VECTOR:
            return group
        out = np.array(group, dtype=np.int64)
        if kind in ("neg", "add"):  # (out, each operand)
            return (out, *(np.array(operand, dtype=np.int64) for operand in zip(*(ins[i][1] for i in group))))
        if kind == "scale":  # (out, operand, constant's value)
            pairs = [(a[1], a[0]) if ins[a[0]][0] == "c" else (a[0], a[1]) for a in (ins[i][1] for i in group)]
            return out, np.array([x for x, _ in pairs], dtype=np.int64), [ins[c][2] for _, c in pairs]
        if kind == "mul":  # (out, histories of the two operands)
            return (out, self._rows([ins[i][1][0] for i in group]), self._rows([ins[i][1][1] for i in group]))
        pairs = [(a[0], a[1]) if self.constant[a[0]] else (a[1], a[0]) for a in (ins[i][1] for i in group)]
        return out, np.array([c for c, _ in pairs], dtype=np.int64), np.array([x for _, x in pairs], dtype=np.int64)

    def _rows(self, members):
        """The history rows of ``members``: a slice where they are consecutive (a view of the
        history, not a copy), else an index array."""
        rows = np.array([self.hist[i] for i in members], dtype=np.int64)
        if len(rows) and (np.diff(rows) == 1).all():
            return slice(int(rows[0]), int(rows[0]) + len(rows))
        return rows


__all__ = ["Plan", "VECTOR"]
