"""Sample passes that keep a GPU render the same bytes run to run.

On a ``cuda_*`` variant Mitsuba's film adds a pixel's samples with atomic float adds, after Dr.Jit has summed
each 32-lane warp's share.  A pixel whose samples span three or more warps gets three or more atomic adds, in an
order the hardware picks, and float addition is not associative.  So its value can differ in the last bits
from run to run. With at most two adds into a zeroed pixel it cannot, because a + b = b + a.  Seen on an H200
(docs/gpu.md): of the main job's 549 files, the 64-spp boards were identical twice over and every image with
1,024-spp shading differed.

So on a cuda variant a render of more than 64 spp is made of passes whose samples of one pixel span at most two
warps, each with its own seed, averaged in float64 in a fixed order.  A spec's spp are powers of two (of four
for multijitter and stratified), so from 64 up they split exactly into passes of 64 = 8 x 8.  The cost: a
stratified sampler stratifies each pass on its own, so on the study's 1,024-spp shading grids the variance
grows 2-3.5x (relative noise 4.3e-5 -> 8.6e-5 on the board, measured on llvm with the split forced), still
far below the sensor's noise (docs/gpu.md).  The orthogonal sampler rounds 64 up to 11^2 and is not
bit-reproducible anyway, so it keeps one pass.  The ``llvm_*`` and ``scalar_*`` variants sum a pixel's samples
in one thread and render in one pass, as before: their bytes, and the shipped results, are unchanged.
"""
from __future__ import annotations

import hashlib
from typing import Callable

import numpy as np

#: lanes per CUDA warp: Dr.Jit reduces a scatter-add within a warp before its atomic
WARP_LANES = 32
#: most samples per pixel in one pass: two warps, aligned, since a pixel's samples are consecutive lanes
MAX_PASS_SPP = 2 * WARP_LANES


def warps_spanned(spp: int) -> int:
    """The most warps the ``spp`` consecutive samples of one pixel touch (sample i of pixel p is lane p·spp + i)."""
    spp = int(spp)
    if spp <= 0:
        return 0
    starts = (np.arange(WARP_LANES, dtype=np.int64) * spp)  # the start's offset in a warp repeats within 32 pixels
    first = starts % WARP_LANES
    return int(((first + spp - 1) // WARP_LANES + 1).max())


def splits(variant: str, sampler: str = "") -> bool:
    """Whether renders on ``variant`` with ``sampler`` are split into passes: a cuda variant, any sampler but the
    orthogonal one."""
    return variant.startswith("cuda") and sampler != "orthogonal"


def pass_spps(spp: int, variant: str, sampler: str = "") -> list[int]:
    """``spp`` split into passes: one where nothing ``splits``; else passes of ``MAX_PASS_SPP`` and the rest, each
    spanning at most two warps per pixel (one pass where ``spp`` already does)."""
    spp = int(spp)
    if not splits(variant, sampler) or warps_spanned(spp) <= 2:
        return [spp]
    full, rest = divmod(spp, MAX_PASS_SPP)
    out = [MAX_PASS_SPP] * full
    if rest and warps_spanned(rest) > 2:
        out += [WARP_LANES, rest - WARP_LANES]  # rest - 32 < 32: within two warps
    elif rest:
        out.append(rest)
    return out


def pass_seed(seed: int, k: int) -> int:
    """The seed of pass ``k`` of a render seeded ``seed`` (a 31-bit integer, as Mitsuba's samplers take)."""
    digest = hashlib.sha256(f"edgetruth/sample-pass/{int(seed)}/{int(k)}".encode()).digest()
    return int.from_bytes(digest[:4], "little") & 0x7FFFFFFF


def render_in_passes(render_once: Callable[[int, int], np.ndarray], seed: int, spp: int, variant: str,
                     sampler: str = "") -> np.ndarray:
    """``render_once(seed, spp)`` (a pixel-mean image) at ``spp`` in all: called once with (seed, spp) where one
    pass does, else once per pass with ``pass_seed(seed, k)``, the passes weighted by their spp and summed in
    float64 in pass order.  Returns float32, as the film does."""
    passes = pass_spps(spp, variant, sampler)
    if len(passes) == 1:
        return np.asarray(render_once(int(seed), int(spp)), dtype=np.float32)
    acc = None
    for k, n in enumerate(passes):
        part = np.asarray(render_once(pass_seed(seed, k), n), dtype=np.float64) * n
        acc = part if acc is None else acc + part
    return (acc / float(sum(passes))).astype(np.float32)


def sample_passes_note(variant: str, sampler: str) -> dict:
    """The JSON's ``render.sample_passes`` where renders are split (a cuda variant, not the orthogonal sampler); empty
    elsewhere, so a CPU image's JSON is as before."""
    if not splits(variant, sampler):
        return {}
    return {"sample_passes": f"renders whose samples of a pixel span more than two {WARP_LANES}-lane warps (above "
                             f"{MAX_PASS_SPP} spp) as passes of at most {MAX_PASS_SPP}, each with its own seed, "
                             "averaged in float64 (the GPU film's atomic adds are then in one order; a stratified "
                             "sampler stratifies each pass alone): render/scene/sample_passes.py"}
