"""Validity of an FE result: how far a design was deformed, against the range the model covers.

The materials of the paper were characterised in uniaxial compression to 45 % nominal strain
(§2.2.2), and the model was validated at nominal strains of about 20 % of the skin thickness
(§5.1). A design can be squashed far beyond that and the solver still converges: the result is
then an extrapolation of the fitted laws, or of the mesh. ``DeformationTracker`` records, at every
committed step a protocol records, the extremes that say how far the model was taken:

- the largest compressive principal logarithmic strain at the quadrature points, -ln(lambda_min),
  from the in-plane principal stretches of F and the plane-strain F33 = 1 (so it is >= 0);
- the smallest volume ratio J = det F at the quadrature points;
- whether the free outer surface touched the rigid base beside the bone;
- whether the outer surface folded (``surface_folded``);

and, once at the protocol's peak load, the width of the contact with the indenter. Each layer is
held to the compressive log strain its own material was tested to (``layer_limit``: the
catalogue's and the families' entries of ``sim/data/material_tests.toml``, a fitted material's
provenance; the paper's 0.60 for a material with no tested range), unless
``ValidityOptions.max_compressive_log_strain`` overrides every layer's (``strain_limits``).
``check`` compares a summary with those limits, the other thresholds of ``ValidityOptions`` and
each layer's Drucker-stable strain when its material's fit has one
(``Material.drucker_limit_log_strain``); ``assess`` words the violations.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

if TYPE_CHECKING:
    from ..fe import Body, Discretization
    from ..materials import Material

__all__ = [
    "BASIS_WORDS",
    "LAYER_LIMIT_KEYS",
    "LAYER_STRAINS",
    "PAPER_LOG_STRAIN",
    "DeformationTracker",
    "LayerLimit",
    "StrainLimit",
    "ValidityOptions",
    "ValidityStop",
    "Violation",
    "assess",
    "binding_strain_limit",
    "check",
    "compressive_log_strain",
    "contact_half_width_mm",
    "design_strain_limit",
    "layer_limit",
    "polyline_self_intersects",
    "strain_limits",
    "strain_summary",
    "surface_folded",
    "volume_ratio",
]

#: The compressive log strain of the paper's compression tests: its materials were characterised
#: in uniaxial compression to 45 % nominal strain (§2.2.2: 10 mm samples to 5.5 mm), a stretch of
#: 0.55 and a log strain of ln(1 / 0.55) = 0.598, rounded. The limit of a layer whose material
#: has no tested range (an inline law without a provenance that records one), and of every layer
#: of a result recorded before the layers had their own (a summary without
#: ``tested_log_strain_by_layer``: the limit it was made with).
PAPER_LOG_STRAIN = 0.60


@dataclass(frozen=True)
class ValidityOptions:
    """Limits of the range in which the model's results are trusted (``--set validity.x=...``)."""

    # The compressive log strain every layer is held to; None (default): each layer to the one
    # its own material was tested to (``layer_limit``: e.g. 0.598 for the paper's materials,
    # tested in compression to 45 %; 1.099 for Dawood's Ecoflex, to 66.7 %; an argued limit for
    # a law fitted in tension only), beyond which its fitted law is extrapolated. A number
    # overrides every layer's, and the result says so. The limit is on the LOCAL strain at the
    # quadrature points, which is what a material test covers, not on the overall compression of
    # the pulp: a human fingertip compresses ~50 % of its pulp at 4 N, so a human-like design
    # must exceed the paper's recommendation of 20 % nominal strain (§5.1, ln(1 / 0.8) = 0.22)
    # overall. That figure is reported as ``nominal_compression`` (indenter travel / body
    # height), for information only.
    max_compressive_log_strain: float | None = None
    # The smallest volume ratio J. The paper identified its laws as incompressible (J = 1) and
    # assumed nu; no test measured a volume change. Applying the strain limit to the volume,
    # ln J >= -0.60 gives J >= 0.55: the volume ratio of a uniaxial compression to 45 % of a
    # material that does not expand sideways at all (nu = 0), the most any 45 % test could have
    # exercised. The materials in the design spaces (nu >= 0.45) lose at most 6 % of their
    # volume in that test (J = 0.55^(1 - 2 nu)), so J < 0.55 is a volumetric compression no test
    # covers, or an element close to collapse (J -> 0) where the mesh, not the law, decides.
    min_J: float = 0.55
    # The free surface resting on the base beside the bone: the pulp's side was squashed down to
    # the bone's plane. The paper's model (§3.1) and the human finger have no such contact (the
    # base stands for the bone, the nail and the tissue between them), so it is out of range.
    allow_base_contact: bool = False
    # A folded surface (see ``surface_folded``) has no meaning for a skin: self-contact is not
    # modelled, so a fold passes through itself. Never valid by default.
    allow_folding: bool = False
    # The protocols the strain limit applies to (comma-separated). Tapping and the plate compress
    # the pulp as a whole, the use the laws were fitted for. The wedge's 0.05 mm tip concentrates
    # strain under itself (0.57-1.2 for the catalogue materials, growing slowly with mesh
    # refinement: the tip is nearly a singularity) over a few hundredths of a mm^2, and that very
    # test is the one the paper validated against experiments (§3.3, Figs. 5a and 6: forces and
    # surface profiles within 10 %). So the wedge's local strain is reported, not held against
    # the design; its J, base contact and folding still are.
    strain_limit_protocols: str = "tapping,plate"
    # A protocol stops at its first recorded step beyond these limits (``ValidityStop``): what
    # it would compute from there on is an extrapolation that no answer may use (a design beyond
    # the limits is never an answer), and on default-space designs 43 % of all factorisations
    # came after such a step (docs/fe_speed.md, "Where the FE time goes"). The stopped
    # protocol has no metrics; its validity summary holds the extremes up to that step, so a
    # limit is judged exactly as on a full run, but the figures beyond it are censored there.
    # ``false`` runs on to the end (the extrapolated numbers, e.g. for --allow-untrusted).
    stop_at_violation: bool = True

    def __post_init__(self) -> None:
        limit = self.max_compressive_log_strain
        if limit is not None and not (
            isinstance(limit, int | float) and not isinstance(limit, bool) and limit > 0
        ):
            raise ValueError(
                "max_compressive_log_strain must be a positive number or None (each layer's "
                f"tested limit), got {limit!r}"
            )

    @property
    def strain_limited(self) -> tuple[str, ...]:
        """The protocols of ``strain_limit_protocols``, parsed (the one place that does)."""
        return tuple(p.strip() for p in self.strain_limit_protocols.split(",") if p.strip())

    @property
    def overridden(self) -> dict[str, float]:
        """The limits that override the materials' own: ``{"max_compressive_log_strain": x}``
        when set, else {} (what a result reports as overridden)."""
        limit = self.max_compressive_log_strain
        return {} if limit is None else {"max_compressive_log_strain": float(limit)}


