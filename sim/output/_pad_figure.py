"""The figure of the deformed 3D pad and its contact patch at 1 N and 4 N (``figures/pad.png``).

``pad_figure_info(result)`` computes what is drawn (``PadFigureInfo``: arrays in mm, the
whole pad mirrored from the quarter model), ``render_pad_figure(info, path)`` draws it with
matplotlib: one column per force, the footprint seen from above (x-z plane: the pad's base
outline, the contact patch filled by contact pressure) over the section x = 0 (deformed
against undeformed, with the plate), both on the same z scale.

An inclined plate (``model.inclination_deg`` = t, the half model x >= 0: docs/model_3d.md,
"Inclination") gives the same figure with the half pad mirrored across x = 0 only: the
footprint is seen along the plate's normal e = (0, cos t, sin t), in the plate's plane, at the
coordinates x (across the finger) and s = x . t_p along t_p = (0, -sin t, cos t) (along the
finger, towards the tip z > 0; s = z at t = 0), its outline the whole pad's silhouette seen
along e; the section x = 0 runs from the heel's end (z = -c) to the tip's (z = c), with the
plate's tilted trace e . (y, z) = position; the first-touch point (``first_touch_mm``) is
marked on both.

The states are the tapping's ``tapping_1N`` and ``tapping_4N`` fields: the first step of the
measured tap at or beyond 1 N (4 N) on loading, so a little beyond it (e.g. 1.21 N on 48
steps), while the metrics (``contact_area_at_1N_mm2``) are interpolated to exactly 1 N: the
figure states both. The plate's position at a state is not stored with it; it is recovered
from the tap's curve (``displacement_mm`` is the undeformed top less the plate's position at
every recorded step, and the state is the curve's first step at or beyond the force on
loading), and checked by the force balance. The penalty stiffness kappa (N/mm^3) follows from
the same balance, the quarter's force = sum of kappa w_i p_i over the surface nodes (w the
nodes' area shares, p > 0 the penetrations), so the pressure kappa p needs no options.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ..geometry import _q2, first_touch_mm

__all__ = ["PadFigureInfo", "PadState", "pad_figure_info", "render_pad_figure"]

#: the tapping's states drawn: (field name, nominal force in N)
STATES = (("tapping_1N", 1.0), ("tapping_4N", 4.0))

#: each touching surface face is drawn as SUBDIVISIONS x SUBDIVISIONS quads of 2 triangles
SUBDIVISIONS = 8

#: the copies of the quarter x >= 0, z >= 0 that make the whole pad: signs of (x, z)
MIRRORS = ((1.0, 1.0), (-1.0, 1.0), (1.0, -1.0), (-1.0, -1.0))

#: the copies of the half pad x >= 0 (an inclined plate) that make the whole pad: signs of
#: (x, s), s the coordinate along the finger in the plate's plane
HALF_MIRRORS = ((1.0, 1.0), (-1.0, 1.0))


@dataclass(frozen=True, eq=False)
class PadState:
    """One state of the tapping drawn: its footprint and its section x = 0 (whole pad, mm).

    Attributes:
        name: the field's name (``tapping_1N``).
        force_N: the nominal force (1 or 4 N).
        state_force_N: the whole pad's force at the state (the first step at or beyond
            ``force_N``).
        plate_position_mm: the plate's face y = plate_position_mm at the state (inclined:
            e . (x, y, z) = plate_position_mm, its height along its normal e).
        metric_area_mm2: the result's ``contact_area_at_<F>N_mm2`` (interpolated to exactly
            ``force_N``; None if missing or NaN).
        patch_area_mm2: the area of the drawn patch (the state's; whole pad): the triangles'
            parts with a positive (linearly interpolated) penetration, in the plate's plane.
        footprint_xz_mm: (P, 2) the deformed (x, z) of the points sampled on the surface faces
            that touch the plate, all four copies; inclined (the half pad): (x, s), the
            coordinates in the plate's plane (s along t_p, ``PadFigureInfo.along_plate``),
            both copies x and -x.
        footprint_triangles: (T, 3) triangles of ``footprint_xz_mm``.
        penetration_mm: (P,) the plate's penetration at those points (> 0 inside).
        pressure_kPa: (P,) the contact pressure (>= 0): the penalty's at the nodes, kappa
            max(p_i, 0), interpolated piecewise bilinearly (``_footprint``).
        section_zy_mm: (n, 2) the deformed outer surface's curve in the plane x = 0, from
            z = -c to z = c (on the half pad from the heel's end to the tip's, not mirrored).
        interfaces_zy_mm: the deformed layer interfaces in the plane x = 0, outermost first.
        plate_trace_zy_mm: (2, 2) the plate's face in the plane x = 0, (z, y) at its two ends
            (z = -1.05 c, 1.05 c): level on the quarter, tilted by t on the half pad.
        patch_centre_mm: the drawn patch's centroid in the footprint's coordinates, (x, z) or
            (x, s): each triangle's centroid weighted by its part inside the patch.
    """

    name: str
    force_N: float
    state_force_N: float
    plate_position_mm: float
    metric_area_mm2: float | None
    patch_area_mm2: float
    footprint_xz_mm: np.ndarray
    footprint_triangles: np.ndarray
    penetration_mm: np.ndarray
    pressure_kPa: np.ndarray
    section_zy_mm: np.ndarray
    interfaces_zy_mm: tuple[np.ndarray, ...]
    plate_trace_zy_mm: np.ndarray
    patch_centre_mm: tuple[float, float]


@dataclass(frozen=True, eq=False)
class PadFigureInfo:
    """What ``render_pad_figure`` draws (mm, whole pad).

    Attributes:
        outline_xz_mm: (n, 2) the pad's base outline |x/a|^m + |z/c|^m = 1, closed; on the
            half pad (an inclined plate) the pad's silhouette seen along the plate's normal e,
            (x, s) in the plate's plane (the convex hull of its undeformed outer surface,
            sampled as the footprint is; the pad is convex), closed.
        section_reference_zy_mm: (n, 2) the undeformed outer curve in the plane x = 0.
        states: the states drawn, by increasing force.
        kappa_N_per_mm3: the contact penalty (pressure per mm of penetration).
        n_elements: elements of the model's mesh (the quarter's, or the half's).
        half: the model is the half pad x >= 0 (mirrored across x = 0 only), not the quarter.
        inclination_deg: the plate's inclination t about x (0: level).
        first_touch_zy_mm: (z*, y*), the point of x = 0 where the plate first touches the
            undeformed pad (``sim.geometry.first_touch_mm``; the apex (0, b) at 0 deg).
    """

    outline_xz_mm: np.ndarray
    section_reference_zy_mm: np.ndarray
    states: tuple[PadState, ...]
    kappa_N_per_mm3: float
    n_elements: int
    half: bool = False
    inclination_deg: float = 0.0
    first_touch_zy_mm: tuple[float, float] = (0.0, 0.0)

    @property
    def max_pressure_kPa(self) -> float:
        return max((float(s.pressure_kPa.max(initial=0.0)) for s in self.states), default=0.0)

    @property
    def plate_normal(self) -> np.ndarray:
        """e = (0, cos t, sin t): the plate's outward normal (from the pad into the plate)."""
        return _plate_normal(self.inclination_deg)

    @property
    def along_plate(self) -> np.ndarray:
        """t_p = (0, -sin t, cos t): the plate's direction along the finger, towards the tip."""
        return _along_plate(self.plate_normal)

    @property
    def first_touch_s_mm(self) -> float:
        """The first-touch point's coordinate s along the finger in the plate's plane."""
        z, y = self.first_touch_zy_mm
        return float(np.array([0.0, y, z]) @ self.along_plate)


