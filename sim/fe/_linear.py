"""Sparse direct solvers of the Newton systems, by name, behind one small interface.

The tangent's sparsity pattern never changes during a simulation, so each solver does its
symbolic analysis (ordering) once and then only numeric factorisations: ``factor(upper)``
with the upper triangle (CSC, the pattern of ``Discretization.upper_matrix``) the first time,
``refactor(values)`` with new values of the same entries after that (or ``refactor(data,
index)``: the values ``data[index]``, gathered once into the solver's own order), ``solve(b)``.

* ``qdldl``: LDL^T with AMD ordering (OSQP's QDLDL, a dependency): the fastest on the 2D
  systems (a few thousand dofs), where supernodes do not pay.
* ``pardiso``: Intel MKL PARDISO, supernodal LDL^T of a real symmetric indefinite matrix
  (``mtype = -2``), through pypardiso (``pip install pypardiso``, which brings MKL): 10-20
  times faster than qdldl on 3D systems of 6 000 dofs and more
  (``python benchmarks/bench_linear_solvers.py``, ``docs/fe_speed.md``).
* ``pardiso-single``: the same in single precision (``PardisoSingle``), for the 3D
  protocols (``sim.simulate.SINGLE_PRECISION_PROTOCOLS``); its ``fallback`` is ``pardiso``.

``default_solver(n)`` picks by the system's size. The FE runs every factorisation on one
thread (the same design gives the same bits whatever the machine's load), so PARDISO is told
to use one thread.
"""

from __future__ import annotations

import sys
from typing import Any, ClassVar

import numpy as np

__all__ = [
    "SOLVERS",
    "LinearSolver",
    "PardisoSingle",
    "SlotView",
    "default_solver",
    "make_solver",
]

#: Systems with more free dofs than this go to PARDISO when it is installed. The 2D tangents
#: (1 700-3 000 dofs) factorise faster in qdldl (1-2 ms against PARDISO's ~5 ms, whose
#: supernodes do not pay at that size); a 3D system of 6 000 dofs already takes qdldl ~0.7 s
#: and PARDISO ~0.05 s (``benchmarks/bench_linear_solvers.py``).
PARDISO_FROM_DOFS = 5000


def _pardiso_iparm() -> np.ndarray:
    """PARDISO's settings (``iparm``, 0-based here, 1-based in Intel's manual: iparm(k) is
    ``[k - 1]``); every entry not named is 0.

    - iparm(1) = 1: these values, not PARDISO's defaults.
    - iparm(2) = 2: nested dissection ordering (METIS). On the pad's tangent (10 622 dofs) its
      factor has 4.4 million entries against minimum degree's (0) 5.4 (PARDISO's own count,
      iparm(18)), and a refactorisation took 81.7 against 122.5 ms (quiet).
    - iparm(10) = 8: pivots below 1e-8 of the matrix's norm are perturbed (the manual's
      default for symmetric indefinite matrices).
    - iparm(18) = -1: PARDISO reports the factor's entries (information only).
    - iparm(21) = 0: 1 x 1 diagonal pivoting. Bunch-Kaufman's 1 x 1 and 2 x 2 pivots (1, the
      default) took 1.7 times as long a refactorisation (136.9 ms on the pad's tangent, 47.5
      against 28.7 ms on the 6 x 6 x 6 Q2 block, quiet); a tangent the
      diagonal pivots cannot factorise accurately shows as a Newton step that does not reduce
      the residual, which Newton's line search and step cuts already handle.

    The figures: ``python benchmarks/bench_linear_solvers.py --systems pad 3d-6 --solvers
    pardiso pardiso-defaults pardiso-md pardiso-bk --repeats 5`` (docs/fe_speed.md)."""
    iparm = np.zeros(64, dtype=np.int32)
    iparm[0], iparm[1], iparm[9], iparm[17], iparm[20] = 1, 2, 8, -1, 0
    return iparm


PARDISO_IPARM = _pardiso_iparm()