# ---------------------------------------------------------------------------- layer limits
#: what a limit is, in words (``StrainLimit.basis``): a material's tests, or an option
BASIS_WORDS = {
    "measured": "measured",
    "argued": "argued",
    "untested": "no tested range: the paper's limit",
    "overridden": "overridden",
    "": "",
}


@dataclass(frozen=True)
class LayerLimit:
    """The compressive log strain a layer's material was tested to (``log_strain``), the
    ``material`` it is the limit of (a catalogue or user material's name, ``family.gel``,
    ``family.foam``, or an inline law) and its ``basis``: "measured" (a test compressed the
    material that far), "argued" (none did, or the material is a family: from its tension tests
    or from tests of similar materials, as the entry's note says) or "untested" (no tested range:
    the paper's ``PAPER_LOG_STRAIN``)."""

    log_strain: float
    material: str
    basis: str


def layer_limit(material: Material) -> LayerLimit:
    """THE rule of the compressive limit a layer of ``material`` is held to, from the tests its
    law was fitted to (``sim.materials._tests``), found in this order:

    1. a shipped catalogue material (exactly the catalogue's entry of its name): its entry in
       ``sim/data/material_tests.toml``;
    2. a material whose ``provenance`` records its tested range (``fingertip fit-material``
       writes it; an inline material may state it): that range;
    3. a member of a design-space family (``sim.design.families.family_of``, also when written
       out as an inline table, or a named material whose law is one of the family's): the
       family's entry (``family.gel``, ``family.foam``), whose argument holds for the law's
       form;
    4. anything else (an inline law without such a provenance, the earlier ``param`` family):
       ``PAPER_LOG_STRAIN``, "untested".

    An entry's compressive limit is measured or argued (``TestedRange.compressive_argued``: a
    law fitted in tension only has an argued one, never none)."""
    from ..design.families import family_of
    from ..materials import CATALOGUE
    from ..materials._tests import tested_range, tested_range_from_provenance

    name = material.name
    own = name or f"inline {material.law.model} law"
    found, label = None, own
    if name is not None and CATALOGUE.get(name) == material:
        found = tested_range(name)
    if found is None and material.provenance:
        found = tested_range_from_provenance(
            dict(material.provenance), material.source, "provenance"
        )
    if found is None and (family := family_of(material)) is not None:
        found = tested_range(f"family.{family}")
        label = f"family.{family}" if name is None else f"{name} as family.{family}"
    if found is None or found.max_compressive_log_strain is None:
        return LayerLimit(PAPER_LOG_STRAIN, own, "untested")
    basis = "argued" if found.compressive_argued else "measured"
    return LayerLimit(found.max_compressive_log_strain, label, basis)


