"""CPU binding of the batch's worker processes (a Dask cluster's workers bind themselves:
:func:`uio_jax._filter.cluster.claim_one_cpu`)."""

import os


def pin_to_one_cpu(slot):
    """Bind this process to one CPU of those allowed (slot ``k`` -> the k-th, cyclically),
    before JAX starts its thread pool, so that it sizes the pool to that one CPU.

    Unpinned, every worker's XLA runs its large operations on a pool as wide as the machine
    and ``jobs`` workers oversubscribe the cores. A single worker (``slot`` None) keeps every
    CPU; where the platform cannot pin (no ``os.sched_setaffinity``), nothing happens.
    """
    if slot is None or not hasattr(os, "sched_setaffinity"):
        return
    try:
        cpus = sorted(os.sched_getaffinity(0))
        os.sched_setaffinity(0, {cpus[slot % len(cpus)]})
    except OSError:  # pragma: no cover - a container that forbids it: run unpinned
        pass