def pad_figure_info(result: Any) -> PadFigureInfo:
    """The figure's arrays for a 3D ``SimResult`` kept with ``keep_fields`` whose tapping
    reached 1 N or 4 N. ``ValueError`` if it has no such state (a 2D result, no fields).

    On the half pad (an inclined plate, ``PadMesh.inclination_deg`` = t) the plate's position
    and the penetrations are along its normal e, as the solver reads them
    (``sim.fe.contact.Plate``), and the footprint is read in its plane."""
    disc = result.discretization
    if disc is None or disc.dim != 3:
        raise ValueError("the pad figure needs a 3D result with its fields (keep_fields=True)")
    present = [(name, f) for name, f in STATES if name in result.fields]
    if not present or "tapping" not in result.curves:
        raise ValueError("the pad figure needs the tapping's states at 1 N / 4 N")
    pmesh = disc.pmesh
    geometry = pmesh.geometry
    half = bool(disc.half)
    inclination = float(getattr(pmesh, "inclination_deg", 0.0))
    e = _plate_normal(inclination)
    s = disc.surface_nodes
    # the curve's displacements are from the undeformed top (along e)
    top0 = float(_heights(disc.X[s], e).max())
    curve = result.curves["tapping"]
    force = np.asarray(curve["force_N"], dtype=float)
    disp = np.asarray(curve["displacement_mm"], dtype=float)
    weights = disc.surface_weights()
    scale = disc.force_scale(0.0)  # whole pad / the model's part
    states, kappas = [], []
    for name, f in present:
        u = result.fields[name]
        i = _state_step(force, f)
        position = top0 - disp[i]
        p = _heights(disc.X[s] + u[s], e) - position
        balance = float(weights @ np.maximum(p, 0.0))
        if not balance > 0.0:
            raise ValueError(f"{name}: no penetration at the plate position read from the curve")
        kappa = force[i] / scale / balance
        kappas.append(kappa)
        states.append((name, f, i, position, u, p, kappa))
    # one kappa for all states (the same penalty): a mismatch means a misread plate position
    if max(kappas) > 1.01 * min(kappas):
        raise ValueError(f"the states' force balances disagree: kappa {kappas} N/mm^3")
    kappa = float(np.mean(kappas))
    a, _, c = geometry.semi_axes_mm()
    out = []
    for name, f, i, position, u, p, _ in states:
        xz, tri, pen, pressure = _footprint(disc, u, p, kappa, e)
        metric = result.metrics.get(f"contact_area_at_{f:g}N_mm2")
        parts = _positive_parts(xz, tri, pen)
        out.append(
            PadState(
                name=name,
                force_N=f,
                state_force_N=float(force[i]),
                plate_position_mm=float(position),
                metric_area_mm2=float(metric) if _finite(metric) else None,
                patch_area_mm2=float(np.sum(parts)),
                footprint_xz_mm=xz,
                footprint_triangles=tri,
                penetration_mm=pen,
                pressure_kPa=pressure,
                section_zy_mm=_section(disc, u),
                interfaces_zy_mm=_interfaces(pmesh, u),
                plate_trace_zy_mm=_plate_trace(float(position), e, 1.05 * c),
                patch_centre_mm=_centre(xz, tri, parts),
            )
        )
    if half:
        outline = _silhouette(disc, e)
    else:
        m = geometry.exponents[1]
        angle = np.linspace(0.0, 2.0 * np.pi, 361)
        cos, sin = np.cos(angle), np.sin(angle)
        outline = np.column_stack(
            [
                a * np.sign(cos) * np.abs(cos) ** (2.0 / m),
                c * np.sign(sin) * np.abs(sin) ** (2.0 / m),
            ]
        )
    _, y_touch, z_touch = first_touch_mm(geometry, inclination)
    return PadFigureInfo(
        outline_xz_mm=outline,
        section_reference_zy_mm=_section(disc, np.zeros_like(disc.X)),
        states=tuple(out),
        kappa_N_per_mm3=kappa,
        n_elements=int(disc.n_el),
        half=half,
        inclination_deg=inclination,
        first_touch_zy_mm=(float(z_touch), float(y_touch)),
    )