def design_strain_limit(materials: Sequence[Material], options: ValidityOptions) -> float:
    """The compressive log strain a design's LARGEST strain is held to when its layers' own
    strains are not known (a surrogate's prediction: it learns the design's largest strain, not
    each layer's): the override when set, else the largest of its layers' limits
    (``layer_limit``). Beyond it every layer would be beyond its own limit, wherever the largest
    strain is, so a design predicted beyond it is not credible; within it the FE's check of each
    layer against its own limit (``strain_limits``) decides."""
    if options.max_compressive_log_strain is not None:
        return float(options.max_compressive_log_strain)
    return max(layer_limit(m).log_strain for m in materials)


@dataclass(frozen=True)
class StrainLimit:
    """The compressive limit one layer of a protocol's result is held to: ``layer`` (outermost
    0; None for a summary without per-layer figures or recorded before the layers had their own
    limits, judged on its largest strain), its ``role`` ("skin", "middle", "core"), the
    ``material`` of the limit (``LayerLimit.material``), its largest compressive log ``strain``,
    the ``limit`` and the limit's ``basis`` (a key of ``BASIS_WORDS``: ``LayerLimit.basis``,
    "overridden", or "" for the paper's limit of an earlier summary)."""

    layer: int | None
    role: str
    material: str
    strain: float
    limit: float
    basis: str

    @property
    def label(self) -> str:
        """``"layer 1 (core, family.gel)"``, as violations name the layer ("" if none)."""
        if self.layer is None:
            return ""
        inside = ", ".join(x for x in (self.role, self.material) if x)
        return f"layer {self.layer} ({inside})" if inside else f"layer {self.layer}"

    @property
    def basis_words(self) -> str:
        """``basis`` in words (``BASIS_WORDS``)."""
        return BASIS_WORDS.get(self.basis, self.basis)


def _roles(n_layers: int) -> tuple[str, ...]:
    from ..design.space import active_roles

    return active_roles(n_layers) if 1 <= n_layers <= 3 else ("",) * n_layers


def strain_limits(summary: dict[str, Any], options: ValidityOptions) -> list[StrainLimit]:
    """THE rule of which compressive limit each layer of a protocol's ``summary`` is held to:
    ``options.max_compressive_log_strain`` when set (an override, every layer), else the
    layer's tested limit the summary records (``tested_log_strain_by_layer``, from
    ``layer_limit``). A summary without per-layer figures (a table row's), or recorded before
    the layers had their own limits, is one entry: its largest strain against the override or
    ``PAPER_LOG_STRAIN``, the limit it was made with."""
    override = options.max_compressive_log_strain
    strains = summary.get("max_compressive_log_strain_by_layer")
    tested = summary.get("tested_log_strain_by_layer")
    if strains is None or (tested is None and override is None):
        limit, basis = (PAPER_LOG_STRAIN, "") if override is None else (override, "overridden")
        return [StrainLimit(None, "", "", summary["max_compressive_log_strain"], limit, basis)]
    roles = _roles(len(strains))
    materials = summary.get("tested_material_by_layer") or [""] * len(strains)
    if override is not None:
        return [
            StrainLimit(k, roles[k], materials[k], strain, float(override), "overridden")
            for k, strain in enumerate(strains)
        ]
    bases = summary.get("tested_basis_by_layer") or [""] * len(strains)
    return [
        StrainLimit(k, roles[k], materials[k], strain, limit, bases[k])
        for k, (strain, limit) in enumerate(zip(strains, tested, strict=True))
    ]


