"""A simulation's folder (``fingertip simulate --out``): ``result.json``, the curves' plots, the
deformed 3D pad and its contact patch (``_pad_figure``), deformed meshes as VTU (``result``)."""

from .result import (
    PadFigureInfo,
    curve_plot_data,
    pad_figure_info,
    render_pad_figure,
    write_result,
    write_vtu,
)

__all__ = [
    "PadFigureInfo",
    "curve_plot_data",
    "pad_figure_info",
    "render_pad_figure",
    "write_result",
    "write_vtu",
]
