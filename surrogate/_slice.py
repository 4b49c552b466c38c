"""The slice model: a 3D pad's tapping read from its 2D section, slice by slice along the finger.

The pad (``sim.geometry.pad``) is the 2D section (semi-axes a, b, exponent n) scaled by
s(z) = (1 - |z/c|^m)^(1/m) along the finger, so its crest at z lies

    dh(z) = b (1 - s(z))

below the crest at z = 0. Pressed by a flat plate to a depth delta from touch, each slice dz is
taken as the 2D plane-strain section pressed by delta - dh(z), carrying the 2D model's line
load q(delta - dh) dz; the slices do not shear each other. The 2D model gives q through its two
tapping readings, 1 N and 4 N on its 10 mm (q = 0.1 and 0.4 N/mm) at the displacements d_1 and
d_4, taken as a power law q(d) = A d^k through them (k = ln 4 / ln(d_4 / d_1)). Then

    F(delta) = 2 int_0^{z_e} A (delta - dh(z))^k dz,     dh(z_e) = delta  (z_e <= c),

and the 3D displacement at a force solves F(delta) = force (``slice_depth``). The work of a press
to delta is W(delta) = 2 A / (k + 1) int_0^{z_e} (delta - dh)^(k + 1) dz, the 2D model's
10 A d_4^(k + 1) / (k + 1), and a tap's hysteresis is taken to scale with that work
(``work_ratio``). The plate's overlap with the undeformed pad at delta (``overlap``): a slice cut
delta - dh(z) below its crest is a superellipse of semi-axes (a s, b s) cut at that depth, of
width w(z) = 2 a s (1 - (1 - (delta - dh) / (b s))^n)^(1/n); the patch's area is int w dz,
its length 2 z_e, its width w(0).

What it is for: the multi-fidelity method ``delta-slice`` (``surrogate._multifidelity``) starts
each 3D displacement, the hysteresis and the contact patch from these values instead of the 2D
prediction itself. On the 3D dataset's first 123 designs (91 with trusted displacements) the
slice model alone, with no fitted constant, predicts the displacement from touch at 1 N to a
median of 4.2 %, where the 2D prediction is off by a median of 12-16 % (docs/multifidelity.md,
"The slice model"). What it leaves out (the slices' shear, the section's scale, the tap's
dynamics) is what the method's trend and ensemble learn.

All functions are vectorised over designs (numpy arrays of one shape, or scalars).
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping

import numpy as np

__all__ = [
    "PAD",
    "SLICE_METRICS",
    "line_load_law",
    "overlap",
    "pad_force",
    "slice_depth",
    "slice_values",
    "work_ratio",
]

#: the 2D model's line loads (N/mm) at its tapping readings: 1 N and 4 N on 10 mm of finger
LINE_LOADS_N_PER_MM = (0.1, 0.4)
#: the 2D model's length of finger (mm): its forces are line loads times this
LENGTH_2D_MM = 10.0
#: Gauss-Legendre points on [0, z_e]: the integrands vanish like (z_e - z)^k at the edge, k >= 1
#: in the default space; 64 points hold the integrals to 1e-6 of a 100 000-point trapezoid rule
#: (``tests/test_multifidelity.py``)
_NODES, _WEIGHTS = np.polynomial.legendre.leggauss(64)
_NODES, _WEIGHTS = 0.5 * (_NODES + 1.0), 0.5 * _WEIGHTS


def line_load_law(d1_mm, d4_mm) -> tuple[np.ndarray, np.ndarray]:
    """``(A, k)`` of the 2D line load q(d) = A d^k (N/mm) through its readings: q = 0.1 N/mm at
    ``d1_mm`` and 0.4 N/mm at ``d4_mm`` (``d4_mm > d1_mm > 0``)."""
    d1, d4 = np.asarray(d1_mm, dtype=float), np.asarray(d4_mm, dtype=float)
    q1, q4 = LINE_LOADS_N_PER_MM
    k = np.log(q4 / q1) / np.log(d4 / d1)
    return q1 / d1**k, k


def _profile(u: np.ndarray, m) -> np.ndarray:
    """s at z = u c: (1 - u^m)^(1/m), 0 <= u <= 1."""
    return np.clip(1.0 - u**m, 0.0, 1.0) ** (1.0 / m)


def _edge(depth, b, m) -> np.ndarray:
    """u_e = z_e / c, where dh(z_e) = depth: (1 - (1 - depth / b)^m)^(1/m), 1 past the crest's
    full height."""
    depth, b, m = (np.asarray(v, dtype=float) for v in (depth, b, m))
    return (1.0 - np.clip(1.0 - depth / b, 0.0, 1.0) ** m) ** (1.0 / m)


def _slices(depth, b, c, m):
    """The quadrature (z (n, q), weights (n, q), the slices' depths delta - dh >= 0 (n, q)) on
    [0, z_e] of each design; scalars broadcast."""
    depth, b, c, m = (np.asarray(v, dtype=float)[..., None] for v in (depth, b, c, m))
    ue = _edge(depth, b, m)
    u = ue * _NODES
    local = np.maximum(depth - b * (1.0 - _profile(u, m)), 0.0)
    return u, c * ue * _WEIGHTS, local


def pad_force(depth_mm, A, k, b_mm, c_mm, m) -> np.ndarray:
    """F(delta) (N): the slices' line loads A (delta - dh)^k summed over the pad's length."""
    return _force_and_log_slope(depth_mm, A, k, b_mm, c_mm, m)[0]


def _force_and_log_slope(depth_mm, A, k, b_mm, c_mm, m) -> tuple[np.ndarray, np.ndarray]:
    """``pad_force`` F and its log slope d ln F / d ln delta = delta F' / F, with
    F' = 2 A k sum w (delta - dh)^(k - 1) (the integrand vanishes at the edge z_e, so the
    edge's motion adds nothing)."""
    _, w, local = _slices(depth_mm, b_mm, c_mm, m)
    A, k = np.asarray(A, dtype=float), np.asarray(k, dtype=float)
    with np.errstate(divide="ignore", invalid="ignore"):  # k < 1: 0^(k - 1) at the edge
        power = np.where(local > 0.0, local ** (k[..., None] - 1.0), 0.0)
        F = 2.0 * A * np.sum(w * power * local, -1)
        dF = 2.0 * A * k * np.sum(w * power, -1)
        return F, np.asarray(depth_mm) * dF / F


def slice_depth(force_N, A, k, b_mm, c_mm, m, iterations: int = 60) -> np.ndarray:
    """The depth delta (mm) at which ``pad_force`` is ``force_N``, every design at once (F grows
    with delta from 0 without bound): Newton's method on ln F against ln delta inside a bracket
    that each evaluation narrows, a bisection step wherever Newton's would leave it. The
    bracket starts at [e^-30 mm, b] and is widened upwards by doubling until it holds the
    force; Newton starts at its top. F is nearly a power of delta: on 65 536 random pads and
    line loads every design's step was below 1e-12 of ln delta at the fifth evaluation, where
    bisection took 60 quadratures, the depths the same to 7e-16."""
    force, A, k, b, c, m = np.broadcast_arrays(
        *(np.asarray(v, dtype=float) for v in (force_N, A, k, b_mm, c_mm, m))
    )
    lo = np.full(A.shape, -30.0)  # ln delta: F(e^-30 mm) is far below any force asked for
    hi = np.log(np.maximum(b, 1e-3))
    for _ in range(40):  # widen upwards until F(e^hi) >= force
        short = pad_force(np.exp(hi), A, k, b, c, m) < force
        if not np.any(short):
            break
        hi = np.where(short, hi + np.log(2.0), hi)
    x = hi.copy()
    # a design with a non-finite input (a line load law of no meaning) has no depth to find:
    # it does not keep the others iterating
    hopeless = ~np.isfinite(force * A * k * b * c * m)
    for _ in range(iterations):
        F, slope = _force_and_log_slope(np.exp(x), A, k, b, c, m)
        below = F < force
        lo, hi = np.where(below, x, lo), np.where(below, hi, x)  # x is now one end
        with np.errstate(divide="ignore", invalid="ignore"):
            new = x + (np.log(force) - np.log(F)) / slope
        outside = ~np.isfinite(new) | (new < lo) | (new > hi)
        new = np.where(outside, 0.5 * (lo + hi), new)
        done = (np.abs(new - x) <= 1e-12) | hopeless
        x = new
        if np.all(done):
            break
    return np.exp(x)


def work_ratio(d1_mm, d4_mm, b_mm, c_mm, m) -> np.ndarray:
    """W_3D / W_2D: the work of pressing the pad to 4 N (slices) over the 2D model's to 4 N on
    its 10 mm, both with the power law through the 2D readings ``d1_mm``, ``d4_mm``."""
    A, k = line_load_law(d1_mm, d4_mm)
    depth = slice_depth(4.0, A, k, b_mm, c_mm, m)
    _, w, local = _slices(depth, b_mm, c_mm, m)
    w3 = 2.0 * A / (k + 1.0) * np.sum(w * local ** np.asarray(k + 1.0)[..., None], -1)
    w2 = LENGTH_2D_MM * A * np.asarray(d4_mm, dtype=float) ** (k + 1.0) / (k + 1.0)
    return w3 / w2


def overlap(depth_mm, a_mm, b_mm, n, c_mm, m) -> dict[str, np.ndarray]:
    """The plate's overlap with the undeformed pad pressed ``depth_mm`` from touch: ``area``
    (mm^2), ``length`` along the finger and ``width`` across it (mm)."""
    u, w, local = _slices(depth_mm, b_mm, c_mm, m)
    a, b, e = (np.asarray(v, dtype=float)[..., None] for v in (a_mm, b_mm, n))
    s = _profile(u, np.asarray(m, dtype=float)[..., None])
    with np.errstate(divide="ignore", invalid="ignore"):
        cut = np.where(s > 0.0, np.clip(1.0 - local / (b * s), 0.0, 1.0), 1.0)
    width = 2.0 * a * s * (1.0 - cut**e) ** (1.0 / e)
    return {
        "area": 2.0 * np.sum(w * width, -1),
        "length": 2.0 * np.asarray(c_mm, dtype=float) * _edge(depth_mm, b_mm, m),
        "width": _crest_width(depth_mm, a_mm, b_mm, n),
    }


def _crest_width(depth, a, b, n) -> np.ndarray:
    """w(0): the section at z = 0 cut ``depth`` below its crest."""
    depth, a, b, n = (np.asarray(v, dtype=float) for v in (depth, a, b, n))
    return 2.0 * a * (1.0 - np.clip(1.0 - depth / b, 0.0, 1.0) ** n) ** (1.0 / n)


_FROM_TOUCH = ("disp_at_1N_from_touch_mm", "disp_at_4N_from_touch_mm")
_FROM_TOP = ("disp_at_1N_mm", "disp_at_4N_mm")
#: what the slice model gives of a 3D metric: (quantity, force in N, the 2D model's pair of
#: displacements at 1 N and 4 N it starts from). The displacements from the undeformed top take
#: the 2D pair from the undeformed top; the work (the hysteresis scales with it) and the patch
#: the pair from touch, the plate's depth beyond the pad's first touch.
SLICE_METRICS: dict[str, tuple[str, float, tuple[str, str]]] = {
    "disp_at_1N_mm": ("depth", 1.0, _FROM_TOP),
    "disp_at_4N_mm": ("depth", 4.0, _FROM_TOP),
    "disp_at_1N_from_touch_mm": ("depth", 1.0, _FROM_TOUCH),
    "disp_at_4N_from_touch_mm": ("depth", 4.0, _FROM_TOUCH),
    "hysteresis_Nmm": ("work", 4.0, _FROM_TOUCH),
    **{
        f"contact_{what}_at_{f}N_{unit}": (what, float(f), _FROM_TOUCH)
        for f in (1, 4)
        for what, unit in (("area", "mm2"), ("width", "mm"), ("length", "mm"))
    },
}
#: the pad's parameters the slice model reads (``geometry.<name>``)
PAD = ("half_width_mm", "height_mm", "exponent", "half_length_mm", "length_exponent")


def slice_values(
    two: Mapping[str, np.ndarray], pad: Mapping[str, np.ndarray], metrics: Iterable[str]
) -> dict[str, np.ndarray]:
    """The slice model's value of each of ``metrics`` (those of ``SLICE_METRICS``) from the 2D
    model's values ``two`` (its displacement pairs; the 2D hysteresis for the hysteresis) and
    the pad ``pad`` (``PAD``'s keys), each (n,); NaN for a design whose 2D pair gives no power
    law (d_4 <= d_1, or d_1 <= 0) or one beyond floating point (d_4 within a hair of d_1: the
    exponent k = ln 4 / ln(d_4 / d_1) in the thousands, d_1^k overflowing; a search meets such
    pairs where the 2D surrogate extrapolates)."""
    with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
        out = _slice_values(two, pad, metrics)
    return {m: np.where(np.isfinite(v), v, np.nan) for m, v in out.items()}


def _slice_values(
    two: Mapping[str, np.ndarray], pad: Mapping[str, np.ndarray], metrics: Iterable[str]
) -> dict[str, np.ndarray]:
    out: dict[str, np.ndarray] = {}
    shape = (pad["height_mm"], pad["half_length_mm"], pad["length_exponent"])
    depths: dict[tuple, np.ndarray] = {}
    for m in metrics:
        what, force, pair = SLICE_METRICS[m]
        d1, d4 = (np.asarray(two[r], dtype=float) for r in pair)
        ok = (d4 > d1) & (d1 > 0)
        A, _ = line_load_law(np.where(ok, d1, 1.0), np.where(ok, d4, 2.0))
        ok &= np.isfinite(A) & (A > 0.0)  # d_1^k beyond floating point
        d1, d4 = np.where(ok, d1, 1.0), np.where(ok, d4, 2.0)
        if what == "work":
            value = np.asarray(two[m], dtype=float) * work_ratio(d1, d4, *shape)
        else:
            if (pair, force) not in depths:
                depths[pair, force] = slice_depth(force, *line_load_law(d1, d4), *shape)
            value = depths[pair, force]
            if what != "depth":
                value = overlap(value, pad["half_width_mm"], pad["height_mm"], pad["exponent"],
                                pad["half_length_mm"], pad["length_exponent"])[what]  # fmt: skip
        out[m] = np.where(ok, value, np.nan)
    return out