#: the summary's per-layer strains, and the keys of its per-layer tested limits
#: (``DeformationTracker.summary``), which ``SimResult.diagnostics`` carries to stored records
LAYER_STRAINS = "max_compressive_log_strain_by_layer"
LAYER_LIMIT_KEYS = (
    "tested_log_strain_by_layer",
    "tested_material_by_layer",
    "tested_basis_by_layer",
)


def strain_summary(diagnostics: Mapping[str, Any], protocol: str) -> dict[str, Any] | None:
    """The part of a protocol's summary that ``strain_limits`` reads, from the flat diagnostics
    of a stored result (``SimResult.diagnostics``: a record's, a search's confirmation); None
    when the protocol has no strain. A record made before the layers had their own limits (or
    a table row) has no per-layer figures: it is judged on its largest strain."""
    strain = diagnostics.get(f"{protocol}_max_compressive_log_strain")
    if not isinstance(strain, int | float) or isinstance(strain, bool):
        return None
    out: dict[str, Any] = {"max_compressive_log_strain": float(strain)}
    layers = diagnostics.get(f"{protocol}_{LAYER_STRAINS}")
    if isinstance(layers, list | tuple) and layers:
        out[LAYER_STRAINS] = list(layers)
        for key in LAYER_LIMIT_KEYS:
            value = diagnostics.get(key)
            if isinstance(value, list | tuple) and len(value) == len(layers):
                out[key] = list(value)
    return out


def binding_strain_limit(summary: dict[str, Any], options: ValidityOptions) -> StrainLimit | None:
    """The layer nearest its compressive limit, or furthest beyond it (the largest strain /
    limit, ``strain_limits``): the limit that binds the design; None without a strain."""
    limits = strain_limits(summary, options)
    return max(limits, key=lambda s: s.strain / s.limit if s.limit > 0 else math.inf, default=None)


# ---------------------------------------------------------------------------- kinematics
def _smallest_stretch_sq(F: np.ndarray, J: np.ndarray) -> np.ndarray:
    """Smallest eigenvalue of C = F^T F (the smallest principal stretch squared; in 2D the
    in-plane one), given J = det F. In 3D (F: (3, 3, E, Q)) ``C`` in Voigt form by the
    assembly's kernel and its eigenvalues by the spectral laws' compiled Jacobi
    (``sim.materials._law3.eigh3``: backward stable as LAPACK's, in 0.6 of ``eigvalsh``'s time
    on a tapping pad's 20 898 points, whose per-matrix overhead it avoids)."""
    if F.shape[0] == 3:
        from ..fe._kernels import VOIGT, right_cauchy_green  # numba: `import sim` stays light
        from ..materials._law3 import eigh3

        C = right_cauchy_green(np.ascontiguousarray(F), VOIGT[3])  # (6, E, Q)
        return eigh3(C.reshape(6, -1))[0][0].reshape(C.shape[1:])
    c00 = F[0, 0] ** 2 + F[1, 0] ** 2
    c11 = F[0, 1] ** 2 + F[1, 1] ** 2
    c01 = F[0, 0] * F[0, 1] + F[1, 0] * F[1, 1]
    largest = 0.5 * (c00 + c11) + np.hypot(0.5 * (c00 - c11), c01)
    return J * J / largest  # det C / largest: no cancellation when the two are far apart


def compressive_log_strain(F: np.ndarray) -> np.ndarray:
    """-ln(smallest principal stretch) of plane-strain deformation gradients F (2, 2, ...).

    The in-plane principal stretches are the square roots of the eigenvalues of C = F^T F; the
    out-of-plane stretch is 1, so the result is clipped at 0 (no compressive strain).
    """
    return np.maximum(-0.5 * np.log(_smallest_stretch_sq(F, volume_ratio(F))), 0.0)


def volume_ratio(F: np.ndarray) -> np.ndarray:
    """J = det F of deformation gradients F (d, d, ...): plane strain (F33 = 1) or 3D."""
    if F.shape[0] == 3:
        return (
            F[0, 0] * (F[1, 1] * F[2, 2] - F[1, 2] * F[2, 1])
            - F[0, 1] * (F[1, 0] * F[2, 2] - F[1, 2] * F[2, 0])
            + F[0, 2] * (F[1, 0] * F[2, 1] - F[1, 1] * F[2, 0])
        )
    return F[0, 0] * F[1, 1] - F[0, 1] * F[1, 0]


