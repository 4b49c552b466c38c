"""Evaluation on the held-out test designs: accuracy, calibration, parity plots, speed.

The plotted data (``ParityData``) is computed first and rendered separately, so the numbers in
report.json are exactly those in the figures.
"""

from __future__ import annotations

import math
import os
import platform
import time
from collections.abc import Sequence
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np
import torch

from sim.provenance import json_safe, json_text

from ._surrogate import Surrogate
from ._train import r2_score

__all__ = [
    "REL_FLOOR",
    "MetricScore",
    "ParityData",
    "Report",
    "Speed",
    "TrustScore",
    "evaluate",
    "inference_speed",
    "parity_data",
]

#: relative errors are taken over designs with |FE| >= REL_FLOOR x median |FE| (see MetricScore)
REL_FLOOR = 0.01


@dataclass(frozen=True)
class MetricScore:
    """Test-set accuracy of one metric (``n`` designs with a finite FE value).

    ``median_rel_error`` / ``p95_rel_error``: |prediction - FE| / |FE| (fractions) over the
    ``n_rel`` designs whose |FE| is at least ``REL_FLOOR`` x the median |FE| (a relative error
    of a value that is zero up to round-off, e.g. the hysteresis of an elastic skin, means
    nothing; those designs still count in R²); ``coverage_90``: fraction of FE values inside
    the predicted central 90 % interval (0.90 for a calibrated model) over the ``n`` - ``n_rule``
    designs whose value is learnt; ``n_rule``: designs whose value is exact by physics (an
    elastic design's hysteresis is 0, ``ZERO_IF_ELASTIC``), which count in R² and RMSE.
    """

    name: str
    unit: str
    n: int
    r2: float
    median_rel_error: float
    p95_rel_error: float
    coverage_90: float
    rmse: float
    n_rel: int
    n_rule: int = 0


@dataclass(frozen=True, eq=False)
class ParityData:
    """FE value vs predicted mean and 90 % interval of one metric on the test designs."""

    metric: str
    unit: str
    fe: np.ndarray
    mean: np.ndarray
    lower_90: np.ndarray
    upper_90: np.ndarray
    in_domain: np.ndarray
    by_rule: np.ndarray | None = None  # True where the prediction is exact by rule


@dataclass(frozen=True)
class Speed:
    """Batched inference throughput on this machine, in designs per second.

    ``model_designs_per_s``: encoded features -> mean/std in metric units;
    ``end_to_end_designs_per_s``: a table of design points -> ``Prediction`` (with encoding and
    the domain check); on ``torch_threads`` threads and on one thread (``*_1_thread``), which is
    faster when other processes keep the cores busy. ``load_average_1min``: the machine's load
    when measured (compare with ``cpu_count``).
    """

    n_designs: int
    model_designs_per_s: float
    end_to_end_designs_per_s: float
    torch_threads: int
    model_designs_per_s_1_thread: float
    end_to_end_designs_per_s_1_thread: float
    machine: str
    cpu_count: int
    load_average_1min: float


@dataclass(frozen=True)
class TrustScore:
    """How well the surrogate's trust outputs (``sim.protocols.trust``) tell a credible FE result
    from one that is not, on the ``n`` test designs where FE says either: ``accuracy`` of the
    predicted flag (valid and settled, the default limits), the fraction of FE-untrusted designs
    predicted trusted (``false_trusted``: the costly mistake, a search would go there) and of
    FE-trusted ones predicted untrusted (``false_untrusted``: the search would miss them), and the
    FE-untrusted fraction (``untrusted_fraction``)."""

    n: int
    accuracy: float
    false_trusted: float
    false_untrusted: float
    untrusted_fraction: float


@dataclass(frozen=True, eq=False)
class Report:
    scores: tuple[MetricScore, ...]
    parity: tuple[ParityData, ...]
    speed: Speed
    n_test: int
    in_domain_fraction: float
    trust: TrustScore | None = None

    def to_dict(self) -> dict[str, Any]:
        return json_safe(
            {
                "n_test": self.n_test,
                "in_domain_fraction": self.in_domain_fraction,
                "metrics": {s.name: asdict(s) for s in self.scores},
                "trust": None if self.trust is None else asdict(self.trust),
                "speed": asdict(self.speed),
            }
        )