def _plate_normal(inclination_deg: float) -> np.ndarray:
    """e = (0, cos t, sin t), the plate's outward normal (``sim.fe.contact.Plate``); exactly
    (0, 1, 0) at 0."""
    t = np.radians(inclination_deg)
    return np.array([0.0, np.cos(t), np.sin(t)])


def _along_plate(e: np.ndarray) -> np.ndarray:
    """t_p = (0, -e_z, e_y): the plate's direction along the finger, towards the tip (z > 0)."""
    return np.array([0.0, -e[2], e[1]])


def _is_level(e: np.ndarray) -> bool:
    return bool(e[1] == 1.0 and e[0] == 0.0 and e[2] == 0.0)


def _heights(x: np.ndarray, e: np.ndarray) -> np.ndarray:
    """e . x of the points x (..., 3): their height along the plate's normal; y for a level
    plate (the solver's reading, ``Body.along_indenter``)."""
    return x[..., 1] if _is_level(e) else x @ e


def _in_plate(x: np.ndarray, e: np.ndarray) -> np.ndarray:
    """The points x (..., 3) projected on the plate's plane: (x, s) (..., 2), s = x . t_p;
    (x, z) for a level plate."""
    if _is_level(e):
        return x[..., [0, 2]]
    return np.stack([x[..., 0], x @ _along_plate(e)], axis=-1)