# ---------------------------------------------------------------------------- surface
@functools.lru_cache(maxsize=8)
def _non_adjacent(n_segments: int) -> np.ndarray:
    """(n, n) mask of the segment pairs (i, j), j >= i + 2, of an open polyline."""
    return np.triu(np.ones((n_segments, n_segments), dtype=bool), k=2)


def _orient(a: np.ndarray, b: np.ndarray, c: np.ndarray) -> np.ndarray:
    """Twice the signed area of the triangles (a, b, c), row by row."""
    return (b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0])


def polyline_self_intersects(xy: np.ndarray) -> bool:
    """True if two non-adjacent segments of the open polyline ``xy`` (n, 2) cross properly.

    A proper crossing has each segment's end points strictly on both sides of the other's line
    (touching or collinear overlap is not counted). Pairs whose bounding boxes are apart are
    skipped before the orientation tests.
    """
    n_seg = len(xy) - 1
    if n_seg < 3:
        return False
    lo = np.minimum(xy[:-1], xy[1:])
    hi = np.maximum(xy[:-1], xy[1:])
    near = _non_adjacent(n_seg).copy()
    for c in (0, 1):  # overlapping bounding boxes, as (n, n) masks: cheaper than index pairs
        near &= lo[:, None, c] <= hi[None, :, c]
        near &= lo[None, :, c] <= hi[:, None, c]
    i, j = np.nonzero(near)
    if not i.size:
        return False
    p1, p2, q1, q2 = xy[i], xy[i + 1], xy[j], xy[j + 1]
    crosses_q = _orient(p1, p2, q1) * _orient(p1, p2, q2) < 0.0
    crosses_p = _orient(q1, q2, p1) * _orient(q1, q2, p2) < 0.0
    return bool(np.any(crosses_q & crosses_p))


def surface_folded(xy: np.ndarray, axis_tol_mm: float = 1e-6) -> bool:
    """Whether the deformed outer surface ``xy`` (nodes in order from the apex) has folded.

    The surface polyline (through the P2 vertex and midside nodes) is folded when

    1. it turns back on itself at a node: two consecutive segments point in opposite directions
       (t_k . t_k+1 < 0, a turn of more than 90 degrees at one node, i.e. the outward normal
       flips between them: a crease the quadratic elements cannot represent as a smooth skin);
    2. it crosses itself: two non-adjacent segments intersect (``polyline_self_intersects``);
       self-contact is not modelled, so a surface that folds over passes through itself; or
    3. it crosses the symmetry axis (a node at x < -axis_tol_mm): the half model's surface then
       intersects its mirror image.

    The apex is not checked against the mirror image's first segment: a surface wrapping the
    wedge's 60 degree tip turns by more than 90 degrees there without folding.
    """
    xy = np.asarray(xy, dtype=float)
    t = np.diff(xy, axis=0)
    dot = t[:-1, 0] * t[1:, 0] + t[:-1, 1] * t[1:, 1]
    if np.any(dot < 0.0):
        return True
    if np.any(xy[:, 0] < -axis_tol_mm):
        return True
    # A polyline whose turns add up to at most pi in absolute value cannot cross itself (the
    # loop between two crossing segments would be a closed polygon turning by less than 2 pi,
    # against Fenchel's theorem): the pairwise test is only needed beyond that.
    cross = t[:-1, 0] * t[1:, 1] - t[:-1, 1] * t[1:, 0]
    if np.abs(np.arctan2(cross, dot)).sum() <= np.pi:
        return False
    return polyline_self_intersects(xy)


def contact_half_width_mm(x_mm: np.ndarray, penetration_mm: np.ndarray) -> float:
    """Half-width of the contact patch from the ordered surface nodes (from the apex).

    The patch ends between the last node with positive penetration and the next one (free, gap
    -penetration >= 0); the edge is where the linear interpolation of the penetration between
    them is zero, at its deformed x. 0 without contact; the last node's x if every node touches.
    """
    touching = np.flatnonzero(penetration_mm > 0.0)
    if touching.size == 0:
        return 0.0
    k = int(touching[-1])
    if k == len(x_mm) - 1:
        return float(x_mm[k])
    p0, p1 = float(penetration_mm[k]), float(penetration_mm[k + 1])
    s = p0 / (p0 - p1)  # p0 > 0 >= p1
    return float(x_mm[k] + s * (x_mm[k + 1] - x_mm[k]))


