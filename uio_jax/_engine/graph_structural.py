"""The structural rules of the jaxpr -> expression graph translation (:mod:`.graph_rules`).

They move node numbers around with numpy (slice, reshape, concatenate, broadcast,
transpose, padding, indexing with constant indices, ``.at[]`` updates) or make sums of
products (``dot_general``, reductions, ``cumsum``). An index computed from the state raises
:class:`~uio_jax._engine.graph_values.Untranslatable`; a constant index past the end
:class:`~uio_jax._engine.graph_values.IndexOutOfRange` (JAX would clamp it silently).
"""

import numpy as np

from .graph_values import IndexOutOfRange, Untranslatable, as_nodes, is_symbolic


def _slice(graph, i, eqn, ins):
    p = eqn.params
    strides = p["strides"] or (1,) * len(p["start_indices"])
    idx = tuple(slice(s, e, st) for s, e, st in zip(p["start_indices"], p["limit_indices"], strides))
    return [np.asarray(ins[0])[idx]]


def _squeeze(graph, i, eqn, ins):
    return [np.squeeze(np.asarray(ins[0]), axis=tuple(eqn.params["dimensions"]))]


def _reshape(graph, i, eqn, ins):
    if eqn.params.get("dimensions") not in (None, ()):
        raise Untranslatable("reshape", "with dimensions")
    return [np.reshape(np.asarray(ins[0]), eqn.params["new_sizes"])]


def _expand_dims(graph, i, eqn, ins):
    return [np.expand_dims(np.asarray(ins[0]), eqn.params["dimensions"])]


def _broadcast_in_dim(graph, i, eqn, ins):
    a = np.asarray(ins[0])
    shape, dims = eqn.params["shape"], eqn.params["broadcast_dimensions"]
    expanded = [1] * len(shape)
    for d, s in zip(dims, a.shape):
        expanded[d] = s
    return [np.broadcast_to(a.reshape(expanded), shape).copy()]


def _concatenate(graph, i, eqn, ins):
    if any(is_symbolic(v) for v in ins):
        ins = [as_nodes(graph, v) for v in ins]
    return [np.concatenate([np.asarray(v) for v in ins], axis=eqn.params["dimension"])]


def _stack(graph, i, eqn, ins):
    if any(is_symbolic(v) for v in ins):
        ins = [as_nodes(graph, v) for v in ins]
    return [np.stack([np.asarray(v) for v in ins], axis=eqn.params.get("axis", 0))]


def _transpose(graph, i, eqn, ins):
    return [np.transpose(np.asarray(ins[0]), eqn.params["permutation"])]


def _rev(graph, i, eqn, ins):
    return [np.flip(np.asarray(ins[0]), axis=tuple(eqn.params["dimensions"]))]


def _tile(graph, i, eqn, ins):
    return [np.tile(np.asarray(ins[0]), eqn.params["reps"])]


def _identity(graph, i, eqn, ins):
    return [ins[0]]


def _iota(graph, i, eqn, ins):
    p = eqn.params
    shape, dim = p["shape"], p["dimension"]
    ar = np.arange(shape[dim], dtype=np.dtype(p["dtype"]))
    view = [1] * len(shape)
    view[dim] = shape[dim]
    return [np.broadcast_to(ar.reshape(view), shape).copy()]


def _pad(graph, i, eqn, ins):
    a, value = ins
    config = eqn.params["padding_config"]
    if any(interior for _, _, interior in config) or any(lo < 0 or hi < 0 for lo, hi, _ in config):
        raise Untranslatable("pad", "interior or negative padding")
    if is_symbolic(a) or is_symbolic(value):
        a, value = as_nodes(graph, a), as_nodes(graph, value)
        out = np.empty(tuple(s + lo + hi for s, (lo, hi, _) in zip(a.shape, config)), dtype=object)
        out[...] = value.reshape(())
        out[tuple(slice(lo, lo + s) for s, (lo, _, _) in zip(a.shape, config))] = a
        return [out]
    return [np.pad(a, [(lo, hi) for lo, hi, _ in config], constant_values=value)]


def _concrete_index(v, what):
    if is_symbolic(v):
        raise Untranslatable(what, "an index that depends on the state")
    return np.asarray(v)


def _window(starts, sizes, shape, what) -> tuple:
    """The slices of a window of ``sizes`` at constant ``starts`` inside ``shape``."""
    idx = []
    for d, (s, size) in enumerate(zip(starts, sizes)):
        s = int(_concrete_index(s, what))
        if s < 0 or s + size > shape[d]:
            raise IndexOutOfRange(f"index {s} is out of bounds for axis {d} with size {shape[d]}")
        idx.append(slice(s, s + size))
    return tuple(idx)