def _plate_trace(position_mm: float, e: np.ndarray, z_end_mm: float) -> np.ndarray:
    """The plate's face e . (y, z) = position in the plane x = 0, (z, y) at z = -+z_end."""
    z = np.array([-z_end_mm, z_end_mm])
    return np.column_stack([z, (position_mm - z * e[2]) / e[1]])


def _silhouette(disc: Any, e: np.ndarray) -> np.ndarray:
    """The whole pad's outline seen along e, (x, s) in the plate's plane, closed: the convex
    hull of its undeformed outer surface sampled on the faces (as ``_footprint``) and of its
    copy x -> -x (the pad is convex, so is its projection)."""
    from scipy.spatial import ConvexHull

    faces = np.asarray(disc.pmesh.surface_faces)
    t = np.linspace(-1.0, 1.0, SUBDIVISIONS + 1)
    S, T = np.meshgrid(t, t, indexing="ij")
    N = _q2.face_shape_functions(np.column_stack([S.ravel(), T.ravel()]))
    points = _in_plate(np.einsum("pa,fai->fpi", N, disc.X[faces]).reshape(-1, 3), e)
    points = np.concatenate([points, points * np.array([-1.0, 1.0])])
    hull = points[ConvexHull(points).vertices]  # counter-clockwise
    return np.concatenate([hull, hull[:1]])


def _finite(value: Any) -> bool:
    return value is not None and bool(np.isfinite(value))


def _state_step(force: np.ndarray, force_N: float) -> int:
    """The curve's index of the state kept at ``force_N``: its first step at or beyond it
    while the force still rises to a new peak
    (``sim.protocols.loading._Recorder.record_peak_force``)."""
    peak = -np.inf
    for i, f in enumerate(force[1:], start=1):
        if f > peak:
            peak = f
            if f >= force_N * (1.0 - 1e-9):
                return i
    raise ValueError(f"the tapping's curve never reaches {force_N:g} N")


def _footprint(
    disc: Any, u: np.ndarray, p: np.ndarray, kappa: float, e: np.ndarray
) -> tuple[np.ndarray, ...]:
    """The surface faces with a node inside the plate (the patch and its edge lie on them: a
    node inside makes every face around it one of them), each sampled on a grid of
    (SUBDIVISIONS + 1)^2 points and split into triangles, mirrored into the four copies of
    the pad: their deformed (x, z), the penetration and the pressure (kPa) there. On the half
    pad (the plate's normal e inclined) their deformed (x, s) in the plate's plane
    (``_in_plate``), mirrored into the two copies x and -x.

    The penetration is interpolated by the faces' shape functions, as
    ``Discretization3D.contact_area_mm2`` does (its positive part is the patch of the
    metric). The pressure is the penalty's at the nodes, kappa max(p_i, 0) (the nodal force
    over the node's area), interpolated piecewise bilinearly between the face's nine nodes:
    between the nodes the quadratic surface pierces the plate much deeper than at them
    (tens of times the nodal penetrations on a coarse mesh), which the penalty, acting at
    the nodes only, does not resist."""
    faces = np.asarray(disc.pmesh.surface_faces)
    on_surface = np.full(disc.n_nodes, -np.inf)
    on_surface[disc.surface_nodes] = p
    faces = faces[np.any(on_surface[faces] > 0.0, axis=1)]
    k = SUBDIVISIONS
    t = np.linspace(-1.0, 1.0, k + 1)
    S, T = np.meshgrid(t, t, indexing="ij")  # point (i, j) at i (k + 1) + j
    points = np.column_stack([S.ravel(), T.ravel()])
    N = _q2.face_shape_functions(points)  # (P, 9)
    x = np.einsum("pa,fai->fpi", N, (disc.X + u)[faces])  # (F, P, 3)
    pen = on_surface[faces] @ N.T  # (F, P)
    pressure = 1e3 * kappa * np.maximum(on_surface[faces], 0.0) @ _face_hats(points).T
    ij = np.arange((k + 1) ** 2).reshape(k + 1, k + 1)
    c00, c10, c01, c11 = ij[:-1, :-1], ij[1:, :-1], ij[:-1, 1:], ij[1:, 1:]
    local = np.concatenate(
        [np.column_stack([c00.ravel(), c10.ravel(), c11.ravel()]),
         np.column_stack([c00.ravel(), c11.ravel(), c01.ravel()])]
    )  # fmt: skip
    n_pts = (k + 1) ** 2
    tri = (np.arange(len(faces))[:, None, None] * n_pts + local[None]).reshape(-1, 3)
    xz = _in_plate(x, e).reshape(-1, 2)
    mirrors = HALF_MIRRORS if disc.half else MIRRORS
    copies = [xz * np.array(sign) for sign in mirrors]
    triangles = [tri + k_copy * len(xz) for k_copy in range(len(mirrors))]
    n = len(mirrors)
    return (
        np.concatenate(copies),
        np.concatenate(triangles),
        np.tile(pen.ravel(), n),
        np.tile(pressure.ravel(), n),
    )