# ---------------------------------------------------------------------------- stop
class ValidityStop(Exception):
    """A protocol reached a recorded step beyond the validity limits, with
    ``ValidityOptions.stop_at_violation``: raised by the protocol's recorder at that step,
    turned by ``sim.simulate`` into a completed protocol without metrics.

    ``protocol``, ``time_s`` (the step's simulated time), ``violations`` (the limits broken,
    as ``Violation``), ``info`` (the recorder's figures so far: the censored validity
    summary) and ``steps`` (the steps recorded up to and with this one)."""

    def __init__(
        self,
        protocol: str,
        time_s: float,
        violations: list[Violation],
        info: dict[str, Any],
        steps: int,
    ) -> None:
        super().__init__(f"{protocol}: stopped at t = {time_s:.4g} s: beyond the validity limits")
        self.protocol = protocol
        self.time_s = time_s
        self.violations = violations
        self.info = info
        self.steps = steps

    def record(self) -> dict[str, Any]:
        """The JSON-ready figures of the stop (``SimResult.protocols[...]["stopped"]``)."""
        return {"time_s": float(self.time_s), "violations": [str(v) for v in self.violations]}


# ---------------------------------------------------------------------------- tracker
class DeformationTracker:
    """Extremes of the deformation over the committed steps of one protocol.

    ``observe(body)`` at every recorded step, ``observe_peak(body)`` once at the protocol's peak
    load (a later call replaces an earlier one), then ``summary()``.
    """

    def __init__(self, disc: Discretization) -> None:
        self.disc = disc
        self._surface = disc.surface_nodes
        self._X_surface = disc.X[self._surface]
        # the surface's curves in the symmetry planes (2D: the one section), each with the
        # horizontal coordinate it runs along: folding and the contact's extents are read there
        self._curves = disc.section_curves()
        # the curves checked for folding, each with its symmetry axis's tolerance
        # (``surface_folded``); on the half pad (an inclined plate) the curve in x = 0 runs
        # from the heel's end through the apex to the tip's and z = 0 is no symmetry plane
        self._fold_curves = [(nodes, axis, 1e-6) for nodes, axis in self._curves]
        heel = getattr(disc, "heel_curve", lambda: None)()
        if heel is not None:
            tip = self._curves[0][0]
            self._fold_curves[0] = (np.concatenate([heel[::-1], tip[1:]]), 2, np.inf)
        self.height_mm = float(self._X_surface[:, 1].max())
        self._qp_xy = disc.quadrature_points()  # (dim, n_el, n_q), reference, mm
        self._strain_at_mm: list[float] | None = None
        n_layers = len(disc.slices)
        # each layer's Drucker-stable strain (a user material fitted unstable beyond it)
        self._stable_strain = [m.drucker_limit_log_strain for m in disc.materials]
        # each layer's tested compressive limit (its material's own tests)
        self._tested = [layer_limit(m) for m in disc.materials]
        self._layer_strain = np.zeros(n_layers)
        self._layer_J = np.ones(n_layers)
        self._base_nodes = 0
        self._folded = False
        self._travel_mm = 0.0
        self._width_mm: float | None = None
        self._extent_mm: dict[int, float] = {}
        self.observed = 0

    def observe(self, body: Body) -> None:
        """Update the extremes from the body's committed state (u, indenter position)."""
        # contiguous components: the arithmetic on F's strided views costs 3x more
        F = np.ascontiguousarray(self.disc.material_deformation_gradient(body.u))
        J = volume_ratio(F)
        lam_sq = _smallest_stretch_sq(F, J)  # the log is taken of the extremes only
        worst = int(np.argmin(lam_sq))
        strain = max(-0.5 * float(np.log(lam_sq.flat[worst])), 0.0)
        if strain > self._layer_strain.max():
            self._strain_at_mm = self._qp_xy.reshape(len(self._qp_xy), -1)[:, worst].tolist()
        for k, sl in enumerate(self.disc.slices):
            if sl.stop > sl.start:
                layer = max(-0.5 * float(np.log(lam_sq[sl].min())), 0.0)
                self._layer_strain[k] = max(self._layer_strain[k], layer)
                self._layer_J[k] = min(self._layer_J[k], float(J[sl].min()))
        self._base_nodes = max(self._base_nodes, body.base_contact_nodes())
        if not self._folded:
            X, u = self.disc.X, body.u
            self._folded = any(
                surface_folded(X[np.ix_(nodes, [axis, 1])] + u[np.ix_(nodes, [axis, 1])], tol)
                for nodes, axis, tol in self._fold_curves
            )
        if np.isfinite(body.indenter_position):
            top = self.height_mm
            if not body.vertical_indenter:  # an inclined plate: the travel along its normal
                top = float(np.max(self._X_surface @ body.indenter_axis))
            self._travel_mm = max(self._travel_mm, top - body.indenter_position)
        self.observed += 1

    def observe_peak(self, body: Body) -> None:
        """Record the full extents of the contact with the indenter (2 x the symmetric
        model's), in mm: across the finger (x) and, in 3D, along it (z)."""
        self._extent_mm = {}
        if getattr(self.disc, "half", False):  # in the plate's plane (contact_patch)
            _, width, length = self.disc.contact_patch_mm(
                body.u, body.indenter_penetration(), body.indenter_axis
            )
            self._extent_mm, self._width_mm = {0: width, 2: length}, width
            return
        for nodes, axis in self._curves:
            coordinate = self.disc.X[nodes, axis] + body.u[nodes, axis]
            p = body.indenter_penetration(nodes)
            self._extent_mm[axis] = 2.0 * contact_half_width_mm(coordinate, p)
        self._width_mm = self._extent_mm[0]

    def summary(self) -> dict[str, Any]:
        """The extremes over the observed steps, JSON-ready:

        - ``max_compressive_log_strain``: largest -ln(lambda_min) at a quadrature point;
        - ``min_J``: smallest volume ratio at a quadrature point;
        - ``contact_width_at_peak_mm``: full contact width with the indenter at the peak load
          (None if ``observe_peak`` was never called);
        - ``reached_base``: a surface node rested on the base beside the bone;
        - ``folded``: the outer surface folded (``surface_folded``);
        - ``nominal_compression``: largest indenter travel below the undeformed top / body
          height (information, no limit), with ``indenter_travel_mm``;
        - ``max_base_contact_nodes``: most surface nodes on the base at once;
        - ``max_compressive_log_strain_at_mm``: reference (x, y) of the quadrature point with the
          largest strain (None if nothing was compressed);
        - ``max_compressive_log_strain_by_layer``, ``min_J_by_layer``: per layer, outermost first;
        - ``tested_log_strain_by_layer``, ``tested_material_by_layer``,
          ``tested_basis_by_layer``: per layer, the compressive log strain its material was
          tested to, the material it is the limit of and whether it was "measured", "argued" or
          "untested" (``layer_limit``): what ``check`` holds the layer to unless overridden, so
          that a stored summary is judged again without the materials;
        - ``drucker_stable_log_strain_by_layer``: per layer, the compressive log strain within
          which its material's fit is Drucker-stable (None: no limit), only when a layer has
          one (``Material.drucker_limit_log_strain``; a result without one is unchanged).
        """
        out = {
            "max_compressive_log_strain": float(self._layer_strain.max()),
            "min_J": float(self._layer_J.min()),
            "contact_width_at_peak_mm": self._width_mm,
            **({"contact_length_at_peak_mm": self._extent_mm.get(2)} if self.disc.dim == 3 else {}),
            "reached_base": self._base_nodes > 0,
            "folded": self._folded,
            "nominal_compression": self._travel_mm / self.height_mm,
            "indenter_travel_mm": self._travel_mm,
            "max_base_contact_nodes": self._base_nodes,
            "max_compressive_log_strain_at_mm": self._strain_at_mm,
            "max_compressive_log_strain_by_layer": self._layer_strain.tolist(),
            "min_J_by_layer": self._layer_J.tolist(),
            "tested_log_strain_by_layer": [t.log_strain for t in self._tested],
            "tested_material_by_layer": [t.material for t in self._tested],
            "tested_basis_by_layer": [t.basis for t in self._tested],
        }
        if any(limit is not None for limit in self._stable_strain):
            out["drucker_stable_log_strain_by_layer"] = list(self._stable_strain)
        return out


