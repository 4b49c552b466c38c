"""Constitutive laws: compressible hyperelasticity + Prony-series viscoelasticity.

Plane strain, total Lagrangian (``C33 = 1``); units MPa, mm, s.  Every law evaluates, fully
vectorised over a batch of points (e.g. ``(n_elements, n_quadrature_points)``):

* ``law.evaluate(C) -> (W, S, D)`` with ``C`` shape ``(3, *batch)`` = ``[C11, C22, C12]``,
  ``W`` (MPa) shape ``batch``, ``S = 2 dW/dC`` = ``[S11, S22, S12]`` (MPa) shape
  ``(3, *batch)``, ``D = 4 d2W/dCdC`` (MPa) shape ``(3, 3, *batch)`` in Voigt form with
  engineering shear (``dS_i = D_ij dE_j``, ``dE = [dE11, dE22, 2 dE12]``), symmetric;
* ``law.stress_tangent(C) -> (S, D)`` (no energy: what a Newton iteration needs);
* ``law.stress(C) -> S`` (no tangent) and ``law.S33(C)`` (out-of-plane 2nd PK stress, MPa;
  Cauchy ``sigma33 = S33 / J``).

Laws (``LAWS``, keyed by the design-file ``model``): ``hyperfoam`` (Abaqus hyperfoam, the law of
Cabibihan et al. Eq. 2), ``neo_hookean``, ``mooney_rivlin``, ``yeoh``.  A ``Material`` couples a
law with a ``Prony`` series; by default (``moduli = "long_term"``) the law's moduli are the
relaxed ones and ``Material.instantaneous`` is the law to evaluate for ``S0``/``D0``, which
``Prony.update`` turns into the viscoelastic stress and the tangent factor.
"""

from sim.materials._catalogue import (
    CATALOGUE,
    CATALOGUE_PATH,
    catalogue_material,
    load_catalogue,
    material_from_spec,
)
from sim.materials._hyperfoam import Hyperfoam
from sim.materials._invariant import MooneyRivlin, NeoHookean, Yeoh
from sim.materials._law import Law
from sim.materials._material import LAWS, MODULI, Material
from sim.materials._prony import MAX_PRONY_TERMS, Prony, prony_update

__all__ = [
    "CATALOGUE",
    "CATALOGUE_PATH",
    "LAWS",
    "MAX_PRONY_TERMS",
    "MODULI",
    "Hyperfoam",
    "Law",
    "Material",
    "MooneyRivlin",
    "NeoHookean",
    "Prony",
    "Yeoh",
    "catalogue_material",
    "load_catalogue",
    "material_from_spec",
    "prony_update",
]
