"""The material catalogue (``sim/data/materials.toml``) and the human targets file.

Every catalogue entry must load, cite its source and be physically admissible; entries without
published relaxation data are elastic-only; the paper's Table 1 entries must stay as published;
the human targets must carry the published values; the entries fitted with fit-material cite
their data, fit and limits; user catalogues merge, refuse clashes and travel with the spaces
that name them.  Fast (no simulation).
"""

from __future__ import annotations

import hashlib
import json
import tomllib
from pathlib import Path

import numpy as np
import pytest

from sim import DesignError, SimOptions
from sim.design import space_from_dict
from sim.materials import (
    CATALOGUE,
    CATALOGUE_PATH,
    Ogden,
    Yeoh,
    catalogue_from_tables,
    load_catalogue,
    load_user_catalogues,
    material_from_spec,
    material_tables,
)
from sim.sweep import record_key

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
    assert tapping["displacement_reading"] == "from_first_touch"
    assert "Serina" in tapping["source"] and "1997" in tapping["source"]
    assert tapping["loading_frequency_Hz"] == 0.5 and tapping["inclination_deg"] == 0.0
    conformance = targets["conformance"]
    assert conformance["wedge_peak_force_N"] == 0.0
    assert conformance["direction"] == "lower_is_better"
    assert "Srinivasan" in conformance["source"] and conformance["note"].strip()


# --------------------------------------------------------------------------------------------
# Provenance, the fitted entries and user catalogues

FITTED = [n for n in NAMES if n.endswith("_marechal")]


@pytest.mark.parametrize("name", [n for n in NAMES if "provenance" in RAW[n]])
def test_provenance_tables_are_accepted_and_kept(name: str) -> None:
    mat = CATALOGUE[name]
    assert mat.provenance_dict == RAW[name]["provenance"]
    assert material_from_spec(mat.to_dict()) == mat  # the design form keeps it


def test_the_fitted_entries_are_there() -> None:
    assert len(FITTED) == 19
    assert {"ecoflex_0010_marechal", "ecoflex_0030_marechal", "ecoflex_0050_marechal",
            "dragon_skin_10_marechal", "dragon_skin_20_marechal", "dragon_skin_30_marechal",
            "dragon_skin_fx_pro_marechal", "dragon_skin_fx_pro_slacker_marechal",
            "platsil_gel_10_marechal", "body_double_silk_marechal"} <= set(FITTED)  # fmt: skip


@pytest.mark.parametrize("name", FITTED)
def test_fitted_entries_cite_data_fit_and_limits(name: str) -> None:
    """Each entry names the paper, the repository and commit, the file, the licence notice, the
    rate, the fitted range and error, and says it is elastic only with compression extrapolated
    from tension; its Drucker ranges are those of its constants."""
    from sim.materials.fit import drucker_stable_ranges

    raw, mat = RAW[name], CATALOGUE[name]
    source = raw["source"]
    for text in ("doi:10.1089/soro.2019.0115", "LucMarechal/Soft-Robotics-Materials-Database",
                 "8ff66c3bdc17bd226eabe83b778e13ea1e2ef8ce", "Tensile-Tests-Data/",
                 "Open Database License", "ELASTIC-ONLY", "compression extrapolated from tension",
                 "nominal strain rate"):  # fmt: skip
        assert text in source, text
    prov = raw["provenance"]
    assert prov["tests"] == ["uniaxial"] and prov["relaxation"] == "none: ELASTIC-ONLY"
    lo, hi = prov["uniaxial_strain_range"]
    assert 0.0 <= lo < 0.1 and 0.95 <= hi <= 1.0
    assert prov["uniaxial_r2"] > 0.96 and prov["uniaxial_rms_MPa"] > 0
    assert 0.2 < prov["rate_per_s"] < 0.26  # 450-500 mm/min over the 33 mm gauge
    assert mat.is_elastic and isinstance(mat.law, Ogden) and len(mat.law.mu_MPa) == 1
    ranges = drucker_stable_ranges("ogden", mat.law.to_dict(), mat.law.nu)
    for mode, (a, b) in ranges.items():
        assert prov[f"drucker_stable_{mode}"] == [a, b] == [-0.8, 2.0]


def _user(tmp_path: Path, name: str, text: str) -> Path:
    path = tmp_path / name
    path.write_text(text)
    return path


GEL = """
[labgel]
source = "our lab"
model = "neo_hookean"
mu_MPa = 0.01
nu = 0.49
[labgel.provenance]
tests = ["uniaxial"]
uniaxial_r2 = 0.99
"""


