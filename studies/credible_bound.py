"""For docs/search.md ("Credible at the interval's bound"): a search run's FE confirmations
judged again as the search judged them, on the median and on the bound.

    python studies/credible_bound.py RUN [RUN ...]

For every FE-confirmed candidate of each search run folder (``confirmations.json``) it takes
the surrogate's predictions the candidate was chosen on (median, 90 % interval) and asks the
search's own credibility rule (``explore._objective.infeasibility`` on
``explore._search._judged``, each layer held to its material's tested limit, the run's
validity options and targets) whether the candidate was credible judged on the median (the
default, ``--credible-at median``) and on the side of each interval towards its limit
(``--credible-at bound``), and sets both against the FE's verdict (the record's ``valid``
and ``settled``, and the sag against the targets' limit). It prints a table per run and the
counts: how many candidates that came back from FE not credible each rule would have sent,
and how many credible ones it would have kept. It judges candidates the median rule chose;
a search run with ``bound`` chooses others (further from the limits).
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from explore._objective import infeasibility, point_layer_limits
from explore._plots import load_run, run_options, run_targets
from explore._run_folder import read_confirmations
from explore._search import _judged
from explore._summary import credible


class _Prediction:
    """The candidates' stored predictions as the arrays of a ``surrogate.Prediction``."""

    def __init__(self, predicted: list[dict]) -> None:
        self.metric_names = list(predicted[0])

        def column(key: str) -> np.ndarray:
            rows = [[p[m].get(key) for m in self.metric_names] for p in predicted]
            return np.array([[np.nan if v is None else v for v in row] for row in rows])

        self.median, self.mean = column("median"), column("mean")
        self.lower_90, self.upper_90 = column("lower_90"), column("upper_90")


def judge(run: Path) -> list[tuple[str, bool, bool, bool, str]]:
    """(candidate, credible on the median, on the bound, by FE, the bound's reason) of each
    confirmation of ``run``."""
    data = load_run(run)  # the run folder's config.json: its targets and FE options
    targets, options = run_targets(data), run_options(data)
    if targets is None:
        raise SystemExit(f"{run}: its config.json holds no targets")
    confirmations = read_confirmations(run)
    pred = _Prediction([c.candidate.predicted for c in confirmations])
    cols = {m: i for i, m in enumerate(pred.metric_names)}
    points = [c.candidate.point for c in confirmations]
    layers = point_layer_limits(points, None, options.validity)
    out = []
    verdicts = {}
    for bound in (False, True):
        penalty, why = infeasibility(_judged(pred, cols, bound), targets, options.validity,
                                     options.tapping, layer_limits=layers)  # fmt: skip
        verdicts[bound] = (penalty == 0, why)
    for i, c in enumerate(confirmations):
        label = f"round {c.candidate.round} {c.candidate.reason}"
        out.append((label, bool(verdicts[False][0][i]), bool(verdicts[True][0][i]),
                    credible(c, targets), str(verdicts[True][1][i])))  # fmt: skip
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("runs", type=Path, nargs="+", help="search run folders")
    args = ap.parse_args()
    counts = np.zeros((2, 2, 2), dtype=int)  # [rule][credible by the rule][credible by FE]
    for run in args.runs:
        rows = judge(run)
        print(f"\n{run}: {len(rows)} confirmations\n")
        print("| candidate | median: credible | bound: credible | FE: credible | bound: why not |")
        print("|---|---|---|---|---|")
        for label, median, bound, fe, why in rows:
            print(f"| {label} | {median} | {bound} | {fe} | {why} |")
            counts[0, int(median), int(fe)] += 1
            counts[1, int(bound), int(fe)] += 1
    for r, rule in enumerate(("median", "bound")):
        sent_bad = counts[r, 1, 0]
        kept_good, good = counts[r, 1, 1], counts[r, :, 1].sum()
        print(f"\n{rule}: would send {counts[r, 1].sum()} of the candidates to FE, "
              f"{sent_bad} of the {counts[r, :, 0].sum()} that FE found not credible; "
              f"keeps {kept_good} of the {good} that FE found credible")  # fmt: skip


if __name__ == "__main__":
    main()
