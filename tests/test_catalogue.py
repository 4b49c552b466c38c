"""The material catalogue (``sim/data/materials.toml``) and the human targets file.

Every catalogue entry must load, cite its source and be physically admissible; entries without
published relaxation data are elastic-only; the paper's Table 1 entries must stay as published;
the human targets must carry the published values.  Fast (no simulation).
"""

from __future__ import annotations

import tomllib

import numpy as np
import pytest

from sim.materials import CATALOGUE, CATALOGUE_PATH, Yeoh, load_catalogue, material_from_spec

HUMAN_TARGETS_PATH = CATALOGUE_PATH.with_name("human_targets.toml")

with open(CATALOGUE_PATH, "rb") as _fh:
    RAW = tomllib.load(_fh)

PRONY_KEYS = ("prony_g", "prony_tau_s")

# Cabibihan et al., Table 1, exactly as in the catalogue (any change must be deliberate).
TABLE1_SOURCE = (
    "Cabibihan, Pattofatto, Jomaa, Benallal, Carrozza: Towards Humanlike Social Touch for "
    "Sociable Robotics and Prosthetics, Table 1"
)
TABLE1 = {
    "silicone_gls40": {
        "source": f"{TABLE1_SOURCE} (silicone GLS 40, Prochima)",
        "model": "hyperfoam",
        "mu_MPa": [0.080, 0.010],
        "alpha": [0.001, 15.5],
        "nu": 0.49,
        "prony_g": [0.015, 0.044, 0.029],
        "prony_tau_s": [0.025, 0.150, 0.300],
        "moduli": "long_term",
    },
    "polyurethane_74_45": {
        "source": f"{TABLE1_SOURCE} (polyurethane Poly 74-45, Polytek)",
        "model": "hyperfoam",
        "mu_MPa": [0.100, 0.063],
        "alpha": [5.5, 8.25],
        "nu": 0.47,
        "prony_g": [0.167, 0.158, 0.113],
        "prony_tau_s": [0.100, 1.380, 25.472],
        "moduli": "long_term",
    },
}

NAMES = sorted(RAW)
ADDED = sorted(set(RAW) - set(TABLE1))


def _has_prony(table: dict) -> bool:
    return any(key in table for key in PRONY_KEYS)


def test_file_and_module_catalogue_agree() -> None:
    assert set(load_catalogue()) == set(RAW) == set(CATALOGUE)
    assert set(TABLE1) <= set(RAW)


@pytest.mark.parametrize("name", NAMES)
def test_entry_loads_with_source_and_admissible_moduli(name: str) -> None:
    mat = material_from_spec(name)
    assert mat is CATALOGUE[name]
    assert mat.name == name
    source = RAW[name]["source"]
    assert isinstance(source, str) and source.strip()
    assert mat.source == source
    assert mat.law.initial_shear_modulus_MPa > 0.0
    assert 0.0 < mat.law.nu < 0.5


@pytest.mark.parametrize("name", [n for n in NAMES if not _has_prony(RAW[n])])
def test_entries_without_prony_terms_are_elastic_only(name: str) -> None:
    mat = CATALOGUE[name]
    assert mat.is_elastic
    assert mat.prony.g == () and mat.prony.tau_s == ()
    assert "ELASTIC-ONLY" in mat.source


@pytest.mark.parametrize("name", NAMES)
def test_entries_marked_elastic_only_have_no_prony_terms(name: str) -> None:
    if "ELASTIC-ONLY" in RAW[name]["source"]:
        assert not _has_prony(RAW[name])
        assert CATALOGUE[name].is_elastic


@pytest.mark.parametrize("name", ADDED)
def test_added_entries_declare_the_poisson_ratio_assumption(name: str) -> None:
    assert "nu = " in RAW[name]["source"] and "our assumption" in RAW[name]["source"]


@pytest.mark.parametrize("name", [n for n in NAMES if isinstance(CATALOGUE[n].law, Yeoh)])
def test_yeoh_entries_are_stable_over_a_wide_strain_range(name: str) -> None:
    """``dU/dI1bar = C10 + 2 C20 x + 3 C30 x^2 > 0`` for ``x = I1bar - 3`` in [0, 50]."""
    law = CATALOGUE[name].law
    x = np.linspace(0.0, 50.0, 5001)
    assert np.all(law.c10_MPa + 2.0 * law.c20_MPa * x + 3.0 * law.c30_MPa * x * x > 0.0)


@pytest.mark.parametrize("name", sorted(TABLE1))
def test_table1_entries_unchanged(name: str) -> None:
    assert RAW[name] == TABLE1[name]
    mat = CATALOGUE[name]
    expected = TABLE1[name]
    assert mat.law.mu_MPa == tuple(expected["mu_MPa"])
    assert mat.law.alpha == tuple(expected["alpha"])
    assert mat.law.nu == expected["nu"]
    assert mat.prony.g == tuple(expected["prony_g"])
    assert mat.prony.tau_s == tuple(expected["prony_tau_s"])
    assert mat.moduli == "long_term" and not mat.is_elastic


def test_human_targets_have_the_published_values() -> None:
    with open(HUMAN_TARGETS_PATH, "rb") as fh:
        targets = tomllib.load(fh)
    tapping = targets["tapping"]
    assert tapping["disp_at_1N_mm"] == 1.83
    assert tapping["disp_at_4N_mm"] == 2.91
    assert tapping["hysteresis_Nmm"] == 2.26
    assert tapping["displacement_reading"] == "from_undeformed_top"
    assert "Serina" in tapping["source"] and "1997" in tapping["source"]
    assert tapping["loading_frequency_Hz"] == 0.5 and tapping["inclination_deg"] == 0.0
    conformance = targets["conformance"]
    assert conformance["wedge_peak_force_N"] == 0.0
    assert conformance["direction"] == "lower_is_better"
    assert "Srinivasan" in conformance["source"] and conformance["note"].strip()