def _dynamic_slice(graph, i, eqn, ins):
    a, *starts = ins
    a = np.asarray(a)
    return [a[_window(starts, eqn.params["slice_sizes"], a.shape, "dynamic_slice")]]


def _dynamic_update_slice(graph, i, eqn, ins):
    a, update, *starts = ins
    if is_symbolic(a) or is_symbolic(update):
        a, update = as_nodes(graph, a).copy(), as_nodes(graph, update)
    else:
        a = np.array(a)
    a[_window(starts, update.shape, a.shape, "dynamic_update_slice")] = update
    return [a]


def _gather(graph, i, eqn, ins):
    a, indices = ins
    indices = _concrete_index(indices, "gather")
    a = np.asarray(a)
    dn = eqn.params["dimension_numbers"]
    sizes = eqn.params["slice_sizes"]
    # the pattern of x[idx] (integer-array indexing of the first axis)
    if (tuple(dn.collapsed_slice_dims) == (0,) and tuple(dn.start_index_map) == (0,)
            and not getattr(dn, "operand_batching_dims", ()) and sizes[0] == 1
            and tuple(sizes[1:]) == a.shape[1:] and indices.shape[-1:] == (1,)):
        idx = indices[..., 0].astype(int)
        if (idx < 0).any() or (idx >= a.shape[0]).any():
            raise IndexOutOfRange(f"index {idx.max()} is out of bounds for axis 0 with size {a.shape[0]}")
        taken = a[idx]  # shape: indices batch + a.shape[1:]
        offset = tuple(dn.offset_dims)
        batch = idx.ndim
        if offset == tuple(range(batch, batch + a.ndim - 1)):
            return [taken]
    raise Untranslatable("gather", "an indexing pattern other than x[integer array]")


def _scatter(add):
    """``x.at[i].set(v)`` / ``.add(v)`` on a vector, with constant indices: single elements
    (``inserted_window_dims=(0,)``) or windows (``update_window_dims=(0,)``)."""

    def rule(graph, i, eqn, ins):
        a, indices, updates = ins
        indices = _concrete_index(indices, eqn.primitive.name)
        dn = eqn.params["dimension_numbers"]
        a, updates = np.asarray(a), np.asarray(updates)
        if (a.ndim != 1 or tuple(dn.scatter_dims_to_operand_dims) != (0,)
                or getattr(dn, "operand_batching_dims", ()) or indices.shape[-1:] != (1,)):
            raise Untranslatable(eqn.primitive.name, "a pattern other than a vector's .at[i]")
        starts = indices[..., 0].astype(int).reshape(-1)
        if tuple(dn.inserted_window_dims) == (0,) and not tuple(dn.update_window_dims):
            pieces = updates.reshape(-1, 1)
        elif not tuple(dn.inserted_window_dims) and tuple(dn.update_window_dims) == (updates.ndim - 1,):
            pieces = updates.reshape(len(starts), -1)
        else:
            raise Untranslatable(eqn.primitive.name, "a pattern other than a vector's .at[i]")
        if (starts < 0).any() or (starts + pieces.shape[1] > a.shape[0]).any():
            raise Untranslatable(eqn.primitive.name, "an index out of range (dropped by JAX)")
        if not (is_symbolic(a) or is_symbolic(updates)):
            out = np.array(a, dtype=np.result_type(a, updates))
            for s0, piece in zip(starts, pieces):
                if add:
                    out[s0:s0 + len(piece)] += piece
                else:
                    out[s0:s0 + len(piece)] = piece
            return [out]
        out, pieces = as_nodes(graph, a).copy(), as_nodes(graph, pieces)
        for s0, piece in zip(starts, pieces):
            for k, v in enumerate(piece):
                out[s0 + k] = graph.add(out[s0 + k], v) if add else v
        return [out]

    return rule


def _reduce(op):
    def rule(graph, i, eqn, ins):
        axes = tuple(eqn.params["axes"])
        a = ins[0]
        if not is_symbolic(a):
            fn = {"add": np.sum, "max": np.max, "min": np.min, "mul": np.prod,
                  "and": np.all, "or": np.any}[op]
            return [np.asarray(fn(a, axis=axes))]
        a = np.moveaxis(a, axes, tuple(range(-len(axes), 0)))
        lead = a.shape[: a.ndim - len(axes)]
        flat = a.reshape(lead + (-1,))
        out = np.empty(lead, dtype=object)
        of = out.reshape(-1)
        for k, row in enumerate(flat.reshape(-1, flat.shape[-1])):
            of[k] = _fold_row(graph, op, list(row))
        return [out]

    return rule