# ---------------------------------------------------------------------------- verdict
@dataclass(frozen=True)
class Violation:
    """One violated limit: the option that sets it, the quantity, its value and the limit."""

    option: str  # the ValidityOptions field (--set validity.<option>=...); "": a material's own
    quantity: str
    value: float | None = None  # None for the yes/no limits
    limit: float | None = None
    relation: str = ">"  # value <relation> limit is the violation
    basis: str = ""  # what the limit is: "measured", "argued", "overridden"... ("": say nothing)

    def _numbers(self) -> tuple[str, str]:
        for digits in (2, 3, 4):
            v, lim = f"{self.value:.{digits}f}", f"{self.limit:.{digits}f}"
            if v != lim:
                break
        return v, lim

    def __str__(self) -> str:
        if self.value is None:
            return self.quantity
        v, lim = self._numbers()
        basis = f" ({self.basis})" if self.basis else ""
        return f"{self.quantity} {v} {self.relation} {lim}{basis}"

    def warning(self) -> str:
        """The sentence of the command line's warning, with the option that moves the limit
        (``option`` "": a material's own limit, which no option moves)."""
        if not self.option:
            v, lim = self._numbers()
            return (
                f"{self.quantity} {v} beyond {lim}: fingertip fit-material found the fitted "
                "law Drucker-unstable there, so the results are an extrapolation"
            )
        if self.value is None:
            return (
                f"{self.quantity}, outside the validity range (--set validity.{self.option}=true)"
            )
        v, lim = self._numbers()
        side = "beyond" if self.relation == ">" else "below"
        hint = f"--set validity.{self.option}=..."
        if self.basis == "overridden":
            hint = f"the limit of --set validity.{self.option}, overriding the layer's own"
        elif self.basis:
            hint = f"{self.basis}; {hint} overrides every layer's"
        return f"{self.quantity} {v} {side} the validity limit {lim} ({hint})"