def score(p: ParityData) -> MetricScore:
    ok = np.isfinite(p.fe) & np.isfinite(p.mean)
    fe, mean = p.fe[ok], p.mean[ok]
    n = int(ok.sum())
    if n == 0:
        nan = math.nan
        return MetricScore(p.metric, p.unit, 0, nan, nan, nan, nan, nan, 0)
    big = np.abs(fe) >= REL_FLOOR * np.median(np.abs(fe))
    with np.errstate(divide="ignore", invalid="ignore"):
        rel = np.abs(mean[big] - fe[big]) / np.abs(fe[big])
    rel = rel[np.isfinite(rel)]
    learnt = ~p.by_rule[ok] if p.by_rule is not None else np.ones(n, dtype=bool)
    inside = (fe >= p.lower_90[ok]) & (fe <= p.upper_90[ok])
    inside = inside[learnt]
    return MetricScore(
        p.metric,
        p.unit,
        n,
        r2_score(fe, mean),
        float(np.median(rel)) if rel.size else math.nan,
        float(np.percentile(rel, 95)) if rel.size else math.nan,
        float(inside.mean()) if inside.size else math.nan,
        float(np.sqrt(np.mean((mean - fe) ** 2))),
        int(rel.size),
        int(n - learnt.sum()),
    )


