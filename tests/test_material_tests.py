"""The tested range of every material (``sim/data/material_tests.toml``, ``sim.materials._tests``).

Every shipped catalogue material and the design spaces' families have an entry with a source;
the strains are physical and agree with the catalogue's own record of its fits; the loader
refuses a malformed entry in one error naming the entry and the key.  Fast (no simulation).
"""

from __future__ import annotations

import dataclasses
import math
import tomllib
from pathlib import Path

import pytest

from sim import DesignError
from sim.materials import CATALOGUE, CATALOGUE_PATH
from sim.materials import _tests as mt
from sim.protocols.validity import PAPER_LOG_STRAIN

FAMILIES = ("family.gel", "family.foam")
RANGES = mt.load_tested_ranges()
with open(CATALOGUE_PATH, "rb") as _fh:
    CATALOGUE_RAW = tomllib.load(_fh)

# what a soft solid's tests can reach: 90 % nominal compression, 1000 % nominal tension
MAX_COMPRESSIVE = -math.log(1.0 - 0.90)
MAX_TENSILE = math.log(1.0 + 10.0)


def test_every_catalogue_material_has_an_entry() -> None:
    missing = sorted(set(CATALOGUE) - set(RANGES))
    assert not missing, f"add these catalogue materials to {mt.TESTS_PATH.name}: {missing}"


def test_the_families_have_entries() -> None:
    for name in FAMILIES:
        entry = mt.tested_range(name)
        assert entry is not None, name
        assert entry.max_compressive_log_strain is not None, name


def test_no_entry_without_a_material() -> None:
    stale = sorted(set(RANGES) - set(CATALOGUE) - set(FAMILIES))
    assert not stale, f"entries of no catalogue material or family: {stale}"


@pytest.mark.parametrize("name", sorted(RANGES))
def test_entry_is_sourced_and_physical(name: str) -> None:
    entry = RANGES[name]
    assert len(entry.source) > 40, "cite authors, year, journal or database, table or file"
    assert entry.mode and set(entry.mode) <= set(mt.MODES)
    limits = (entry.max_compressive_log_strain, entry.max_tensile_log_strain)
    assert any(v is not None for v in limits)
    if entry.max_compressive_log_strain is not None:
        assert 0.0 <= entry.max_compressive_log_strain <= MAX_COMPRESSIVE
    if entry.max_tensile_log_strain is not None:
        assert 0.0 < entry.max_tensile_log_strain <= MAX_TENSILE


@pytest.mark.parametrize("name", sorted(RANGES))
def test_argued_limits_say_so(name: str) -> None:
    """A compressive limit of a law never tested in compression is argued in its note."""
    entry = RANGES[name]
    if entry.max_compressive_log_strain and "uniaxial_compression" not in entry.mode:
        assert "ARGUED" in entry.note, name
        assert entry.compressive_argued, name


@pytest.mark.parametrize("name", sorted(RANGES))
def test_every_entry_has_a_compressive_limit(name: str) -> None:
    """The FE holds every layer to its material's compressive limit: a law fitted in tension
    only has an argued one, never none (no free pass)."""
    assert RANGES[name].max_compressive_log_strain is not None, name


def test_measured_and_argued_limits() -> None:
    """Measured: a test compressed the material that far; argued: none did (tension only), or
    the entry is a family's, whose law has no fit of its own (its note says ARGUED)."""
    measured = {n for n, e in RANGES.items() if not e.compressive_argued}
    assert measured == {
        "silicone_gls40",
        "polyurethane_74_45",
        "ecoflex_0010_dawood",
        "ecoflex_0030_dawood",
        "ecoflex_0050_dawood",
    }
    assert RANGES["family.gel"].compressive_argued  # its modes include compression
    assert "uniaxial_compression" in RANGES["family.gel"].mode


def test_a_provenance_records_a_tested_range() -> None:
    """A material's provenance (fingertip fit-material's keys) gives its tested range, checked
    like a file entry; errors name the provenance key; nothing recorded: None."""
    prov = {
        "tested_mode": ("uniaxial_tension",),  # a Material keeps its lists as tuples
        "max_compressive_log_strain": 0.35,
        "max_tensile_log_strain": 0.69,
        "tested_note": "ARGUED: the lateral contraction of the tension test",
    }
    got = mt.tested_range_from_provenance(prov, "our lab", "m.provenance")
    assert got == mt.TestedRange(("uniaxial_tension",), 0.35, 0.69, "our lab", prov["tested_note"])
    assert got.compressive_argued
    assert mt.tested_range_from_provenance({"tests": ["uniaxial"]}, "x", "m.provenance") is None
    unargued = {k: v for k, v in prov.items() if k != "tested_note"}
    with pytest.raises(DesignError, match=r"^m\.provenance\.tested_note: is required"):
        mt.tested_range_from_provenance(unargued, "x", "m.provenance")
    with pytest.raises(DesignError, match=r"^m\.provenance\.tested_mode: unknown mode"):
        mt.tested_range_from_provenance({**prov, "tested_mode": "squash"}, "x", "m.provenance")


def test_fitted_tension_matches_the_catalogue_record() -> None:
    """The entries fitted with fit-material record their fitted strain range; the tensile limit
    is its upper end as a log strain."""
    checked = 0
    for name, table in CATALOGUE_RAW.items():
        record = table.get("provenance", {})
        if "uniaxial_strain_range" in record:
            top = record["uniaxial_strain_range"][1]
            assert RANGES[name].max_tensile_log_strain == pytest.approx(
                math.log1p(top), abs=1e-4
            ), name
            assert RANGES[name].mode == ("uniaxial_tension",), name
            checked += 1
    assert checked == 19