class LinearSolver:
    """Factorise once per pattern, then refactorise and solve (see the module docstring).

    A solver with ``slots > 1`` keeps that many numeric factorisations of the one pattern at
    once (one symbolic analysis): ``refactor`` and ``solve`` act on the factorisation in slot
    ``slot`` (1 to ``slots``); set ``slot`` to switch between them."""

    name: ClassVar[str]
    #: the solver to go over to where this one's solves are too inexact for Newton (None: none)
    fallback: ClassVar[str | None] = None
    #: factorisations kept at once (``slot`` 1 to ``slots``)
    slots: int = 1
    slot: int = 1

    def factor(self, upper: Any) -> None:
        raise NotImplementedError

    def refactor(self, values: np.ndarray, index: np.ndarray | None = None) -> None:
        """Factorise new values of the entries of ``factor``'s upper triangle (its CSC order):
        ``values``, or ``values[index]`` (``index``: the triangle's positions in the tangent's
        data, ``Pattern.upper_data``; one gather, where ``np.take(values, index)`` and then
        the solver's own reordering would copy the values twice)."""
        raise NotImplementedError

    def solve(self, b: np.ndarray) -> np.ndarray:
        raise NotImplementedError

    def solve_many(self, B: np.ndarray) -> np.ndarray:
        """``solve`` for every column of ``B`` (n, k)."""
        return np.column_stack([self.solve(b) for b in B.T]) if B.shape[1] else B.copy()

    def view(self, slot: int) -> LinearSolver | SlotView:
        """What solves with the factorisation in ``slot``, whatever ``slot`` is later set to:
        the solver itself where it keeps one factorisation."""
        return self if self.slots == 1 else SlotView(self, slot)

    def slot_memory_MB(self) -> float | None:
        """Memory one more slot's factorisation takes (MB); None: unknown."""
        return None


class SlotView:
    """Solves with the factorisation in slot ``slot`` of ``solver`` (``LinearSolver.view``)."""

    def __init__(self, solver: LinearSolver, slot: int) -> None:
        self.solver = solver
        self.slot = slot
        self.name = solver.name
        self.fallback = solver.fallback

    def solve(self, b: np.ndarray) -> np.ndarray:
        self.solver.slot = self.slot
        return self.solver.solve(b)

    def solve_many(self, B: np.ndarray) -> np.ndarray:
        self.solver.slot = self.slot
        return self.solver.solve_many(B)


class Qdldl(LinearSolver):
    name = "qdldl"

    def __init__(self) -> None:
        self._solver = None
        self._upper = None

    def factor(self, upper: Any) -> None:
        import qdldl  # here: `import sim` stays light

        self._upper = upper.copy()  # ``refactor`` writes its values: not the caller's matrix
        self._solver = qdldl.Solver(self._upper, upper=True)

    def refactor(self, values: np.ndarray, index: np.ndarray | None = None) -> None:
        if index is None:
            np.copyto(self._upper.data, values)
        else:
            np.take(values, index, out=self._upper.data)
        self._solver.update(self._upper, upper=True)

    def solve(self, b: np.ndarray) -> np.ndarray:
        return self._solver.solve(b)


