"""Recompute the compression checks behind ``sim/data/material_tests.toml``.

The compressive limits argued there for laws fitted to tension (and for the ``gel`` family) come
from one comparison: a law's uniaxial-compression curve against the measured compression curves
of Ecoflex silicones (Dawood et al., github.com/abubakardawood/tissue-phantom-material-database,
CC BY 4.0: 19 phantoms, Ecoflex 00-10/00-30/00-50 with 0-100 % thinner, 10 uniaxial compression
tests each, cylinders 50 mm x 30 mm, to 20 mm = 66.7 % nominal strain).  The data are not in
this repository; get them, then run::

    git clone https://github.com/abubakardawood/tissue-phantom-material-database dawood
    python studies/tested_ranges.py --dawood dawood

The criterion (``within``): the law's nominal stress, scaled by the one factor that minimises the
largest relative error (its modulus is a property of the batch and the lab, not of the strain
range: the catalogue's Marechal Ecoflex moduli are 2.4-4x below Dawood's for the same grades, and
below Steck et al.'s tensile one), stays within +-10 % of the mean of the 10 tests from 5 %
nominal strain up to the strain reported.  10 %: the agreement the paper accepted between its
model and its experiments (Cabibihan et al. §3.3).  5 %: below it the platens' seating toe of the
tests, not the law, dominates (Dawood's own compression fits miss it by up to 12 %).
Fast (190 small files, no simulation).
"""

from __future__ import annotations

import argparse
import io
import subprocess
from pathlib import Path

import numpy as np

from sim.materials import CATALOGUE
from sim.materials.fit import nominal_stress

COMMIT = "52b1271f0f8a966c168e5ddc0886190f12c6551f"
TOLERANCE = 0.10
STRAINS = np.append(np.round(np.arange(0.05, 0.6665, 0.005), 4), 0.6666)
#: the Ecoflex entries and the phantoms of the same product (no thinner, as Marechal's)
SAME_PRODUCT = {
    "ecoflex_0010_dawood": ("EF10_0T",),
    "ecoflex_0030_dawood": ("EF30_0T",),
    "ecoflex_0050_dawood": ("EF50_0T",),
    "ecoflex_0010_marechal": ("EF10_0T",),
    "ecoflex_0030_marechal": ("EF30_0T",),
    "ecoflex_0050_marechal": ("EF50_0T",),
    "ecoflex_0030_steck2019": ("EF30_0T",),
    # 00-35 FAST: no phantom of that grade; the two grades around it
    "ecoflex_0035_fast_marechal": ("EF30_0T", "EF50_0T"),
}
GEL_ALPHAS = np.round(np.arange(1.5, 4.0001, 0.05), 2)  # the gel family's alpha range


def _git(repo: Path, *args: str) -> str:
    return subprocess.run(
        ["git", "-C", str(repo), *args], check=True, capture_output=True, text=True
    ).stdout


def mean_curves(repo: Path, commit: str) -> dict[str, np.ndarray]:
    """Phantom -> mean engineering compressive stress (MPa, positive) of its tests at STRAINS."""
    names = _git(repo, "ls-tree", "-r", "--name-only", commit, "data/").split()
    files: dict[str, list[str]] = {}
    for name in names:
        if name.endswith(".csv"):
            files.setdefault(name.split("/")[1], []).append(name)
    out = {}
    for phantom, paths in sorted(files.items()):
        rows = []
        for path in paths:
            text = _git(repo, "show", f"{commit}:{path}")
            data = np.genfromtxt(io.StringIO(text), delimiter=",", skip_header=8)
            strain, stress = -data[:, 3], -data[:, 4] / 1000.0  # engineering, kPa -> MPa
            order = np.argsort(strain)
            rows.append(np.interp(STRAINS, strain[order], stress[order]))
        out[phantom] = np.mean(rows, axis=0)
    return out


def law_curve(model: str, params: dict, nu: float) -> np.ndarray:
    return -nominal_stress(model, params, "compression", -STRAINS, nu)


def within(ratio: np.ndarray, tol: float = TOLERANCE) -> float:
    """The largest strain up to which one factor brings ``ratio`` (law / data) within
    ``tol`` of 1 (minimax relative error over the prefix, which only grows with the strain)."""
    best = 0.0
    for i in range(len(STRAINS)):
        r = ratio[: i + 1]
        if (r.max() - r.min()) / (r.max() + r.min()) > tol:
            break
        best = float(STRAINS[i])
    return best


def log_strain(nominal: float) -> float:
    return float(-np.log(1.0 - nominal))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--dawood", type=Path, required=True, help="clone of the database")
    parser.add_argument("--commit", default=COMMIT)
    args = parser.parse_args()
    curves = mean_curves(args.dawood, args.commit)

    print("Same product: the catalogue law against the mean compression curve")
    for name, phantoms in SAME_PRODUCT.items():
        table = CATALOGUE[name].law.to_dict()
        law = law_curve(table["model"], table, table["nu"])
        for phantom in phantoms:
            ratio = law / curves[phantom]
            s = within(ratio)
            err = 100 * (ratio - 1)
            print(
                f"  {name:28s} vs {phantom:8s} within 10 % to {100 * s:5.1f} % "
                f"(log {log_strain(s):.3f}); unscaled error {err.min():+.1f}..{err.max():+.1f} %"
            )

    ogden = {a: law_curve("ogden", {"mu_MPa": [1.0], "alpha": [a]}, 0.499) for a in GEL_ALPHAS}
    print(f"gel family: one-term Ogden, alpha {GEL_ALPHAS[0]}-{GEL_ALPHAS[-1]}, all phantoms")
    worst = min((within(ogden[a] / c), a, p) for a in GEL_ALPHAS for p, c in curves.items())
    print(
        f"  worst case within 10 % to {100 * worst[0]:.1f} % (log {log_strain(worst[0]):.3f}), "
        f"alpha {worst[1]} vs {worst[2]}"
    )

    print("Tension-fitted one-term Ogden entries: their alpha against every phantom")
    for name, mat in CATALOGUE.items():
        table = mat.law.to_dict()
        if name.endswith("_marechal") and table["model"] == "ogden":
            law = law_curve("ogden", table, table["nu"])
            s, phantom = min((within(law / c), p) for p, c in curves.items())
            print(
                f"  {name:36s} alpha {table['alpha'][0]:.2f}: within 10 % of every phantom to "
                f"{100 * s:5.1f} % (log {log_strain(s):.3f}; worst {phantom})"
            )


if __name__ == "__main__":
    main()