def _face_hats(points: np.ndarray) -> np.ndarray:
    """The piecewise bilinear hat functions (P, 9) of the 9-node face's nodes at reference
    points (P, 2): the product of the 1D hats on the nodes -1, 0, 1 (max(-t, 0), 1 - |t|,
    max(t, 0))."""
    index = np.rint(_q2.FACE_REFERENCE_POINTS).astype(int) + 1  # (9, 2)
    hats = []
    for d in range(2):
        t = points[:, d]
        h = np.stack([np.maximum(-t, 0.0), 1.0 - np.abs(t), np.maximum(t, 0.0)], axis=-1)
        hats.append(h[:, index[:, d]])
    return hats[0] * hats[1]


def _positive_parts(xy: np.ndarray, triangles: np.ndarray, value: np.ndarray) -> np.ndarray:
    """Each triangle's area (T,) where the linear interpolation of ``value`` is > 0."""
    v = value[triangles]  # (T, 3)
    a, b, c = (xy[triangles[:, k]] for k in range(3))
    ab, ac = b - a, c - a
    area = 0.5 * np.abs(ab[:, 0] * ac[:, 1] - ab[:, 1] * ac[:, 0])
    positive = v > 0.0
    n_pos = positive.sum(axis=1)
    frac = np.where(n_pos == 3, 1.0, 0.0)
    # one vertex on its own side (the apex, value v0 against v1, v2): its corner triangle
    # has the fraction v0^2 / ((v0 - v1)(v0 - v2)) of the area
    for lone, inside in ((1, True), (2, False)):
        rows = np.flatnonzero(n_pos == lone)
        if not rows.size:
            continue
        vr = v[rows]
        apex = np.argmax(positive[rows] == inside, axis=1)
        v0 = vr[np.arange(len(rows)), apex]
        others = vr[np.arange(len(rows))[:, None], (apex[:, None] + np.array([1, 2])) % 3]
        corner = v0**2 / ((v0 - others[:, 0]) * (v0 - others[:, 1]))
        frac[rows] = corner if inside else 1.0 - corner
    return area * frac


def _centre(xy: np.ndarray, triangles: np.ndarray, parts: np.ndarray) -> tuple[float, float]:
    """The centroid of the triangles weighted by their parts ``parts`` (T,) inside the patch
    (``_positive_parts``): the patch's, to within a triangle at its edge; (nan, nan) without
    a patch."""
    total = float(np.sum(parts))
    if not total > 0.0:
        return float("nan"), float("nan")
    centroids = xy[triangles].mean(axis=1)  # (T, 2)
    cx, cs = parts @ centroids / total
    return float(cx), float(cs)


def _section(disc: Any, u: np.ndarray) -> np.ndarray:
    """The outer surface's curve in the plane x = 0 (deformed by ``u``), (z, y) from z = -c
    through the apex to z = c: on the quarter its half z >= 0 and that half's mirror image, on
    the half pad its heel's half (``heel_curve``) and its tip's."""
    nodes, axis = disc.section_curves()[0]
    assert axis == 2, "the first section curve runs along z"
    zy = disc.X[nodes][:, [2, 1]] + u[nodes][:, [2, 1]]
    if not disc.half:
        return _mirror_z(zy)
    heel = disc.heel_curve()  # from the apex towards z = -c
    assert heel[0] == nodes[0], "both halves of the section start at the apex"
    heel_zy = disc.X[heel][:, [2, 1]] + u[heel][:, [2, 1]]
    return np.concatenate([heel_zy[::-1], zy[1:]])