class Pardiso(LinearSolver):
    """MKL PARDISO through pypardiso's ``PyPardisoSolver`` (phases 12, 22, 33).

    ``slots``: PARDISO's ``maxfct``, the numeric factorisations it keeps of the one pattern
    (``mnum`` is ``slot``). A slot's memory is taken at its first factorisation (on the pad's
    tangent in single precision about 20 MB: ``slot_memory_MB``). Each slot keeps its
    own matrix values too: PARDISO's iterative refinement of a solve reads them."""

    name = "pardiso"
    #: the precision of the matrix, the factor and the right-hand sides PARDISO is given
    dtype: ClassVar[type] = np.float64

    def __init__(self, slots: int = 1) -> None:
        import os

        from pypardiso import PyPardisoSolver, scipy_aliases

        # pypardiso's import already found MKL (a recursive search of the environment, some
        # 0.3 s): a new solver is told where instead of searching again
        found = getattr(getattr(scipy_aliases.pypardiso_solver, "libmkl", None), "_name", None)
        if found and "PYPARDISO_MKL_RT" not in os.environ:
            os.environ["PYPARDISO_MKL_RT"] = found
        self._ps = PyPardisoSolver(mtype=-2)  # real symmetric indefinite
        self._ps.iparm[:] = PARDISO_IPARM
        self._ps.iparm[27] = int(self.dtype == np.float32)  # iparm(28): single precision
        _one_thread(self._ps)
        self._csr = None
        self.slots = slots
        self.slot = 1
        self._values: dict[int, np.ndarray] = {}  # per slot, the CSR values in ``dtype``
        self._composed_from: np.ndarray | None = None  # the ``index`` of ``_composed_order``
        self._composed_order = np.zeros(0, dtype=np.int64)

    def factor(self, upper: Any) -> None:
        # the upper triangle as CSR is what PARDISO reads for a symmetric matrix: the CSC upper
        # triangle's transpose, i.e. the lower triangle in CSC read as CSR
        csr = upper.tocsr()
        csr.sort_indices()
        self._order = _csr_order(upper)  # CSC values -> CSR values
        self._composed_from = None
        self._csr = csr
        self._values = {self.slot: csr.data.astype(self.dtype)}
        self._ps._check_A(csr)
        # PARDISO's 1-based index arrays, made once (pypardiso makes them again at every call)
        self._ia = (csr.indptr.astype(np.int32) + 1, csr.indices.astype(np.int32) + 1)
        self._call(12, np.zeros((csr.shape[0], 1), dtype=self.dtype))
        # one factorisation's memory (kB): iparm(17) grows with each slot factorised
        self._factor_kB = int(self._ps.iparm[16])

    def refactor(self, values: np.ndarray, index: np.ndarray | None = None) -> None:
        if self.slot not in self._values:
            self._values[self.slot] = np.zeros(len(self._order), dtype=self.dtype)
        order = self._order if index is None else self._composed(index)
        # cast to ``dtype``: in single precision an entry beyond float32's range (a pursued
        # Newton iterate far from the solution, which stiffens a crushed element without bound)
        # becomes inf, silently: Newton judges the direction by its line search as always, and
        # a failed attempt is retried in double precision, since this factorisation then
        # solves its own tangent badly (``Body.last_factor_residual``, ``Body._retry``)
        with np.errstate(over="ignore"):
            np.take(values, order, out=self._values[self.slot])
        self._call(22, np.zeros((self._csr.shape[0], 1), dtype=self.dtype))

    def _composed(self, index: np.ndarray) -> np.ndarray:
        """``index[_order]``: the tangent's data positions in PARDISO's CSR order, composed
        once per ``index`` (a body's discretisation hands the same array every time)."""
        if self._composed_from is not index:
            self._composed_order = index[self._order]
            self._composed_from = index
        return self._composed_order

    def solve(self, b: np.ndarray) -> np.ndarray:
        rhs = np.ascontiguousarray(b, dtype=self.dtype).reshape(-1, 1)
        return self._call(33, rhs).ravel().astype(float, copy=False)

    def solve_many(self, B: np.ndarray) -> np.ndarray:
        # PARDISO takes the right-hand sides column by column (Fortran order), all in one call
        return self._call(33, np.asfortranarray(B, dtype=self.dtype)).astype(float, copy=False)

    def _call(self, phase: int, b: np.ndarray) -> np.ndarray:
        """PARDISO's one entry point, as ``PyPardisoSolver._call_pardiso`` calls it, with the
        index arrays kept (``factor``); ``b`` (n, k) in Fortran order."""
        import ctypes

        from pypardiso.pardiso_wrapper import PyPardisoError

        ps, n = self._ps, self._csr.shape[0]
        ps.set_phase(phase)
        x = np.zeros_like(b)
        error = ctypes.c_int32(0)
        i32 = ctypes.POINTER(ctypes.c_int32)
        real = ctypes.POINTER(ctypes.c_float if self.dtype == np.float32 else ctypes.c_double)
        assert b.dtype == self.dtype  # PARDISO reads the arrays' bytes in its own precision
        if not 1 <= self.slot <= self.slots:
            raise ValueError(f"PARDISO slot {self.slot} outside 1..{self.slots}")
        ps._mkl_pardiso(
            ps.pt.ctypes.data_as(ctypes.POINTER(ps._pt_type[0])),
            ctypes.byref(ctypes.c_int32(self.slots)),  # maxfct
            ctypes.byref(ctypes.c_int32(self.slot)),  # mnum
            ctypes.byref(ctypes.c_int32(ps.mtype)),
            ctypes.byref(ctypes.c_int32(phase)),
            ctypes.byref(ctypes.c_int32(n)),
            self._values[self.slot].ctypes.data_as(real),
            self._ia[0].ctypes.data_as(i32),
            self._ia[1].ctypes.data_as(i32),
            ps.perm.ctypes.data_as(i32),
            ctypes.byref(ctypes.c_int32(b.shape[1])),  # right-hand sides
            ps.iparm.ctypes.data_as(i32),
            ctypes.byref(ctypes.c_int32(ps.msglvl)),
            b.ctypes.data_as(real),
            x.ctypes.data_as(real),
            ctypes.byref(error),
        )
        if error.value != 0:
            raise PyPardisoError(error.value)
        return x

    def slot_memory_MB(self) -> float | None:
        """PARDISO's count of its first numeric factorisation's memory (iparm(17), kB, which
        then grows with each slot factorised) and the slot's own values: on the pad's tangent
        in single precision each slot after the first took 20 MB of resident memory,
        iparm(17) 21 MB (``python studies/tap_factors.py --memory``)."""
        kb = getattr(self, "_factor_kB", 0)
        if kb <= 0:
            return None
        return kb / 1024.0 + self._csr.nnz * np.dtype(self.dtype).itemsize / 2**20

    def __del__(self) -> None:
        ps = getattr(self, "_ps", None)
        if ps is None or sys.meta_path is None:  # at interpreter exit MKL frees it anyway
            return
        try:
            ps.free_memory(everything=True)
        except Exception:  # modules half torn down at exit: nothing left to free
            pass


