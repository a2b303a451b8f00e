"""Names of derived coordinates: the derivatives of an input, kept apart from the states."""


def derivative_names(inputs, count: int, taken, *, order_major: bool = False) -> tuple[str, ...]:
    """Names of the derivatives ``w^(d)``, ``d = 0..count - 1``, of each input ``w``.

    Order 0 keeps the input's name, order ``d`` gets ``^(d)``; a name already taken (a
    state, or one given earlier in this list) gets a ``'`` appended until it is free.

    Args:
        inputs: the input names, in order.
        count: orders per input (``d = 0..count - 1``).
        taken: names the new ones must avoid (the states).
        order_major: list order by order (``[w_1, w_2, w_1^(1), w_2^(1), ...]``, the
            EORC's extended state, 004 eq. 4) instead of input by input
            (``[u^(0..R), v^(0..R)]``, the jets of smooth known inputs).

    Returns:
        ``len(inputs) * count`` names.
    """
    taken = set(taken)
    pairs = ([(d, w) for d in range(count) for w in inputs] if order_major
             else [(d, w) for w in inputs for d in range(count)])
    out = []
    for d, w in pairs:
        name = w if d == 0 else f"{w}^({d})"
        while name in taken:
            name += "'"
        taken.add(name)
        out.append(name)
    return tuple(out)


__all__ = ["derivative_names"]
