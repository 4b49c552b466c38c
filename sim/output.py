"""Write a simulation result: JSON, PNG plots of the curves, deformed meshes as VTU."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from .options import SimOptions
from .provenance import provenance, run_folder, write_json
from .simulate import SimResult
from .validity import compressive_log_strain, volume_ratio

__all__ = ["curve_plot_data", "write_result"]


def curve_plot_data(result: SimResult) -> dict[str, dict[str, Any]]:
    """What each figure shows: x/y data, labels. Computed first, rendered by ``_render``."""
    c = result.curves
    figs: dict[str, dict[str, Any]] = {}
    if "tapping" in c:
        figs["tapping"] = {
            "series": [("last tap", c["tapping"]["displacement_mm"], c["tapping"]["force_N"])],
            "xlabel": "plate displacement from the undeformed top (mm)",
            "ylabel": "force (N)",
            "title": "Tapping loop (quasi-steady state)",
        }
    if "plate" in c:
        figs["plate"] = {
            "series": [("plate", c["plate"]["displacement_mm"], c["plate"]["force_N"])],
            "xlabel": "indentation from first touch (mm)",
            "ylabel": "force (N)",
            "title": "Quasi-static plate indentation (L = 22 mm)",
        }
    if "wedge" in c:
        figs["wedge"] = {
            "series": [("wedge", c["wedge"]["time_s"], c["wedge"]["force_N"])],
            "xlabel": "time (s)",
            "ylabel": "force (N)",
            "title": "Wedge indentation: ramp 1 s, hold 100 s",
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


def write_vtu(result: SimResult, folder: Path) -> list[Path]:
    """The deformed P2 mesh at the end of each protocol (triangle6 cells) for ParaView, with
    each cell's layer and, over its quadrature points, its largest compressive log strain and
    smallest J (the quantities ``sim.validity`` limits, in that final state). Nothing unless
    the result kept its fields (``simulate(..., keep_fields=True)``)."""
    import meshio

    disc = result.discretization
    if disc is None:
        return []
    cells = disc.edofs_scalar  # (n_el, 6): 3 vertices then midsides of edges 01, 12, 02
    layer = np.concatenate(
        [np.full(sl.stop - sl.start, k) for k, sl in enumerate(disc.slices)]
    ).astype(np.int32)
    paths = []
    for name, u in result.fields.items():
        pts = np.column_stack([disc.X + u, np.zeros(disc.n_nodes)])
        disp = np.column_stack([u, np.zeros(disc.n_nodes)])
        F = disc.deformation_gradient(u)
        strain = compressive_log_strain(F).max(axis=1)
        J = volume_ratio(F).min(axis=1)
        mesh = meshio.Mesh(
            pts,
            [("triangle6", cells)],
            point_data={"displacement_mm": disp},
            cell_data={
                "layer": [layer],
                "compressive_log_strain": [strain],
                "J": [J],
            },
        )
        path = folder / f"deformed_{name}.vtu"
        meshio.write(path, mesh)
        paths.append(path)
    return paths


def write_result(
    result: SimResult, out: str | Path, options: SimOptions, catalogues: Sequence[Any] = ()
) -> Path:
    """Create the run folder ``out`` with result.json, meta.json, figures/ and VTU meshes.

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
        _render(curve_plot_data(result), figures)
        write_vtu(result, tmp)
    return Path(out)
