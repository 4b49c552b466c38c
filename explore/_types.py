"""The data that flows through a search run (candidate -> confirmation -> summary).

The run folder these are written to and read from, file by file, is ``explore._run_folder``'s.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

from sim.provenance import finite_or_none, json_safe

__all__ = ["Candidate", "Confirmation", "Summary"]


@dataclass(frozen=True)
class Candidate:
    """A design proposed by the search for FE confirmation.

    ``point``: the design-space point (parameter name -> value; inactive = NaN or "").
    ``reason``: why it was chosen — "best" (among the lowest predicted scores),
    "uncertain" (promising but with a wide predictive interval) or "buildable" (best of the
    catalogue-only search). ``predicted``: metric -> {"median", "mean", "std", "lower_90",
    "upper_90"} in the metric's unit, and "by_rule" (exact by physics, e.g. an elastic design's
    hysteresis: 0). ``score``: predicted closeness (explore._objective, lower is better).
    ``disagreement``: the largest relative ensemble spread std/|mean| over the scored metrics.
    ``flags``: trust-guard notes ("out of domain: ...", "high disagreement 0.12 > 0.05").
    """

    point: dict[str, Any]
    reason: str
    round: int
    trial: int
    search: str
    score: float
    predicted: dict[str, dict[str, float | None]]
    in_domain: bool
    disagreement: float
    flags: tuple[str, ...] = ()

    @property
    def trusted(self) -> bool:
        return not self.flags

    def to_json(self) -> dict[str, Any]:
        return {
            "point": json_safe(self.point),
            "reason": self.reason,
            "round": self.round,
            "trial": self.trial,
            "search": self.search,
            "score": finite_or_none(self.score),
            "predicted": self.predicted,
            "in_domain": self.in_domain,
            "disagreement": finite_or_none(self.disagreement),
            "flags": list(self.flags),
            "trusted": self.trusted,
        }

    @classmethod
    def from_json(cls, d: dict[str, Any]) -> Candidate:
        point = {k: (math.nan if v is None else v) for k, v in d["point"].items()}
        return cls(
            point=point,
            reason=d["reason"],
            round=int(d["round"]),
            trial=int(d["trial"]),
            search=d["search"],
            score=math.inf if d["score"] is None else float(d["score"]),
            predicted=d["predicted"],
            in_domain=bool(d["in_domain"]),
            disagreement=math.nan if d["disagreement"] is None else float(d["disagreement"]),
            flags=tuple(d.get("flags", ())),
        )


@dataclass(frozen=True)
class Confirmation:
    """A candidate re-run with full FE and compared with its prediction.

    ``key``: the FE record (``fe/records/<key>.json``); ``status``: "ok" | "failed";
    ``fe_metrics``: metric -> value (None: not reached / failed), the names of
    ``fingertip simulate --json``; ``fe_score``: closeness of the FE metrics;
    ``rel_error``: metric -> (surrogate median - FE) / |FE|; ``inside_90``: metric -> whether the
    FE value lies in the predicted 90 % interval.
    """

    candidate: Candidate
    key: str
    status: str
    reason: str
    fe_metrics: dict[str, float | None]
    fe_score: float
    rel_error: dict[str, float | None] = field(default_factory=dict)
    inside_90: dict[str, bool | None] = field(default_factory=dict)
    diagnostics: dict[str, Any] = field(default_factory=dict)

    @property
    def trusted(self) -> bool:
        """The FE result can be an answer: it ran, its taps reached the periodic state and its
        deformation stayed within the validity limits (``sim.SimResult.diagnostics``). A record
        from before these were stored is taken as it is."""
        d = self.diagnostics
        return self.status == "ok" and d.get("settled") is not False and d.get("valid") is not False

    def to_json(self) -> dict[str, Any]:
        return {
            "candidate": self.candidate.to_json(),
            "key": self.key,
            "status": self.status,
            "reason": self.reason,
            "fe_metrics": {k: finite_or_none(v) for k, v in self.fe_metrics.items()},
            "fe_score": finite_or_none(self.fe_score),
            "rel_error": {k: finite_or_none(v) for k, v in self.rel_error.items()},
            "inside_90": self.inside_90,
            "diagnostics": self.diagnostics,
            "trusted": self.trusted,
        }

    @classmethod
    def from_json(cls, d: dict[str, Any]) -> Confirmation:
        return cls(
            candidate=Candidate.from_json(d["candidate"]),
            key=d["key"],
            status=d["status"],
            reason=d.get("reason", ""),
            fe_metrics=d["fe_metrics"],
            fe_score=math.inf if d["fe_score"] is None else float(d["fe_score"]),
            rel_error=d.get("rel_error", {}),
            inside_90=d.get("inside_90", {}),
            diagnostics=d.get("diagnostics", {}),
        )


@dataclass(frozen=True)
class Summary:
    """The answer of a run: the best FE-confirmed design and the best buildable one.

    Each entry of ``answers`` ("best", "buildable") is a dict with ``design`` (the design-file
    form, ``sim.Design.to_dict()``), ``point``, ``predicted`` (mean/std/lower_90/upper_90 per
    metric), ``fe_metrics`` (as ``fingertip simulate --json``), ``fe_score``, ``errors_vs_targets``
    (relative error per tapping target, FE) and ``within_tolerance`` (per target, bool), or None
    when no design of that kind was confirmed. ``targets``: the target values; ``notes``: what
    was missed and why. ``timing``: how long the invocation that wrote summary.json took
    (``wall_time_s``, ``timings``, ``resumed``: ``explore._run_folder.write_summary``; a
    finished run re-run keeps the first one); empty until it is written, and not part of
    ``to_json`` (the answer).
    """

    answers: dict[str, dict[str, Any] | None]
    targets: dict[str, float]
    tolerance: float
    rounds: list[dict[str, Any]]
    notes: list[str]
    timing: dict[str, Any] = field(default_factory=dict)

    def to_json(self) -> dict[str, Any]:
        return {
            "answers": self.answers,
            "targets": self.targets,
            "tolerance": self.tolerance,
            "rounds": self.rounds,
            "notes": self.notes,
        }