def check(
    summary: dict[str, Any], options: ValidityOptions, protocol: str | None = None
) -> list[Violation]:
    """The limits of ``options`` that the ``protocol``'s ``summary`` violates (the strain limit
    only for the protocols of ``options.strain_limit_protocols``, or always if ``protocol`` is
    None)."""
    out = []
    J = summary["min_J"]
    limited = protocol is None or protocol in options.strain_limited
    if limited:
        out += _strain_violations(summary, options)
        out += _drucker_violations(summary)
    if J < options.min_J:
        out.append(Violation("min_J", "volume ratio J", J, options.min_J, "<"))
    if summary["reached_base"] and not options.allow_base_contact:
        out.append(Violation("allow_base_contact", "surface reached the base beside the bone"))
    if summary["folded"] and not options.allow_folding:
        out.append(Violation("allow_folding", "surface folded"))
    return out


def _strain_violations(summary: dict[str, Any], options: ValidityOptions) -> list[Violation]:
    """The layers strained beyond their compressive limit (``strain_limits``), each named with
    its material and what its limit is (measured, argued, the paper's, overridden)."""
    return [
        Violation(
            "max_compressive_log_strain",
            f"{s.label} compressive log strain" if s.label else "compressive log strain",
            s.strain,
            s.limit,
            basis=s.basis_words,
        )
        for s in strain_limits(summary, options)
        if s.strain > s.limit
    ]


def _drucker_violations(summary: dict[str, Any]) -> list[Violation]:
    """The layers strained beyond the Drucker-stable strain of their material's fit
    (``drucker_stable_log_strain_by_layer``, when the summary has it). Held against the same
    protocols as the strain limit (``strain_limit_protocols``), for the same reason: under the
    wedge's tip the strain is a near-singularity over a few hundredths of a mm^2."""
    limits = summary.get("drucker_stable_log_strain_by_layer")
    if not limits:  # no layer has one (every result before this limit): nothing is read
        return []
    strains = summary["max_compressive_log_strain_by_layer"]
    return [
        Violation("", f"layer {k} compressive log strain (Drucker-stable fit)", strain, limit)
        for k, (strain, limit) in enumerate(zip(strains, limits, strict=False))
        if limit is not None and strain > limit
    ]


def assess(
    summary: dict[str, Any], options: ValidityOptions, protocol: str | None = None
) -> list[str]:
    """The violated limits as short sentences, e.g. ``"compressive log strain 0.81 > 0.60"``."""
    return [str(v) for v in check(summary, options, protocol)]