class PardisoSingle(Pardiso):
    """PARDISO in single precision (iparm(28) = 1: the matrix, its factor and the solves in
    float32; the Newton solver hands over and gets back float64).

    Newton needs a direction, not an exact solve: the residual and the tangent stay in double,
    and the iteration stops on the double residual, so a factor good to about 1e-6 (float32's
    epsilon 6e-8 times the tangent's conditioning) changes Newton's path, not its answer.
    Half the factor's bytes: on the pad's tangent (10 622 dofs) a refactorisation took 50.3
    against 84.2 ms, a solve 1.1 against 3.3 ms, the relative residual 7.9e-6 against 2.3e-14
    (quiet: ``python benchmarks/bench_linear_solvers.py --systems pad --solvers pardiso
    pardiso-single --repeats 5``). A step Newton fails with it is tried again from a fresh
    factorisation, in double precision (``fallback``) where this one's last factorisation
    solved its tangent worse than ``sim.fe.solver.INEXACT_SOLVE_RTOL``, and the body goes
    back to this solver at the next step that converges (``Body.advance``)."""

    name = "pardiso-single"
    dtype = np.float32
    #: the solver a body goes over to where this one's solves are too inexact for Newton
    fallback: ClassVar[str] = "pardiso"


def _csr_order(upper: Any) -> np.ndarray:
    """Permutation taking the CSC values of ``upper`` to its CSR (sorted) values."""
    n = upper.shape[0]
    col = np.repeat(np.arange(n), np.diff(upper.indptr))
    row = upper.indices
    return np.lexsort((col, row))


def _one_thread(ps: Any) -> None:
    """PARDISO on one thread (MKL's own setting; the FE's BLAS is limited the same way)."""
    lib = getattr(ps, "libmkl", None)
    if lib is not None and hasattr(lib, "MKL_Set_Num_Threads"):
        import ctypes

        lib.MKL_Set_Num_Threads(ctypes.c_int(1))  # the C interface: the count by value


SOLVERS: dict[str, type[LinearSolver]] = {cls.name: cls for cls in (Qdldl, Pardiso, PardisoSingle)}


def pardiso_available() -> bool:
    try:
        import pypardiso  # noqa: F401
    except ImportError:
        return False
    return True


def default_solver(n_free: int, dim: int = 2, single_precision: bool = False) -> str:
    """The solver for a system of ``n_free`` dofs of a ``dim``-dimensional mesh: PARDISO (if
    installed) for every 3D system (a Q2 hexahedron couples 81 dofs: the fill-in grows so fast
    that qdldl took 0.37 s a factorisation at 4 400 dofs, PARDISO 0.04 s: the plate press of
    ``homogeneous_design("silicone_gls40")`` on ``COARSE_MESH_3D``, 42 factorisations each,
    beside another job) and
    for 2D systems beyond ``PARDISO_FROM_DOFS``; in single precision (``PardisoSingle``) where
    ``single_precision`` asks for it."""
    if (dim == 3 or n_free > PARDISO_FROM_DOFS) and pardiso_available():
        return "pardiso-single" if single_precision else "pardiso"
    return "qdldl"


def make_solver(name: str, slots: int = 1) -> LinearSolver:
    """The solver ``name``; ``slots`` factorisations kept at once where it can keep several
    (PARDISO), else one."""
    if name not in SOLVERS:
        raise ValueError(f"unknown linear solver {name!r}; known: {', '.join(SOLVERS)}")
    cls = SOLVERS[name]
    return cls(slots) if issubclass(cls, Pardiso) else cls()
