"""How the lineage's batched solvers split ``n`` independent problems into blocks, each with its
own work buffers (one set per problem would take ``n`` times the memory: ``n p^2`` doubles for
the lasso's Cholesky factors, 350 MB at ASLA's 5400 problems of 90 atoms).

A block is solved problem after problem by one thread of a ``prange`` over blocks, and each
problem starts from scratch, so the result depends on neither the blocks nor the thread count.
"""
from __future__ import annotations

#: The most blocks, hence sets of work buffers, one call allocates.
MAX_BLOCKS = 64


def problem_blocks(n: int) -> tuple[int, int]:
    """``(n_blocks, block_size)`` for ``n >= 1`` problems: at most :data:`MAX_BLOCKS` blocks of
    ``block_size`` consecutive problems (the last may be shorter), none empty."""
    block_size = -(-n // min(n, MAX_BLOCKS))
    return -(-n // block_size), block_size
