"""numpy's pairwise summation in numba kernels, bit for bit: ``block_sum``, the sum numpy's ``add.reduce``
gives over one block of at most 128 (``BLOCK``: numpy's ``PW_BLOCKSIZE``) contiguous float64 values, eight
running sums then the rest in order.  Longer sums halve (at a multiple of 8) down to blocks: the patch fit's
costs (``locate.methods.patch_esf_fit``) and the ranging's line fits (``evaluate.ranging.line_kernels``) build
on it, so their kernels answer as their numpy references do, to the last bit."""
from __future__ import annotations

from edgetruth.jit import njit

BLOCK = 128  # numpy's PW_BLOCKSIZE


@njit(cache=True, forceinline=True)
def block_sum(a, lo, n):
    """numpy's pairwise sum of ``a[lo:lo + n]`` for n <= ``BLOCK``: 8 accumulators, then the rest in order
    (below 8 values, one)."""
    if n < 8:
        res = -0.0
        for i in range(lo, lo + n):
            res += a[i]
        return res
    r0, r1, r2, r3 = a[lo], a[lo + 1], a[lo + 2], a[lo + 3]
    r4, r5, r6, r7 = a[lo + 4], a[lo + 5], a[lo + 6], a[lo + 7]
    i = 8
    while i < n - n % 8:
        r0 += a[lo + i]
        r1 += a[lo + i + 1]
        r2 += a[lo + i + 2]
        r3 += a[lo + i + 3]
        r4 += a[lo + i + 4]
        r5 += a[lo + i + 5]
        r6 += a[lo + i + 6]
        r7 += a[lo + i + 7]
        i += 8
    res = ((r0 + r1) + (r2 + r3)) + ((r4 + r5) + (r6 + r7))
    while i < n:
        res += a[lo + i]
        i += 1
    return res