def test_quoted_compression_tests() -> None:
    """The limits read from tests, not argued: 45 % (the paper), 20 mm of 30 mm (Dawood)."""
    for name in ("silicone_gls40", "polyurethane_74_45"):
        assert RANGES[name].max_compressive_log_strain == pytest.approx(-math.log(0.55), abs=1e-4)
        # the paper's limit of sim/protocols/validity.py is the same tests' strain, rounded
        assert RANGES[name].max_compressive_log_strain == pytest.approx(PAPER_LOG_STRAIN, abs=0.005)
    for name in ("ecoflex_0010_dawood", "ecoflex_0030_dawood", "ecoflex_0050_dawood"):
        assert RANGES[name].max_compressive_log_strain == pytest.approx(math.log(3.0), abs=1e-4)
        assert RANGES[name].max_tensile_log_strain is None


def test_loader_reads_once_and_returns_none_for_unknown() -> None:
    assert mt.load_tested_ranges() is mt.load_tested_ranges()
    assert mt.tested_range("no_such_material") is None
    entry = mt.tested_range("silicone_gls40")
    assert isinstance(entry, mt.TestedRange)
    with pytest.raises(dataclasses.FrozenInstanceError):
        entry.source = ""  # type: ignore[misc]
    with pytest.raises(TypeError):
        RANGES["x"] = entry  # type: ignore[index]


GOOD = """
[gel_a]
mode = ["uniaxial_compression", "uniaxial_tension"]
max_compressive_log_strain = 0.5
max_tensile_log_strain = 0.7
source = "Someone A, Other B: A study of a gel, Journal 1 (2020) 1-10, Table 2"
"""


def _write(tmp_path: Path, body: str) -> Path:
    path = tmp_path / "tests.toml"
    path.write_text(body)
    return path


def test_loader_takes_a_path(tmp_path: Path) -> None:
    path = _write(tmp_path, GOOD)
    entry = mt.tested_range("gel_a", path)
    assert entry == mt.TestedRange(
        ("uniaxial_compression", "uniaxial_tension"),
        0.5,
        0.7,
        "Someone A, Other B: A study of a gel, Journal 1 (2020) 1-10, Table 2",
    )
    assert mt.tested_range("gel_a", str(path)) == entry


BAD = {
    "unknown mode": ('mode = "indentation"', "gel_a.mode", "unknown mode"),
    "empty mode list": ("mode = []", "gel_a.mode", "non-empty"),
    "mode twice": (
        'mode = ["uniaxial_tension", "uniaxial_tension"]',
        "gel_a.mode",
        "twice",
    ),
    "negative strain": (
        "max_compressive_log_strain = -0.5",
        "gel_a.max_compressive_log_strain",
        ">= 0",
    ),
    "strain as text": (
        'max_tensile_log_strain = "0.7"',
        "gel_a.max_tensile_log_strain",
        "finite number",
    ),
    "strain as bool": (
        "max_tensile_log_strain = true",
        "gel_a.max_tensile_log_strain",
        "finite number",
    ),
    "infinite strain": (
        "max_tensile_log_strain = inf",
        "gel_a.max_tensile_log_strain",
        "finite number",
    ),
    "empty source": ('source = "  "', "gel_a.source", "required"),
    "unknown key": ("nominal = 0.45", "gel_a.nominal", "unknown key"),
}


def _replace(body: str, line: str) -> str:
    key = line.split("=", 1)[0].strip()
    lines = [x for x in body.splitlines() if x.split("=", 1)[0].strip() != key]
    return "\n".join([*lines, line]) + "\n"


@pytest.mark.parametrize("case", sorted(BAD))
def test_loader_rejects_a_malformed_entry(tmp_path: Path, case: str) -> None:
    line, field, words = BAD[case]
    path = _write(tmp_path, _replace(GOOD, line))
    with pytest.raises(DesignError) as err:
        mt.tested_range("gel_a", path)
    assert err.value.field == f"tests.toml:{field}"
    assert words in err.value.message


@pytest.mark.parametrize(
    ("body", "field", "words"),
    [
        (GOOD.replace('mode = ["uniaxial_compression", "uniaxial_tension"]\n', ""), "mode", "req"),
        (GOOD.replace('source = "Someone', 'note = "Someone'), "source", "required"),
        (
            GOOD.replace("max_compressive_log_strain = 0.5\n", "").replace(
                "max_tensile_log_strain = 0.7\n", ""
            ),
            "",
            "needs max_compressive_log_strain",
        ),
        # a compressive limit of a tension-only law must say how it was argued
        (
            GOOD.replace('["uniaxial_compression", "uniaxial_tension"]', '"uniaxial_tension"'),
            "note",
            "argued",
        ),
        ('gel_a = "not a table"\n', "", "must be a table"),
    ],
    ids=["missing mode", "missing source", "no strain", "argued without note", "not a table"],
)
def test_loader_names_the_missing_part(tmp_path: Path, body: str, field: str, words: str) -> None:
    path = _write(tmp_path, body)
    with pytest.raises(DesignError) as err:
        mt.tested_range("gel_a", path)
    assert err.value.field == "tests.toml:gel_a" + (f".{field}" if field else "")
    assert words in err.value.message


def test_a_note_licenses_an_argued_limit(tmp_path: Path) -> None:
    body = GOOD.replace('["uniaxial_compression", "uniaxial_tension"]', '"uniaxial_tension"')
    path = _write(tmp_path, body + 'note = "ARGUED from a similar gel in compression"\n')
    assert mt.tested_range("gel_a", path).max_compressive_log_strain == 0.5


def test_malformed_toml_is_one_error(tmp_path: Path) -> None:
    path = _write(tmp_path, "[gel_a\nmode = 1\n")
    with pytest.raises(DesignError) as err:
        mt.tested_range("gel_a", path)
    assert err.value.field == "tests.toml"