def test_user_catalogues_merge_and_refuse_clashes(tmp_path: Path) -> None:
    gel = _user(tmp_path, "gel.toml", GEL)
    user, merged = load_user_catalogues([gel])
    assert set(merged) == set(CATALOGUE) | {"labgel"} and user[0].names == ["labgel"]
    assert merged["labgel"].provenance_dict == {"tests": ["uniaxial"], "uniaxial_r2": 0.99}
    assert user[0].record()["sha256"] == hashlib.sha256(gel.read_bytes()).hexdigest()
    assert set(CATALOGUE) == set(RAW)  # the module's catalogue stays the shipped one
    shipped = _user(tmp_path, "s.toml", GEL.replace("[labgel", "[silicone_gls40"))
    for files, words in (([gel, gel], "gel.toml"), ([shipped], "shipped catalogue")):
        with pytest.raises(DesignError) as info:
            load_user_catalogues(files)
        assert info.value.field == "--catalogue" and words in info.value.message
        assert "rename" in info.value.message


@pytest.mark.parametrize(
    ("text", "field", "words"),
    [
        ("[gel\nmodel = 1", "--catalogue", "malformed TOML"),
        ("", "--catalogue", "no material"),
        (GEL.replace('source = "our lab"\n', ""), "gel.toml:labgel.source", "required"),
        (GEL.replace("nu = 0.49", "nu = 0.5"), "gel.toml:labgel.nu", "(-1, 0.5)"),
        (
            GEL.replace("uniaxial_r2 = 0.99", "fit = { r2 = 1 }"),
            "gel.toml:labgel.provenance.fit",
            "text, a number",
        ),
    ],
)
def test_bad_user_catalogue_names_the_field(tmp_path: Path, text: str, field: str, words: str):
    with pytest.raises(DesignError) as info:
        load_user_catalogues([_user(tmp_path, "gel.toml", text)])
    assert info.value.field == field and words in info.value.message
    with pytest.raises(DesignError) as info:
        load_user_catalogues([tmp_path / "missing.toml"])
    assert info.value.field == "--catalogue" and "no such file" in info.value.message


SPACE_WITH_GEL = {
    "geometry": {"half_width_mm": {"value": 5.84}},
    "layers": {
        "count": {"choice": [1, 2]},
        "skin": {
            "thickness_mm": {"low": 0.3, "high": 1.0},
            "material": {"choice": ["labgel", "silicone_gls40"]},
        },
        "core": {"material": {"choice": ["labgel", "polyurethane_74_45"]}},
    },
}


def test_a_user_material_may_not_take_a_family_name(tmp_path: Path) -> None:
    with pytest.raises(DesignError) as info:
        load_user_catalogues([_user(tmp_path, "gel.toml", GEL.replace("[labgel", "[gel"))])
    assert info.value.field == "gel.toml:gel" and "family" in info.value.message


def test_a_space_lists_user_materials_and_keeps_them(tmp_path: Path) -> None:
    _, merged = load_user_catalogues([_user(tmp_path, "gel.toml", GEL)])
    with pytest.raises(DesignError) as info:
        space_from_dict(SPACE_WITH_GEL)  # without the catalogue
    assert info.value.field == "skin.material" and "--catalogue" in info.value.message
    space = space_from_dict(SPACE_WITH_GEL, merged)
    assert [m.name for m in space.materials] == ["labgel"]
    data = space.to_dict()
    assert (
        set(data["materials"]) == {"labgel"} and data["materials"]["labgel"]["source"] == "our lab"
    )
    again = space_from_dict(json.loads(json.dumps(data)))  # from a run folder, no catalogue
    assert again == space
    point = space.check({"layers.count": 2, "skin.material": "labgel", "skin.thickness_mm": 0.5,
                         "core.material": "polyurethane_74_45"})  # fmt: skip
    design = space.design(point)
    assert design.layers[0].material == merged["labgel"]
    # the design file form holds the user material in full; its record key follows its table
    assert design.to_dict()["layers"][0]["material"]["mu_MPa"] == 0.01
    stiffer = space_from_dict(
        {**data, "materials": {"labgel": {**data["materials"]["labgel"], "mu_MPa": 0.02}}}
    )
    options = SimOptions()
    assert record_key(point, options, space.catalogue) != record_key(
        point, options, stiffer.catalogue
    )
    # the same name meaning another material than the --catalogue's is refused
    with pytest.raises(DesignError) as info:
        space_from_dict({**data, "materials": {"labgel": {**data["materials"]["labgel"],
                                                       "mu_MPa": 0.02}}}, merged)  # fmt: skip
    assert info.value.field == "materials.labgel"
    # the worker side: the tables alone rebuild the catalogue
    tables = material_tables({"labgel": merged["labgel"]})
    assert catalogue_from_tables(tables)["labgel"] == merged["labgel"]
