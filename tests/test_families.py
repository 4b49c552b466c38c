"""The realisable material families of the design spaces (sim.design.families) and the spaces that
use them: what each family's material is, which parameters it uses, and that the shipped spaces hold
no compressible "gel"."""

from __future__ import annotations

import math

import numpy as np
import pytest

from sim.design import (
    DEFAULT_SPACE_PATH,
    FAMILIES,
    GEL_NU,
    family_material,
    family_uses,
    is_family,
    load_space,
    mask_inactive,
    space_from_dict,
)
from sim.errors import DesignError
from sim.materials import CATALOGUE
from surrogate._encoding import material_descriptors

WIDE = DEFAULT_SPACE_PATH.with_name("wide_space.toml")
GEL = {"mu0_MPa": 0.006, "alpha": 3.0, "g_total": 0.6, "tau_s": 0.3}
FOAM = {**GEL, "nu": 0.2}


def test_gel_is_nearly_incompressible_and_relaxes_in_shear_only():
    m = family_material("gel", GEL)
    assert m.law.model == "ogden" and m.law.nu == GEL_NU >= 0.495
    t = np.array([0.0, 0.03, 0.3, 3.0, 300.0])
    # shear: three equal terms at tau/10, tau, 10 tau, relaxing by g_total in all
    assert m.prony.tau_s == pytest.approx((0.03, 0.3, 3.0))
    expected = 1 - sum(0.2 * (1 - np.exp(-t / tau)) for tau in (0.03, 0.3, 3.0))
    np.testing.assert_allclose(m.prony.relaxation(t), expected, rtol=1e-12)
    # bulk: elastic (a gel's volume response does not creep away)
    np.testing.assert_allclose(m.bulk_relaxation(t), 1.0)
    assert m.long_term.initial_shear_modulus_MPa == pytest.approx(0.006)


def test_foam_relaxes_its_whole_stress_with_its_own_poisson_ratio():
    m = family_material("foam", FOAM)
    assert m.law.model == "hyperfoam" and m.law.nu == 0.2
    t = np.array([0.0, 0.3, 30.0])
    np.testing.assert_allclose(m.bulk_relaxation(t), m.prony.relaxation(t), rtol=1e-12)


def test_elastic_family_member_has_no_prony_terms():
    assert family_material("gel", {**GEL, "g_total": 0.0}).is_elastic


def test_which_parameters_a_layer_uses():
    assert not family_uses("gel", "nu") and family_uses("gel", "alpha")
    assert family_uses("foam", "nu") and family_uses("param", "nu")
    assert not family_uses("silicone_gls40", "mu0_MPa") and not is_family("silicone_gls40")
    p = mask_inactive(
        {"layers.count": 2, "skin.material": "gel", "skin.nu": 0.3, "skin.alpha": 2.0,
         "core.material": "foam", "core.nu": 0.1}
    )  # fmt: skip
    assert math.isnan(p["skin.nu"]) and p["skin.alpha"] == 2.0 and p["core.nu"] == 0.1


@pytest.mark.parametrize("path", [DEFAULT_SPACE_PATH, WIDE])
def test_shipped_spaces_hold_only_realisable_materials(path):
    """No compressible "gel": every family is gel or foam, every catalogue choice a material
    whose nu is that of a real solid (the paper's own two entries keep their 0.49 / 0.47)."""
    space = load_space(path)
    for p in space.parameters:
        if not p.name.endswith(".material"):
            continue
        for choice in p.choices:
            if is_family(choice):
                assert choice in ("gel", "foam")
                assert choice != "foam" or not p.name.startswith("skin.")  # foam: cores only
            elif choice not in ("silicone_gls40", "polyurethane_74_45"):
                assert CATALOGUE[choice].law.nu >= 0.495, choice
    assert space["core.nu"].low >= 0.0 and space["core.nu"].high <= 0.3  # the foam's range
    assert "skin.nu" not in space.names  # a skin is never a foam: it has no nu


def test_a_space_bound_outside_a_family_range_is_refused():
    data = {
        "layers": {
            "core": {
                "material": {"choice": ["foam"]},
                "mu0_MPa": {"low": 0.01, "high": 0.1},
                "alpha": {"value": 2.0},
                "nu": {"low": 0.0, "high": 0.45},  # a foam's nu is at most 0.3
                "g_total": {"value": 0.3},
                "tau_s": {"value": 0.1},
            }
        }
    }
    with pytest.raises(DesignError) as exc:
        space_from_dict(data)
    assert exc.value.field == "core.nu" and "foam" in str(exc.value)


def test_family_descriptors_equal_those_of_the_built_material():
    """The surrogate's linear-viscoelastic descriptors of a family point (computed from the
    parameters, vectorised) are those of the material the FE builds from it."""
    for family, values in (("gel", GEL), ("foam", FOAM)):
        cols = {"core.material": np.array([family], dtype=object)}
        cols |= {f"core.{k}": np.array([v]) for k, v in values.items()}
        direct, _ = material_descriptors(cols, 1, ["core"])
        name = f"built_{family}"
        built = family_material(family, values)
        via, _ = material_descriptors(
            {"core.material": np.array([name], dtype=object)}, 1, ["core"], {name: built}
        )
        np.testing.assert_allclose(direct, via, rtol=1e-12)


def test_every_family_is_registered_with_its_keys():
    for name, fam in FAMILIES.items():
        assert fam.name == name and set(fam.keys) <= set(fam.limits)
        assert len(fam.time_ratios) == 3 and fam.time_ratios[1] == 1.0


def test_every_bound_of_the_default_space_is_argued_in_the_docs():
    """docs/design_space.md's "Bounds" table has a row, with its source or argument, for every
    parameter of the default space, and the bounds it states are the file's."""
    doc = (DEFAULT_SPACE_PATH.parents[2] / "docs" / "design_space.md").read_text()
    rows = {
        line.split("|")[1].strip().strip("`"): line.split("|")[2:4]
        for line in doc.split("## Bounds", 1)[1].split("\n## ", 1)[0].splitlines()
        if line.startswith("| `")
    }
    space = load_space()
    for p in space.parameters:
        assert p.name in rows, p.name
        bound, argument = (cell.strip() for cell in rows[p.name])
        assert len(argument) > 40, p.name  # a source or an argument, not a placeholder
        if p.kind == "float":
            assert bound.startswith(f"{p.low:g}-{p.high:g}"), (p.name, bound)


@pytest.mark.parametrize("path", [DEFAULT_SPACE_PATH, WIDE])
def test_a_design_maps_back_to_its_point(path):
    """point_from_design inverts point_to_design on the space's own samples (catalogue names and
    family members alike), so a design file names one point of the space."""
    from sim.design import point_from_design, point_to_design

    space = load_space(path)
    rng = np.random.default_rng(3)
    for _ in range(60):
        p = space.point(rng.random(len(space.sampled)))
        back = space.check(point_from_design(point_to_design(p, space.catalogue), space))
        assert back.keys() == p.keys()
        for k, v in p.items():
            if isinstance(v, float):
                assert (math.isnan(v) and math.isnan(back[k])) or back[k] == pytest.approx(v)
            else:
                assert back[k] == v, k


def test_a_material_outside_the_families_is_named():
    from sim.design import Design, Layer, point_from_design

    compressible = family_material("param", {**FOAM, "nu": 0.45})  # the old "gel"
    with pytest.raises(DesignError) as exc:
        point_from_design(Design((Layer(compressible),)), load_space())
    assert exc.value.field == "layers[0].material" and "gel" in str(exc.value)