def _fold_row(graph, op, row):
    if op in ("add", "mul"):  # from the identity: an empty sum is 0, an empty product 1
        row = [graph.zero if op == "add" else graph.one, *row]
    acc = row[0]
    for v in row[1:]:
        if op in ("max", "min"):
            acc = graph.select(graph.binary("gt" if op == "max" else "lt", v, acc), acc, v)
        else:
            acc = graph.binary(op, acc, v)
    return acc


def _dot_general(graph, i, eqn, ins):
    lhs, rhs = ins
    (lc, rc), (lb, rb) = eqn.params["dimension_numbers"]
    if not (is_symbolic(lhs) or is_symbolic(rhs)):
        return [_np_dot_general(np.asarray(lhs), np.asarray(rhs), lc, rc, lb, rb)]
    lhs, rhs = as_nodes(graph, lhs), as_nodes(graph, rhs)
    lf = [d for d in range(lhs.ndim) if d not in lc and d not in lb]
    rf = [d for d in range(rhs.ndim) if d not in rc and d not in rb]
    L = np.transpose(lhs, list(lb) + lf + list(lc))
    R = np.transpose(rhs, list(rb) + list(rc) + rf)
    nb = int(np.prod([lhs.shape[d] for d in lb])) if lb else 1
    nl = int(np.prod([lhs.shape[d] for d in lf])) if lf else 1
    nc = int(np.prod([lhs.shape[d] for d in lc])) if lc else 1
    nr = int(np.prod([rhs.shape[d] for d in rf])) if rf else 1
    L = L.reshape(nb, nl, nc)
    R = R.reshape(nb, nc, nr)
    out = np.empty((nb, nl, nr), dtype=object)
    for b in range(nb):
        for p in range(nl):
            for q in range(nr):
                out[b, p, q] = graph.dot(L[b, p], R[b, :, q])
    shape = [lhs.shape[d] for d in lb] + [lhs.shape[d] for d in lf] + [rhs.shape[d] for d in rf]
    return [out.reshape(shape)]


def _np_dot_general(lhs, rhs, lc, rc, lb, rb):
    letters = "abcdefghijklmnopqrstuvwxyz"
    ls = [letters[d] for d in range(lhs.ndim)]
    rs = [letters[lhs.ndim + d] for d in range(rhs.ndim)]
    for a, b in zip(lc, rc):
        rs[b] = ls[a]
    for a, b in zip(lb, rb):
        rs[b] = ls[a]
    lf = [ls[d] for d in range(lhs.ndim) if d not in lc and d not in lb]
    rf = [rs[d] for d in range(rhs.ndim) if d not in rc and d not in rb]
    out = "".join([ls[d] for d in lb] + lf + rf)
    return np.einsum(f"{''.join(ls)},{''.join(rs)}->{out}", lhs, rhs)


def _split(graph, i, eqn, ins):
    sizes, axis = eqn.params["sizes"], eqn.params["axis"]
    cuts = np.cumsum(sizes)[:-1]
    return list(np.split(np.asarray(ins[0]), cuts, axis=axis))


def _cumsum(graph, i, eqn, ins):
    a = ins[0]
    axis, reverse = eqn.params["axis"], eqn.params.get("reverse", False)
    if not is_symbolic(a):
        a = np.asarray(a)
        return [np.flip(np.cumsum(np.flip(a, axis), axis), axis) if reverse else np.cumsum(a, axis)]
    a = np.moveaxis(a, axis, -1)
    out = np.empty(a.shape, dtype=object)
    for idx in np.ndindex(a.shape[:-1]):
        row = a[idx]
        order = range(len(row) - 1, -1, -1) if reverse else range(len(row))
        acc = graph.zero
        for k in order:
            acc = graph.add(acc, row[k])
            out[idx + (k,)] = acc
    return [np.moveaxis(out, -1, axis)]


#: primitive -> rule, for the table of :mod:`.graph_rules`.
STRUCTURAL = {
    "slice": _slice, "squeeze": _squeeze, "reshape": _reshape, "expand_dims": _expand_dims,
    "broadcast_in_dim": _broadcast_in_dim, "concatenate": _concatenate, "stack": _stack,
    "transpose": _transpose, "rev": _rev, "tile": _tile, "copy": _identity, "copy_p": _identity,
    "reduce_precision": _identity, "iota": _iota, "pad": _pad,
    "dynamic_slice": _dynamic_slice, "dynamic_update_slice": _dynamic_update_slice,
    "gather": _gather, "scatter": _scatter(False), "scatter-add": _scatter(True),
    "scatter_add": _scatter(True),
    "reduce_sum": _reduce("add"), "reduce_max": _reduce("max"), "reduce_min": _reduce("min"),
    "reduce_prod": _reduce("mul"), "reduce_and": _reduce("and"), "reduce_or": _reduce("or"),
    "dot_general": _dot_general, "split": _split, "cumsum": _cumsum,
}


__all__ = ["STRUCTURAL"]