def inference_speed(
    surrogate: Surrogate, points: list[dict], n: int = 65536, repeats: int = 3
) -> Speed:
    """Best-of-``repeats`` throughput on ``n`` designs tiled from ``points``."""
    reps = -(-n // max(len(points), 1))
    table = {name: ([p[name] for p in points] * reps)[:n] for name in surrogate.space.names}
    features = surrogate.encoder.encode(table).features

    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else math.nan

    def best(fn) -> float:
        fn()  # warm-up
        times = []
        for _ in range(repeats):
            t0 = time.perf_counter()
            fn()
            times.append(time.perf_counter() - t0)
        return n / min(times)

    def model() -> None:
        surrogate.predict_features(features)

    def end_to_end() -> None:
        surrogate.predict(table)

    threads = torch.get_num_threads()
    fast = (best(model), best(end_to_end))
    torch.set_num_threads(1)  # also on one thread (restored below): a loaded machine's view
    try:
        single = (best(model), best(end_to_end)) if threads > 1 else fast
    finally:
        torch.set_num_threads(threads)
    return Speed(
        n_designs=n,
        model_designs_per_s=fast[0],
        end_to_end_designs_per_s=fast[1],
        torch_threads=threads,
        model_designs_per_s_1_thread=single[0],
        end_to_end_designs_per_s_1_thread=single[1],
        machine=f"{platform.machine()} {platform.processor() or ''}".strip(),
        cpu_count=os.cpu_count() or 0,
        load_average_1min=load,
    )


def parity_data(
    surrogate: Surrogate, points: list[dict], targets: np.ndarray
) -> tuple[ParityData, ...]:
    """Per metric: FE values against the surrogate's point prediction (the median) and its
    90 % interval, on ``points`` with FE metrics ``targets`` (n, n_metrics; NaN = missing)."""
    pred = surrogate.predict(points)
    return tuple(
        ParityData(
            m,
            surrogate.units[j],
            targets[:, j],
            pred.median[:, j],
            pred.lower_90[:, j],
            pred.upper_90[:, j],
            pred.in_domain,
            pred.by_rule[:, j],
        )
        for j, m in enumerate(surrogate.metric_names)
    )


def trust_score(parity: Sequence[ParityData]) -> TrustScore | None:
    """The ``TrustScore`` of the trust outputs' parity data (None without trust outputs)."""
    from sim.protocols import TRUST_OUTPUTS, TappingOptions, ValidityOptions, trust_flags

    by_name = {p.metric: p for p in parity if p.metric in TRUST_OUTPUTS}
    if not by_name:
        return None

    def flags(field: str) -> np.ndarray:
        # the FE's and the surrogate's figures under the same thresholds: an agreement score, not
        # a verdict, so the designs' materials are not needed (their largest strain is held to
        # the paper's 0.60, ``sim.protocols.strain_limit_of``)
        values = {m: getattr(p, field) for m, p in by_name.items()}
        f = trust_flags(values, ValidityOptions(), TappingOptions())
        return f["valid"] & f["settled"]

    fe_known = np.any([np.isfinite(p.fe) for p in by_name.values()], axis=0)
    fe_ok, pred_ok = flags("fe")[fe_known], flags("mean")[fe_known]
    n = int(fe_known.sum())
    if n == 0:
        return TrustScore(0, math.nan, math.nan, math.nan, math.nan)

    def frac(mask: np.ndarray) -> float:
        return float(mask.mean()) if mask.size else math.nan

    return TrustScore(
        n,
        frac(fe_ok == pred_ok),
        frac(pred_ok[~fe_ok]),
        frac(~pred_ok[fe_ok]),
        frac(~fe_ok),
    )


def evaluate(
    surrogate: Surrogate, points: list[dict], targets: np.ndarray, *, speed_n: int = 65536
) -> Report:
    """Score ``surrogate`` on held-out designs (points + FE metrics, NaN = missing)."""
    parity = parity_data(surrogate, points, targets)
    return Report(
        tuple(score(p) for p in parity),
        parity,
        inference_speed(surrogate, points, speed_n),
        len(points),
        float(parity[0].in_domain.mean()) if len(points) and parity else math.nan,
        trust_score(parity),
    )


def render_parity(p: ParityData, path: Path) -> None:
    """Parity plot: predicted mean with its 90 % interval against the FE value."""
    from matplotlib.figure import Figure

    fig = Figure(figsize=(4.2, 4.0), layout="constrained")
    ax = fig.add_subplot()
    ok = np.isfinite(p.fe) & np.isfinite(p.mean)
    if ok.any():
        fe, mean = p.fe[ok], p.mean[ok]
        err = np.vstack([mean - p.lower_90[ok], p.upper_90[ok] - mean]).clip(min=0)
        dom = p.in_domain[ok]
        for sel, colour, label in ((dom, "C0", "in domain"), (~dom, "C3", "out of domain")):
            if sel.any():
                ax.errorbar(
                    fe[sel],
                    mean[sel],
                    yerr=err[:, sel],
                    fmt="o",
                    ms=3,
                    color=colour,
                    elinewidth=0.6,
                    alpha=0.8,
                    label=label,
                )
        lo, hi = float(min(fe.min(), mean.min())), float(max(fe.max(), mean.max()))
        pad = 0.05 * (hi - lo or 1.0)
        ax.plot([lo - pad, hi + pad], [lo - pad, hi + pad], "k--", lw=0.8)
        ax.legend(fontsize=7, loc="upper left")
    unit = f" [{p.unit}]" if p.unit else ""
    ax.set_xlabel(f"FE{unit}")
    ax.set_ylabel(f"surrogate (mean, 90 % interval){unit}")
    sc = score(p)
    ax.set_title(
        f"{p.metric}: R² {_fmt(sc.r2, '.3f')}, {_fmt(100 * sc.coverage_90, '.0f')} % "
        f"in 90 % interval (n = {sc.n})",
        fontsize=8,
    )
    fig.savefig(path, dpi=110)


def _fmt(x: float, spec: str) -> str:
    return "–" if not math.isfinite(x) else format(x, spec)


def _excluded_line(info: dict[str, Any]) -> str:
    """Which designs of the sweep the surrogate did not learn from, and why."""
    excluded = info.get("excluded") or {}
    parts = [f"{n} {why}" for why, n in sorted(excluded.items())]
    text = (
        f"Left out (FE results not trusted): {', '.join(parts)}."
        if parts
        else "Left out: none (every design with FE results reached its periodic state and "
        "stayed within the validity limits)."
    )
    if parts:
        text += " Their trust outputs (why they are not trusted) are learnt all the same"
        partial = info.get("partial") or 0
        text += (
            f"; so are the metrics of {partial} of them from the protocols whose own result "
            "is trusted (e.g. the taps of a design invalid only through the wedge)."
            if partial
            else "."
        )
    if info.get("unchecked"):
        text += (
            f" {info['unchecked']} designs come from a sweep that did not record these flags "
            "and were used unchecked."
        )
    return text


def _factors(info: dict[str, Any]) -> str:
    """``: factors 0.6 to 1.05`` from the checkpoint's calibration record, if any."""
    scale = (info.get("calibration") or {}).get("interval_scale") or {}
    values = [v for v in scale.values() if v != 1.0]
    return f": factors {min(values):.3g} to {max(values):.3g}" if values else ""


def write_report(report: Report, folder: Path, info: dict[str, Any]) -> None:
    """report.json, report.md and figures/parity_<metric>.png in ``folder``."""
    figures = folder / "figures"
    figures.mkdir(parents=True, exist_ok=True)
    for p in report.parity:
        render_parity(p, figures / f"parity_{p.metric}.png")
    data = {**json_safe(info), **report.to_dict()}
    (folder / "report.json").write_text(json_text(data, indent=1) + "\n")
    s = report.speed
    lines = [
        "# Surrogate evaluation",
        "",
        f"Held-out test designs: {report.n_test} "
        f"({_fmt(100 * report.in_domain_fraction, '.0f')} % inside the training domain). "
        f"Ensemble of {info.get('members', '?')} members, seed {info.get('seed', '?')}, "
        f"trained on {info.get('n_train', '?')} designs "
        f"(validation {info.get('n_val', '?')}), {info.get('epochs', '?')} epochs.",
        "",
        _excluded_line(info),
        "",
        "| metric | unit | n | R² | n rel. | median rel. error | 95th pct rel. error "
        "| n rule | in 90 % interval |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for sc in report.scores:
        lines.append(
            f"| {sc.name} | {sc.unit} | {sc.n} | {_fmt(sc.r2, '.3f')} | {sc.n_rel} | "
            f"{_fmt(100 * sc.median_rel_error, '.2f')} % | {_fmt(100 * sc.p95_rel_error, '.2f')} % "
            f"| {sc.n_rule} | {_fmt(100 * sc.coverage_90, '.0f')} % |"
        )
    t = report.trust
    if t is not None:
        lines += [
            "",
            f"Credibility (valid and settled at the default limits, from the trust outputs) on "
            f"{t.n} test designs, {_fmt(100 * t.untrusted_fraction, '.0f')} % of them not "
            f"credible by FE: {_fmt(100 * t.accuracy, '.1f')} % predicted right; "
            f"{_fmt(100 * t.false_trusted, '.1f')} % of the FE-untrusted designs predicted "
            f"credible, {_fmt(100 * t.false_untrusted, '.1f')} % of the FE-credible ones "
            "predicted not.",
        ]
    lines += [
        "",
        f"Inference ({s.n_designs} designs batched, {s.torch_threads} torch threads, "
        f"{s.machine}, {s.cpu_count} CPUs, load average {s.load_average_1min:.1f} when "
        f"measured): {s.model_designs_per_s:,.0f} designs/s from encoded features, "
        f"{s.end_to_end_designs_per_s:,.0f} designs/s from a table of design points; on "
        f"1 thread {s.model_designs_per_s_1_thread:,.0f} and "
        f"{s.end_to_end_designs_per_s_1_thread:,.0f} designs/s.",
        "",
        "Parity plots: `figures/parity_<metric>.png`. Relative errors are |pred - FE| / |FE| "
        f"over the designs with |FE| >= {REL_FLOOR:g} x the median |FE| (n rel. in the table; "
        "e.g. an elastic skin's hysteresis is zero up to round-off); the 90 % interval is the "
        "ensemble's (mixture mean ± 1.645 std in the normalised space: log, or log(y + offset) "
        "for a nonnegative metric that reaches zero), its std multiplied per metric by the "
        f"factor calibrated on the validation designs (split conformal{_factors(info)}). The "
        "hysteresis of an elastic design (no "
        "layer relaxes) is 0 by physics: the surrogate predicts it exactly, does not learn it, "
        "and those designs (n rule) are left out of the coverage.",
        "",
    ]
    (folder / "report.md").write_text("\n".join(lines))
