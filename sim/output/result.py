"""Write a simulation result: JSON, PNG plots of the curves (and, in 3D, of the deformed pad),
deformed meshes as VTU."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ..geometry import _q2
from ..metrics import METRICS_3D
from ..options import SimOptions
from ..protocols.validity import compressive_log_strain, volume_ratio
from ..provenance import provenance, run_folder, write_json
from ..simulate import SimResult
from ._pad_figure import MIRRORS, STATES, PadFigureInfo, pad_figure_info, render_pad_figure

__all__ = [
    "PadFigureInfo",
    "curve_plot_data",
    "pad_figure_info",
    "render_pad_figure",
    "write_result",
    "write_vtu",
]


def curve_plot_data(result: Any, options: SimOptions | None = None) -> dict[str, dict[str, Any]]:
    """What each figure shows: x/y data, labels. Computed first, rendered by ``_render``.

    The forces are the whole fingertip's: in 2D the plane-strain section's force per mm times
    the protocol's out-of-plane length L (``length_mm`` of ``options``' protocol options,
    default ``SimOptions()``), which the labels state; in 3D the whole pad's (4 x the quarter
    model's), no length. The model is read from ``result.discretization`` (kept fields), else
    from ``options``, else from the metrics (a 3D result has the contact patch's)."""
    c = result.curves
    three_d = _is_3d(result, options)
    opts = options or SimOptions()

    def force_label(protocol: str) -> str:
        if three_d:
            return "force on the whole pad (N)"
        return f"force (N, plane strain × L = {getattr(opts, protocol).length_mm:g} mm)"

    model = "3D pad" if three_d else "plane strain"
    figs: dict[str, dict[str, Any]] = {}
    if "tapping" in c:
        figs["tapping"] = {
            "series": [("last tap", c["tapping"]["displacement_mm"], c["tapping"]["force_N"])],
            "xlabel": "plate displacement from the undeformed top (mm)",
            "ylabel": force_label("tapping"),
            "title": f"Tapping loop (quasi-steady state, {model})",
        }
    if "plate" in c:
        length = "" if three_d else f", L = {opts.plate.length_mm:g} mm"
        figs["plate"] = {
            "series": [("plate", c["plate"]["displacement_mm"], c["plate"]["force_N"])],
            "xlabel": "indentation from first touch (mm)",
            "ylabel": force_label("plate"),
            "title": f"Quasi-static plate indentation ({model}{length})",
        }
    if "wedge" in c:
        figs["wedge"] = {
            "series": [("wedge", c["wedge"]["time_s"], c["wedge"]["force_N"])],
            "xlabel": "time (s)",
            "ylabel": force_label("wedge"),
            "title": f"Wedge indentation: ramp 1 s, hold 100 s ({model})",
            "xscale": "symlog",
        }
    prof = [(k, c[k]) for k in ("profile_1s", "profile_100s") if k in c]
    if prof:
        figs["profile"] = {
            "series": [(k[8:], v["distance_mm"], v["deflection_mm"]) for k, v in prof],
            "xlabel": "distance from the wedge corner (mm)",
            "ylabel": "surface deflection, downward (mm)",
            "title": "Surface deflection under the wedge",
            "invert_y": True,
        }
    return figs


def _is_3d(result: Any, options: SimOptions | None) -> bool:
    """Whether ``result`` is the 3D model's (``curve_plot_data``)."""
    disc = getattr(result, "discretization", None)
    if disc is not None:
        return disc.dim == 3
    if options is not None:
        return options.dimension == "3d"
    return any(name in METRICS_3D for name in getattr(result, "metrics", {}))


def _render(figs: dict[str, dict[str, Any]], folder: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    for name, info in figs.items():
        fig, ax = plt.subplots(figsize=(5.5, 4))
        for label, x, y in info["series"]:
            ax.plot(x, y, ".-", ms=3, label=label)
        ax.set_xlabel(info["xlabel"])
        ax.set_ylabel(info["ylabel"])
        ax.set_title(info["title"])
        if info.get("xscale") == "symlog":
            ax.set_xscale("symlog", linthresh=1.0)
        if info.get("invert_y"):
            ax.invert_yaxis()
        ax.grid(alpha=0.3)
        if len(info["series"]) > 1:
            ax.legend()
        fig.tight_layout()
        fig.savefig(folder / f"{name}.png", dpi=120)
        plt.close(fig)


def write_vtu(result: SimResult, folder: Path, whole_pad: bool = True) -> list[Path]:
    """The deformed mesh of each kept field (``deformed_<field>.vtu``: each protocol's final
    state and the tapping's ``tapping_1N``, ``tapping_4N``) for ParaView, with the point data
    ``displacement_mm`` and, per cell, its ``layer`` and, over its quadrature points, its
    largest ``compressive_log_strain`` and smallest ``J`` (the quantities ``sim.protocols.validity``
    limits, in that state). Nothing unless the result kept its fields
    (``simulate(..., keep_fields=True)``).

    2D: the half section's P2 triangles (``triangle6``, z = 0), as modelled. 3D: the 27-node
    hexahedra (``hexahedron27``: VTK_TRIQUADRATIC_HEXAHEDRON, the order ``sim.geometry._q2`` uses,
    which meshio writes as it is); by default (``whole_pad``) the whole pad, the quarter model
    mirrored across x = 0 and z = 0 into four copies (the mirrored displacement components flipped,
    the nodes on the symmetry planes shared, every cell positively oriented), which is what a person
    opening the file expects to see; ``whole_pad=False``: the quarter alone."""
    import meshio

    if result.discretization is None:
        return []
    paths, mirrors = [], {}
    for name, u in result.fields.items():
        # the wedge's field on its own mesh (a band along its edge) is written on that mesh
        disc = result.field_discretizations.get(name, result.discretization)
        if disc.dim == 3:
            cell_type, cells, layer = "hexahedron27", disc.conn, disc.layer
        else:  # (n_el, 6): 3 vertices then midsides of edges 01, 12, 02
            cell_type, cells = "triangle6", disc.edofs_scalar
            layer = np.concatenate(
                [np.full(sl.stop - sl.start, k) for k, sl in enumerate(disc.slices)]
            )
        layer = np.asarray(layer, dtype=np.int32)
        if id(disc) not in mirrors:
            mirrors[id(disc)] = _mirror_map(disc, cells) if disc.dim == 3 and whole_pad else None
        mirror = mirrors[id(disc)]
        F = disc.material_deformation_gradient(u)  # the strains the laws see
        cell_data = {
            "layer": layer,
            "compressive_log_strain": compressive_log_strain(F).max(axis=1),
            "J": volume_ratio(F).min(axis=1),
        }
        if disc.dim == 2:
            pts = np.column_stack([disc.X + u, np.zeros(disc.n_nodes)])
            disp = np.column_stack([u, np.zeros(disc.n_nodes)])
            mesh_cells = cells
        elif mirror is None:
            pts, disp, mesh_cells = disc.X + u, u, cells
        else:
            pts, disp = mirror.points(disc.X + u), mirror.points(u)
            mesh_cells = mirror.cells
            cell_data = {k: np.tile(v, len(mirror.copies)) for k, v in cell_data.items()}
        mesh = meshio.Mesh(
            pts,
            [(cell_type, mesh_cells)],
            point_data={"displacement_mm": disp},
            cell_data={k: [v] for k, v in cell_data.items()},
        )
        path = folder / f"deformed_{name}.vtu"
        meshio.write(path, mesh)
        paths.append(path)
    return paths


@dataclass(frozen=True, eq=False)
class _Mirror:
    """The quarter mesh's four mirror copies as one mesh (``write_vtu``): ``source[j]`` is
    the quarter's node of whole-pad node j and ``signs[j]`` its copy's (x, y, z) signs;
    ``cells`` (4 E, 27) the copies' cells, in the order of ``copies`` (``MIRRORS``; on the
    half pad, an inclined plate's model, its first two: the mirror across x = 0 alone)."""

    source: np.ndarray
    signs: np.ndarray
    cells: np.ndarray
    copies: tuple[tuple[float, float], ...] = MIRRORS

    def points(self, v: np.ndarray) -> np.ndarray:
        """The whole pad's (N', 3) values of the quarter's nodal vectors ``v`` (N, 3)."""
        return v[self.source] * self.signs


def _mirror_map(disc: Any, cells: np.ndarray) -> _Mirror:
    """Mirror the quarter (nodes on the planes x = 0, z = 0: ``pmesh.sym_x``, ``sym_z``) into
    the whole pad: a copy's node on a plane it is mirrored across is the node of the copy it
    comes from, numbered once. A copy mirrored once is turned inside out; its cells' local
    nodes are then reflected (xi -> -xi), so every cell keeps a positive Jacobian."""
    n = disc.n_nodes
    on = {0: np.zeros(n, dtype=bool), 2: np.zeros(n, dtype=bool)}
    on[0][disc.pmesh.sym_x] = True
    on[2][disc.pmesh.sym_z] = True
    reflected = _q2.REFERENCE_POINTS * np.array([-1.0, 1.0, 1.0])
    flip = np.array(
        [np.flatnonzero(np.all(_q2.REFERENCE_POINTS == r, axis=1))[0] for r in reflected]
    )
    ids: dict[tuple[float, float], np.ndarray] = {}
    source, signs, all_cells = [], [], []
    count = 0
    copies = MIRRORS[:2] if getattr(disc, "half", False) else MIRRORS
    for sx, sz in copies:
        index = np.empty(n, dtype=np.int64)
        new = np.ones(n, dtype=bool)
        for mirrored, (tx, tz) in (
            (on[0] & on[2], (1.0, 1.0)),
            (on[0] & ~on[2], (1.0, sz)),
            (~on[0] & on[2], (sx, 1.0)),
        ):
            if (tx, tz) != (sx, sz):  # shared with the copy (tx, tz), numbered before
                index[mirrored] = ids[(tx, tz)][mirrored]
                new &= ~mirrored
        index[new] = count + np.arange(int(new.sum()))
        count += int(new.sum())
        ids[(sx, sz)] = index
        source.append(np.flatnonzero(new))
        signs.append(np.tile([sx, 1.0, sz], (int(new.sum()), 1)))
        c = index[cells]
        all_cells.append(c[:, flip] if sx * sz < 0 else c)
    return _Mirror(np.concatenate(source), np.concatenate(signs), np.concatenate(all_cells), copies)


def write_result(
    result: SimResult, out: str | Path, options: SimOptions, catalogues: Sequence[Any] = ()
) -> Path:
    """Create the run folder ``out`` with result.json, meta.json, figures/ and VTU meshes;
    for a 3D result with the tapping's states at 1 N / 4 N also figures/pad.png, the deformed
    pad and its contact patch (``sim.output._pad_figure``).

    ``catalogues``: the ``--catalogue`` files used (``sim.materials.UserCatalogue``), recorded
    with their sha256 in meta.json (the design holds their materials' tables in full)."""
    with run_folder(out) as tmp:
        write_json(tmp / "result.json", result.to_json())
        config = {"design": result.design.to_dict(), "options": options.as_dict()}
        if catalogues:
            config["catalogues"] = [c.record() for c in catalogues]
        write_json(tmp / "meta.json", provenance(config, kind="simulate"))
        figures = tmp / "figures"
        figures.mkdir()
        _render(curve_plot_data(result, options), figures)
        write_vtu(result, tmp)
        if _has_pad_states(result):
            render_pad_figure(pad_figure_info(result), figures / "pad.png")
    return Path(out)


def _has_pad_states(result: SimResult) -> bool:
    """A 3D result with a tapping state the pad figure draws (``sim.output._pad_figure.STATES``):
    the quarter model's, or the half pad's (an inclined plate: the figure mirrors it across
    x = 0 and views the footprint along the plate's normal)."""
    disc = result.discretization
    return (
        disc is not None
        and disc.dim == 3
        and "tapping" in result.curves
        and any(name in result.fields for name, _ in STATES)
    )
