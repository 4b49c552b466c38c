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
Cabibihan et al. Eq. 2), ``neo_hookean``, ``mooney_rivlin``, ``yeoh``, ``ogden`` (decoupled
Ogden, :mod:`sim.materials._ogden`).  The invariant laws and the Ogden law are
decoupled (``law.decoupled``): ``law.evaluate_split(C)`` etc. give the isochoric and volumetric
parts apart (a leading axis of length 2, ``[iso, vol]``).

3D (for the 3D fingertip; :mod:`sim.materials._law3`): every law also has ``evaluate3(C)`` with
``C`` shape ``(6, *batch)`` = ``[C11, C22, C33, C12, C23, C13]``, ``S`` in the same order and
``D`` shape ``(6, 6, *batch)`` (engineering shear, ``dE = [dE11, dE22, dE33, 2 dE12, 2 dE23,
2 dE13]``), ``stress3``, ``stress_tangent3`` and, for the decoupled laws, ``evaluate3_split``,
``stress3_split``, ``stress_tangent3_split``.  The same parameters and energies: with ``C33 = 1``,
``C23 = C13 = 0`` they reduce to the plane-strain methods.  The Ogden-type laws (``ogden``,
``hyperfoam``) use the spectral tangent with closed-form divided differences, exact and
continuous at equal eigenvalues.

A ``Material`` couples a law with a ``Prony`` series: shear coefficients ``prony_g``, relaxation
times ``prony_tau_s`` and optional bulk coefficients ``prony_k`` (Abaqus' ``g_i``, ``k_i``,
sharing ``tau_i``).  Without ``prony_k`` an invariant law relaxes its shear only (``k_i = 0``:
the bulk response of a nearly incompressible solid stays elastic) and the hyperfoam relaxes its
whole stress (``k_i = g_i``, the paper's convention; a hyperfoam with ``k != g`` is refused, as in
Abaqus, its shear and bulk being coupled).  By default (``moduli = "long_term"``) the law's moduli
are the relaxed ones: ``Material.instantaneous`` (shear moduli / ``g_inf``, bulk modulus /
``k_inf``) is the law to evaluate for ``S0``/``D0``, and ``Material.relax`` turns them into the
viscoelastic stress and the tangent factor (``Material.tangent``); the assembly goes through those
``Material`` methods, which keep ``S0`` and the history split when ``k != g``.

Calibrating a material from test data (``fingertip fit-material``) is :mod:`sim.materials.fit`,
imported on its own: a simulation never loads it.
"""

from sim.materials._catalogue import (
    CATALOGUE,
    CATALOGUE_PATH,
    UserCatalogue,
    catalogue_from_tables,
    catalogue_material,
    load_catalogue,
    load_user_catalogues,
    material_from_spec,
    material_tables,
    merge_catalogues,
    read_user_catalogue,
    user_materials,
)
from sim.materials._hyperfoam import Hyperfoam
from sim.materials._invariant import MooneyRivlin, NeoHookean, Yeoh
from sim.materials._law import Law
from sim.materials._material import LAWS, MODULI, Material, default_prony_k
from sim.materials._ogden import Ogden
from sim.materials._prony import (
    MAX_PRONY_TERMS,
    Prony,
    prony_stress,
    prony_stress_split,
    prony_update,
    prony_update_split,
)

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
    "Ogden",
    "Prony",
    "UserCatalogue",
    "Yeoh",
    "catalogue_from_tables",
    "catalogue_material",
    "default_prony_k",
    "load_catalogue",
    "load_user_catalogues",
    "material_from_spec",
    "material_tables",
    "merge_catalogues",
    "prony_stress",
    "prony_stress_split",
    "prony_update",
    "prony_update_split",
    "read_user_catalogue",
    "user_materials",
]
