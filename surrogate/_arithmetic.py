"""The same arithmetic on every x86-64 CPU with AVX2: torch's kernels and its MKL held to AVX2
(:func:`pin_arithmetic`), set when this package is imported, before it first uses torch.

Left to themselves, ATen (torch's element-wise operators and reductions) and the MKL inside
torch (its matrix products) pick their kernels by CPU, AVX2 or AVX-512, each summing in its own
order, and a retraining turns those last bits into another surrogate. On this project's AVX-512
host, the main job's retraining (150 epochs from the shipped checkpoint, 14 sweep designs in the
place of confirmed ones) with MKL held to AVX2 instructions (``MKL_ENABLE_INSTRUCTIONS=AVX2``,
what an AVX2 CPU runs) predicted the tapping metrics 0.15-0.6 % (median over 32 768 designs)
away from the same retraining on AVX-512: as far as the surrogate's own median error, so the
next round searched elsewhere (issue 31); with MKL held, the retraining after a short main
job's first round (2 designs) gave other weights with ATen held to AVX2
(``ATEN_CPU_CAPABILITY=avx2``). With both held to AVX2 (``MKL_CBWR``: MKL's Conditional
Numerical Reproducibility branch, ``MKL_BRANCH``) the host retrained and predicted bit for bit
as with AVX2 instructions only (tests/test_reproducible.py), and two runs of that short job
(2 rounds; one with numpy, OpenBLAS and MKL on their AVX2 paths) retrained the same surrogate
and chose the same designs, where they had not before.
"""

from __future__ import annotations

import os

__all__ = ["ATEN_CAPABILITY", "MKL_BRANCH", "has_avx2", "pin_arithmetic"]

#: AVX2: the widest instruction set every x86-64 CPU of the last decade has (Intel Core since
#: Haswell, 2013; AMD since Excavator, 2015); a wider one (AVX-512) would differ on those CPUs,
#: a narrower one slows every CPU. STRICT: MKL's products give a row the same bits whatever
#: the rows beside it (and the threads), which its AVX2 kernels do not otherwise: with plain
#: ``AVX2``, as on an AVX2 CPU, a design's prediction depended on its batch
#: (``ROWS_MULTIPLE``, tests/test_fast_predict.py). MKL's name of the branch, ATen's of its
#: kernels.
MKL_BRANCH = "AVX2,STRICT"
ATEN_CAPABILITY = "avx2"


def has_avx2() -> bool:
    """Whether this CPU runs AVX2 (numpy's detection of it: this package does not import torch
    before it needs it); False where numpy does not say (another architecture)."""
    try:
        from numpy._core._multiarray_umath import __cpu_features__
    except ImportError:  # numpy 1.x
        try:
            from numpy.core._multiarray_umath import __cpu_features__
        except ImportError:
            return False
    return bool(__cpu_features__.get("AVX2", False))


def pin_arithmetic() -> bool:
    """Hold ATen and MKL to AVX2 (``ATEN_CPU_CAPABILITY``, ``MKL_CBWR``) on a CPU that has it;
    returns whether it did. A value set before (the environment) is kept. torch reads them at
    its first operator and first matrix product in the process: code that used torch before
    importing this package runs on torch's own choice. A CPU without AVX2 (an old or a small
    x86-64 one, ARM) is left alone: ATen held to AVX2 would stop it with an illegal
    instruction, and ARM has neither MKL nor AVX2."""
    if not has_avx2():
        return False
    os.environ.setdefault("MKL_CBWR", MKL_BRANCH)
    os.environ.setdefault("ATEN_CPU_CAPABILITY", ATEN_CAPABILITY)
    return True