def _interfaces(pmesh: Any, u: np.ndarray) -> tuple[np.ndarray, ...]:
    """Each layer interface's curve in the plane x = 0 (deformed by ``u``), as ``_section``:
    ordered by the angle from the y axis, on the half pad from its heel's end to its tip's."""
    X = np.asarray(pmesh.nodes)
    depths = np.cumsum(pmesh.thicknesses_mm)
    out = []
    for nodes, depth in zip(pmesh.interfaces, depths, strict=True):
        on = nodes[X[nodes, 0] == 0.0]
        _, b, c = pmesh.geometry.semi_axes_mm(float(depth))
        order = np.argsort(np.arctan2(X[on, 2] / c, X[on, 1] / b), kind="stable")
        on = on[order]
        zy = X[on][:, [2, 1]] + u[on][:, [2, 1]]
        out.append(zy if pmesh.half else _mirror_z(zy))
    return tuple(out)


def _mirror_z(zy: np.ndarray) -> np.ndarray:
    """A curve (z, y) from z = 0 out to z > 0, with its mirror image z -> -z before it."""
    left = zy[::-1] * np.array([-1.0, 1.0])
    return np.concatenate([left[:-1], zy])


# ----------------------------------------------------------------------------- rendering
def render_pad_figure(info: PadFigureInfo, path: str | Path) -> Path:
    """Draw ``info`` to ``path`` (PNG): a column per state, the footprint seen from above over
    the section x = 0, with one pressure scale for all. On the half pad (an inclined plate)
    the footprint is seen along the plate's normal (s along the finger in its plane, the tip
    to the right) and the section shows the tilted plate; both on the same scale along the
    finger, the angle and the tip's end stated."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.tri import Triangulation

    outline = info.outline_xz_mm
    ref = info.section_reference_zy_mm
    inclined = info.half
    if inclined:  # one scale along the finger: the footprint's s and the section's z
        z_lim = 1.05 * max(float(np.abs(outline[:, 1]).max()), float(np.abs(ref[:, 0]).max()))
    else:
        z_lim = 1.05 * float(np.abs(outline[:, 1]).max())
    x_lim = 1.1 * float(np.abs(outline[:, 0]).max())
    y_top = 1.08 * float(ref[:, 1].max())
    n = len(info.states)
    fig, axes = plt.subplots(
        2,
        n,
        figsize=(5.2 * n + 1.0, 6.6),
        gridspec_kw={"height_ratios": [2.0 * x_lim, y_top + 0.8]},
        squeeze=False,
    )
    p_max = max(info.max_pressure_kPa, 1e-12)
    filled = None
    angle = f"{info.inclination_deg:g}\N{DEGREE SIGN}"
    for col, st in enumerate(info.states):
        top, side = axes[0, col], axes[1, col]
        # footprint from above: z to the right, x up (seen from +y); inclined: seen along
        # the plate's normal, s (along the finger in the plate's plane) to the right
        top.fill(outline[:, 1], outline[:, 0], color="0.93", zorder=0)
        top.plot(outline[:, 1], outline[:, 0], color="0.3", lw=1.0)
        zx = (st.footprint_xz_mm[:, 1], st.footprint_xz_mm[:, 0])
        # the patch: the triangles inside (by their mean penetration) coloured, its edge
        # (the penetration's zero level) drawn exactly
        outside = st.penetration_mm[st.footprint_triangles].mean(axis=1) <= 0.0
        patch = Triangulation(*zx, st.footprint_triangles, mask=outside)
        filled = top.tripcolor(
            patch, st.pressure_kPa, shading="gouraud", cmap="viridis", vmin=0.0, vmax=p_max
        )
        edge = Triangulation(*zx, st.footprint_triangles)
        top.tricontour(edge, st.penetration_mm, levels=[0.0], colors="k", linewidths=0.8)
        top.axhline(0.0, color="0.6", lw=0.5, ls=":")
        top.axvline(0.0, color="0.6", lw=0.5, ls=":")
        top.set_xlim(-z_lim, z_lim)
        top.set_ylim(-x_lim, x_lim)
        top.set_aspect("equal")
        top.set_ylabel("x, across the finger (mm)")
        if inclined:
            top.plot(info.first_touch_s_mm, 0.0, "r+", ms=9, mew=1.5, zorder=5)
            top.set_xlabel("s, along the finger in the plate's plane (mm), heel \u2190 \u2192 tip")
            top.text(-0.97 * z_lim, 0.92 * x_lim, "heel", fontsize=8, va="top")
            top.text(0.97 * z_lim, 0.92 * x_lim, "tip", fontsize=8, va="top", ha="right")
        else:
            top.set_xlabel("z, along the finger (mm)")
        metric = (
            f"contact area {st.metric_area_mm2:.1f} mm$^2$"
            if st.metric_area_mm2 is not None
            else "contact area: no metric"
        )
        top.set_title(
            f"{st.force_N:g} N: {metric}\n"
            f"drawn: the step at {st.state_force_N:.2f} N (the first at or beyond "
            f"{st.force_N:g} N), patch {st.patch_area_mm2:.1f} mm$^2$",
            fontsize=10,
        )
        # the section x = 0: deformed (filled) against undeformed (dashed), the plate
        sec = st.section_zy_mm
        side.fill(sec[:, 0], sec[:, 1], color="#f3d9b1", zorder=0)
        side.plot(sec[:, 0], sec[:, 1], color="#8c5a1e", lw=1.2, label="deformed")
        side.plot(ref[:, 0], ref[:, 1], color="0.35", lw=0.9, ls="--", label="undeformed")
        for k, curve in enumerate(st.interfaces_zy_mm):
            label = "layer interfaces" if k == 0 else None
            side.plot(curve[:, 0], curve[:, 1], color="#8c5a1e", lw=0.6, ls="-.", label=label)
        side.axhline(0.0, color="k", lw=2.0)
        if inclined:
            trace = st.plate_trace_zy_mm
            high = 10.0 * (y_top + 0.8)  # the plate's side, beyond the axes
            side.fill(
                [trace[0, 0], trace[1, 0], trace[1, 0], trace[0, 0]],
                [trace[0, 1], trace[1, 1], high, high],
                color="0.75",
                alpha=0.6,
                lw=0,
            )
            side.plot(trace[:, 0], trace[:, 1], color="0.2", lw=1.5, label="plate")
            z_t, y_t = info.first_touch_zy_mm
            side.plot(z_t, y_t, "r+", ms=9, mew=1.5, zorder=5, label="first touch (undeformed)")
            side.text(
                0.97 * z_lim,
                y_top + 0.6,
                f"plate at {angle}, e\u00b7x = {st.plate_position_mm:.2f} mm",
                fontsize=8,
                va="top",
                ha="right",
            )
        else:
            side.axhspan(st.plate_position_mm, y_top + 0.8, color="0.75", alpha=0.6, lw=0)
            side.axhline(st.plate_position_mm, color="0.2", lw=1.5, label="plate")
            side.text(
                -0.97 * z_lim,
                st.plate_position_mm + 0.15,
                f"plate, y = {st.plate_position_mm:.2f} mm",
                fontsize=8,
                va="bottom",
            )
        side.set_xlim(-z_lim, z_lim)
        side.set_ylim(-0.3, y_top + 0.8)
        side.set_aspect("equal")
        side.set_xlabel(
            "z, along the finger (mm), heel \u2190 \u2192 tip"
            if inclined
            else "z, along the finger (mm)"
        )
        side.set_ylabel("y (mm)")
        side.set_title("section x = 0", fontsize=9)
    if inclined:
        title = (
            f"Tapping on a plate inclined {angle} about x (tip end z > 0 meets it first): the "
            "deformed pad and its contact patch seen along the plate's normal\n"
            f"(3D half model x \u2265 0, mirrored across x = 0; {info.n_elements} elements; "
            "+ first touch)"
        )
    else:
        title = (
            "Tapping: the deformed pad and its contact patch "
            f"(3D quarter model, mirrored; {info.n_elements} elements)"
        )
    fig.suptitle(title, fontsize=11)
    handles, labels = axes[1, 0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="lower center", ncol=len(labels), fontsize=8, frameon=False)
    fig.tight_layout(rect=(0.0, 0.04, 0.92, 1.0))
    if filled is not None:
        cax = fig.add_axes((0.93, 0.45, 0.013, 0.4))
        fig.colorbar(filled, cax=cax, label="contact pressure (kPa)")
    path = Path(path)
    fig.savefig(path, dpi=130)
    plt.close(fig)
    return path
