"""Design files (sim.design.skin): round trips, the documented layout, defaults and validation.

Every invalid input must raise ``DesignError`` whose ``field`` is the dotted path of the offending
key, so that the CLI can print one line naming it.
"""

from __future__ import annotations

import json
import math
import textwrap
from pathlib import Path
from typing import Any

import pytest

import sim.design.skin
from sim import (
    REFERENCE_GEOMETRY,
    Design,
    DesignError,
    Geometry,
    Layer,
    design_from_dict,
    homogeneous_design,
    load_design,
)
from sim.design import MIN_CORE_MM, MIN_LAYER_MM
from sim.materials import (
    CATALOGUE,
    Hyperfoam,
    Material,
    MooneyRivlin,
    NeoHookean,
    Prony,
    Yeoh,
)

SILICONE = "silicone_gls40"
POLYURETHANE = "polyurethane_74_45"

# Inline material tables, one per law, with and without Prony terms.
HYPERFOAM = {"model": "hyperfoam", "mu_MPa": [0.100, 0.063], "alpha": [5.5, 8.25], "nu": 0.47}
HYPERFOAM_PRONY = {
    **HYPERFOAM,
    "prony_g": [0.167, 0.158, 0.113],
    "prony_tau_s": [0.100, 1.380, 25.472],
}
NEO_HOOKEAN = {"model": "neo_hookean", "mu_MPa": 0.12, "nu": 0.45}
NEO_HOOKEAN_PRONY = {
    **NEO_HOOKEAN,
    "prony_g": [0.3],
    "prony_tau_s": [2.0],
    "moduli": "instantaneous",
}
MOONEY_RIVLIN = {"model": "mooney_rivlin", "c10_MPa": 0.05, "c01_MPa": 0.02, "nu": 0.3}
MOONEY_RIVLIN_PRONY = {**MOONEY_RIVLIN, "prony_g": [0.1, 0.2], "prony_tau_s": [0.5, 10.0]}
YEOH = {"model": "yeoh", "c10_MPa": 0.05, "c20_MPa": -0.01, "c30_MPa": 0.003, "nu": 0.4}
YEOH_PRONY = {**YEOH, "prony_g": [0.25], "prony_tau_s": [3.0], "source": "made up for a test"}


def two_layers(outer: Any, core: Any, thickness: float = 1.0) -> dict[str, Any]:
    return {"layers": [{"thickness_mm": thickness, "material": outer}, {"material": core}]}


def one_layer(material: Any, **geometry: float) -> dict[str, Any]:
    data: dict[str, Any] = {"layers": [{"material": material}]}
    if geometry:
        data["geometry"] = geometry
    return data


ROUND_TRIP_CASES: dict[str, dict[str, Any]] = {
    "homogeneous_silicone": one_layer(SILICONE),
    "homogeneous_polyurethane": one_layer(POLYURETHANE),
    "homogeneous_hyperfoam_inline": one_layer(HYPERFOAM),
    "homogeneous_neo_hookean_other_geometry": one_layer(
        NEO_HOOKEAN, half_width_mm=7.0, height_mm=4.0, exponent=2.0
    ),
    "two_layer_catalogue": two_layers(SILICONE, POLYURETHANE),
    "two_layer_hyperfoam_prony_over_mooney_rivlin": two_layers(HYPERFOAM_PRONY, MOONEY_RIVLIN, 0.8),
    "two_layer_yeoh_over_catalogue": two_layers(YEOH, SILICONE, 2.5),
    "three_layer_inline_prony": {
        "geometry": {"half_width_mm": 6.0, "height_mm": 6.5, "exponent": 1.8},
        "layers": [
            {"thickness_mm": 0.5, "material": NEO_HOOKEAN_PRONY},
            {"thickness_mm": 1.5, "material": YEOH_PRONY},
            {"material": MOONEY_RIVLIN_PRONY},
        ],
    },
    "three_layer_mixed": {
        "layers": [
            {"thickness_mm": 0.3, "material": POLYURETHANE},
            {"thickness_mm": 2, "material": HYPERFOAM},
            {"material": NEO_HOOKEAN},
        ],
    },
}


# --- a minimal TOML writer for the design-file form (tomllib only reads) -------------------------
def _toml_value(value: Any) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, str):
        return json.dumps(value)  # a JSON string is a valid TOML basic string
    if isinstance(value, int | float):
        return repr(float(value))
    if isinstance(value, list | tuple):
        return "[" + ", ".join(_toml_value(x) for x in value) + "]"
    raise TypeError(f"not a TOML scalar or array: {value!r}")


def to_toml(data: dict[str, Any]) -> str:
    lines: list[str] = []
    for key, value in data.items():
        if not isinstance(value, dict | list):
            lines.append(f"{key} = {_toml_value(value)}")
    if "geometry" in data:
        lines.append("[geometry]")
        lines += [f"{k} = {_toml_value(v)}" for k, v in data["geometry"].items()]
    for layer in data["layers"]:
        lines.append("[[layers]]")
        if "thickness_mm" in layer:
            lines.append(f"thickness_mm = {_toml_value(layer['thickness_mm'])}")
        material = layer["material"]
        if isinstance(material, str):
            lines.append(f"material = {_toml_value(material)}")
        else:
            lines.append("[layers.material]")
            lines += [f"{k} = {_toml_value(v)}" for k, v in material.items()]
    return "\n".join(lines) + "\n"


def write(tmp_path: Path, text: str, name: str = "design.toml") -> Path:
    path = tmp_path / name
    path.write_text(textwrap.dedent(text))
    return path


# --- round trips ---------------------------------------------------------------------------------
@pytest.mark.parametrize("case", list(ROUND_TRIP_CASES))
def test_round_trip_through_dict(case: str) -> None:
    design = design_from_dict(ROUND_TRIP_CASES[case])
    data = design.to_dict()
    again = design_from_dict(data)
    assert again == design
    assert again.to_dict() == data
    # The dict form is plain data (it goes into result.json and meta.json).
    assert json.loads(json.dumps(data, allow_nan=False)) == data


@pytest.mark.parametrize("case", list(ROUND_TRIP_CASES))
def test_round_trip_through_a_toml_file(case: str, tmp_path: Path) -> None:
    design = design_from_dict(ROUND_TRIP_CASES[case])
    path = write(tmp_path, to_toml(design.to_dict()))
    assert load_design(path) == design


def test_to_dict_keeps_catalogue_names_and_inlines_tables() -> None:
    design = design_from_dict(two_layers(SILICONE, YEOH_PRONY, 1.25))
    data = design.to_dict()
    assert data["geometry"] == {"half_width_mm": 5.84, "height_mm": 5.48, "exponent": 1.5}
    outer, core = data["layers"]
    assert outer == {"thickness_mm": 1.25, "material": SILICONE}
    assert "thickness_mm" not in core
    assert core["material"]["model"] == "yeoh"
    assert core["material"]["c10_MPa"] == 0.05
    assert core["material"]["prony_g"] == [0.25]
    assert core["material"]["prony_tau_s"] == [3.0]
    assert core["material"]["moduli"] == "long_term"
    assert core["material"]["source"] == "made up for a test"


def test_round_trip_keeps_every_material_parameter() -> None:
    design = design_from_dict(ROUND_TRIP_CASES["three_layer_inline_prony"])
    outer, middle, core = design.materials
    assert outer.law == NeoHookean(mu_MPa=0.12, nu=0.45)
    assert outer.prony == Prony((0.3,), (2.0,))
    assert outer.moduli == "instantaneous"
    assert middle.law == Yeoh(c10_MPa=0.05, c20_MPa=-0.01, c30_MPa=0.003, nu=0.4)
    assert middle.source == "made up for a test"
    assert core.law == MooneyRivlin(c10_MPa=0.05, c01_MPa=0.02, nu=0.3)
    assert core.prony.g == (0.1, 0.2)
    assert core.prony.tau_s == (0.5, 10.0)
    assert design.thicknesses_mm == (0.5, 1.5)
    assert design.geometry == Geometry(6.0, 6.5, 1.8)


def test_round_trip_inline_material_with_a_name() -> None:
    design = design_from_dict(one_layer({**NEO_HOOKEAN, "name": "soft"}))
    assert design.materials[0].name == "soft"
    assert design_from_dict(design.to_dict()) == design


def test_round_trip_inline_material_named_like_the_catalogue() -> None:
    design = design_from_dict(one_layer({**NEO_HOOKEAN, "name": SILICONE}))
    again = design_from_dict(design.to_dict())
    assert again.materials[0].law == NeoHookean(mu_MPa=0.12, nu=0.45)


# --- the documented layout and defaults ----------------------------------------------------------
def test_module_docstring_example_loads(tmp_path: Path) -> None:
    doc = sim.design.skin.__doc__
    assert doc is not None
    example = doc.split("A design file::", 1)[1].split("Every validation failure", 1)[0]
    design = load_design(write(tmp_path, example))
    assert design.geometry == REFERENCE_GEOMETRY
    assert len(design.layers) == 2
    assert design.layers[0] == Layer(CATALOGUE[SILICONE], 1.0)
    core = design.layers[1]
    assert core.thickness_mm is None
    assert core.material.law == Hyperfoam(mu_MPa=(0.100, 0.063), alpha=(5.5, 8.25), nu=0.47)
    assert core.material.is_elastic
    assert core.material.name is None


def test_documented_layout_written_by_hand(tmp_path: Path) -> None:
    path = write(
        tmp_path,
        """\
        name = "soft skin"
        description = "silicone skin over a neo-Hookean core, on a rounder section"

        [geometry]
        half_width_mm = 6.5
        height_mm = 6.0
        exponent = 2.0

        [[layers]]                    # outermost first
        thickness_mm = 0.75
        material = "silicone_gls40"

        [[layers]]
        thickness_mm = 1
        [layers.material]
        model = "yeoh"
        c10_MPa = 0.04
        nu = 0.45

        [[layers]]                    # the last layer fills the rest
        [layers.material]
        model = "neo_hookean"
        mu_MPa = 0.2
        nu = 0.4
        prony_g = [0.2]
        prony_tau_s = [5.0]
        """,
    )
    design = load_design(path)
    assert design.geometry == Geometry(half_width_mm=6.5, height_mm=6.0, exponent=2.0)
    assert design.thicknesses_mm == (0.75, 1.0)
    assert design.materials[0] is CATALOGUE[SILICONE]
    assert design.materials[1].law == Yeoh(c10_MPa=0.04, nu=0.45)  # c20, c30 default to 0
    assert design.materials[1].law.c20_MPa == 0.0
    assert design.materials[2].law == NeoHookean(mu_MPa=0.2, nu=0.4)
    assert design.materials[2].prony.g_inf == pytest.approx(0.8)
    assert design.layers[2].thickness_mm is None


def test_load_design_accepts_str_paths(tmp_path: Path) -> None:
    path = write(tmp_path, 'layers = [{material = "polyurethane_74_45"}]\n')
    assert load_design(str(path)) == homogeneous_design(POLYURETHANE)


def test_geometry_left_out_is_the_reference(tmp_path: Path) -> None:
    design = load_design(write(tmp_path, '[[layers]]\nmaterial = "silicone_gls40"\n'))
    assert design.geometry == REFERENCE_GEOMETRY
    assert REFERENCE_GEOMETRY == Geometry(half_width_mm=5.84, height_mm=5.48, exponent=1.5)
    assert design_from_dict(one_layer(SILICONE)).geometry == REFERENCE_GEOMETRY


def test_partial_geometry_takes_the_rest_from_the_reference() -> None:
    design = design_from_dict(one_layer(SILICONE, exponent=2.5))
    assert design.geometry == Geometry(
        REFERENCE_GEOMETRY.half_width_mm, REFERENCE_GEOMETRY.height_mm, 2.5
    )


def test_homogeneous_design() -> None:
    design = homogeneous_design(SILICONE)
    assert design == Design((Layer(CATALOGUE[SILICONE]),), REFERENCE_GEOMETRY)
    assert design.thicknesses_mm == ()
    assert design.to_dict() == {
        "geometry": REFERENCE_GEOMETRY.to_dict(),
        "layers": [{"material": SILICONE}],
    }
    material = Material(NeoHookean(mu_MPa=0.1, nu=0.3))
    geometry = Geometry(4.0, 3.0, 2.0)
    custom = homogeneous_design(material, geometry)
    assert custom.materials == [material]
    assert custom.geometry == geometry
    with pytest.raises(DesignError) as info:
        homogeneous_design("no_such_material")
    assert info.value.field == "material"
    assert "no_such_material" in info.value.message


def test_design_error_names_the_field_first() -> None:
    with pytest.raises(DesignError) as info:
        design_from_dict(one_layer({**NEO_HOOKEAN, "nu": 0.5}))
    assert info.value.field == "layers[0].material.nu"
    assert str(info.value).startswith("layers[0].material.nu: ")
    assert isinstance(info.value, ValueError)


# --- validation ----------------------------------------------------------------------------------
LIMIT_MM = min(REFERENCE_GEOMETRY.half_width_mm, REFERENCE_GEOMETRY.height_mm) - MIN_CORE_MM

INVALID: dict[str, tuple[dict[str, Any], str]] = {
    # materials
    "unknown_catalogue_name": (one_layer("silicone_gls41"), "layers[0].material"),
    "unknown_name_in_layer_2": (two_layers(SILICONE, "steel"), "layers[1].material"),
    "material_not_a_table": (one_layer(3.0), "layers[0].material"),
    "material_missing": ({"layers": [{}]}, "layers[0].material"),
    "model_missing": (one_layer({"mu_MPa": 0.1, "nu": 0.3}), "layers[0].material.model"),
    "model_unknown": (one_layer({**NEO_HOOKEAN, "model": "gent"}), "layers[0].material.model"),
    "nu_half_neo_hookean": (one_layer({**NEO_HOOKEAN, "nu": 0.5}), "layers[0].material.nu"),
    "nu_above_half_hyperfoam": (
        two_layers(SILICONE, {**HYPERFOAM, "nu": 0.6}),
        "layers[1].material.nu",
    ),
    "nu_half_mooney_rivlin": (one_layer({**MOONEY_RIVLIN, "nu": 0.5}), "layers[0].material.nu"),
    "nu_half_yeoh": (one_layer({**YEOH, "nu": 0.5}), "layers[0].material.nu"),
    "nu_minus_one": (one_layer({**NEO_HOOKEAN, "nu": -1.0}), "layers[0].material.nu"),
    "nu_missing": (one_layer({"model": "neo_hookean", "mu_MPa": 0.1}), "layers[0].material.nu"),
    "nu_string": (one_layer({**NEO_HOOKEAN, "nu": "0.3"}), "layers[0].material.nu"),
    "mu_zero_neo_hookean": (one_layer({**NEO_HOOKEAN, "mu_MPa": 0.0}), "layers[0].material.mu_MPa"),
    "mu_negative_neo_hookean": (
        one_layer({**NEO_HOOKEAN, "mu_MPa": -0.1}),
        "layers[0].material.mu_MPa",
    ),
    "mu_negative_hyperfoam": (
        one_layer({**HYPERFOAM, "mu_MPa": [-0.1, -0.063]}),
        "layers[0].material.mu_MPa",
    ),
    "c10_zero_yeoh": (one_layer({**YEOH, "c10_MPa": 0.0}), "layers[0].material.c10_MPa"),
    "mu0_zero_mooney_rivlin": (
        one_layer({**MOONEY_RIVLIN, "c10_MPa": 0.02, "c01_MPa": -0.02}),
        "layers[0].material.c10_MPa",
    ),
    "alpha_length_mismatch": (
        one_layer({**HYPERFOAM, "alpha": [5.5]}),
        "layers[0].material.alpha",
    ),
    "prony_sum_one": (
        one_layer({**NEO_HOOKEAN, "prony_g": [0.5, 0.5], "prony_tau_s": [1.0, 2.0]}),
        "layers[0].material.prony_g",
    ),
    "prony_sum_above_one": (
        two_layers(SILICONE, {**HYPERFOAM, "prony_g": [0.7, 0.4], "prony_tau_s": [1.0, 2.0]}),
        "layers[1].material.prony_g",
    ),
    "prony_negative_g": (
        one_layer({**NEO_HOOKEAN, "prony_g": [-0.1], "prony_tau_s": [1.0]}),
        "layers[0].material.prony_g",
    ),
    "prony_zero_tau": (
        one_layer({**NEO_HOOKEAN, "prony_g": [0.1], "prony_tau_s": [0.0]}),
        "layers[0].material.prony_tau_s",
    ),
    "prony_length_mismatch": (
        one_layer({**NEO_HOOKEAN, "prony_g": [0.1, 0.1], "prony_tau_s": [1.0]}),
        "layers[0].material.prony_tau_s",
    ),
    "moduli_unknown": (
        one_layer({**NEO_HOOKEAN, "moduli": "relaxed"}),
        "layers[0].material.moduli",
    ),
    # unknown keys at every level
    "unknown_top_level_key": ({**one_layer(SILICONE), "layer": []}, "layer"),
    "unknown_geometry_key": (one_layer(SILICONE, width_mm=5.0), "geometry.width_mm"),
    "unknown_layer_key": (
        {"layers": [{"material": SILICONE, "thickness": 1.0}]},
        "layers[0].thickness",
    ),
    "unknown_material_key": (
        one_layer({**NEO_HOOKEAN, "mu": 0.1}),
        "layers[0].material.mu",
    ),
    "yeoh_key_on_neo_hookean": (
        two_layers(SILICONE, {**NEO_HOOKEAN, "c20_MPa": 0.0}),
        "layers[1].material.c20_MPa",
    ),
    # layers and thicknesses
    "zero_layers": ({"layers": []}, "layers"),
    "layers_missing": ({"geometry": {"exponent": 2.0}}, "layers"),
    "layers_not_an_array": ({"layers": {"material": SILICONE}}, "layers"),
    "layer_not_a_table": ({"layers": [SILICONE]}, "layers[0]"),
    "four_layers": (
        {
            "layers": [{"thickness_mm": 0.5, "material": SILICONE} for _ in range(3)]
            + [{"material": POLYURETHANE}]
        },
        "layers",
    ),
    "thickness_on_the_only_layer": (
        {"layers": [{"thickness_mm": 1.0, "material": SILICONE}]},
        "layers[0].thickness_mm",
    ),
    "thickness_on_the_last_layer": (
        {
            "layers": [
                {"thickness_mm": 1.0, "material": SILICONE},
                {"thickness_mm": 1.0, "material": POLYURETHANE},
            ]
        },
        "layers[1].thickness_mm",
    ),
    "thickness_missing_on_outer_layer": (
        {"layers": [{"material": SILICONE}, {"material": POLYURETHANE}]},
        "layers[0].thickness_mm",
    ),
    "thickness_missing_on_middle_layer": (
        {
            "layers": [
                {"thickness_mm": 1.0, "material": SILICONE},
                {"material": SILICONE},
                {"material": POLYURETHANE},
            ]
        },
        "layers[1].thickness_mm",
    ),
    "thickness_below_min": (
        two_layers(SILICONE, POLYURETHANE, 0.5 * MIN_LAYER_MM),
        "layers[0].thickness_mm",
    ),
    "thickness_negative": (two_layers(SILICONE, POLYURETHANE, -1.0), "layers[0].thickness_mm"),
    "thickness_string": (two_layers(SILICONE, POLYURETHANE, "1.0"), "layers[0].thickness_mm"),  # type: ignore[arg-type]
    "layer_as_thick_as_the_body": (
        two_layers(SILICONE, POLYURETHANE, REFERENCE_GEOMETRY.height_mm),
        "layers.thickness_mm",
    ),
    "layer_just_over_the_core_limit": (
        two_layers(SILICONE, POLYURETHANE, LIMIT_MM + 1e-6),
        "layers.thickness_mm",
    ),
    "two_outer_layers_too_thick_together": (
        {
            "layers": [
                {"thickness_mm": 2.5, "material": SILICONE},
                {"thickness_mm": 2.5, "material": POLYURETHANE},
                {"material": SILICONE},
            ]
        },
        "layers.thickness_mm",
    ),
    "core_limit_uses_the_half_width_when_narrower": (
        {
            "geometry": {"half_width_mm": 3.0, "height_mm": 10.0},
            "layers": [{"thickness_mm": 2.6, "material": SILICONE}, {"material": POLYURETHANE}],
        },
        "layers.thickness_mm",
    ),
    "thickness_infinite": (
        two_layers(SILICONE, POLYURETHANE, math.inf),
        "layers[0].thickness_mm",
    ),
    # geometry out of range
    "geometry_not_a_table": ({**one_layer(SILICONE), "geometry": 5.0}, "geometry"),
    "half_width_too_small": (one_layer(SILICONE, half_width_mm=0.99), "geometry.half_width_mm"),
    "half_width_too_large": (one_layer(SILICONE, half_width_mm=50.1), "geometry.half_width_mm"),
    "height_too_small": (one_layer(SILICONE, height_mm=0.5), "geometry.height_mm"),
    "height_too_large": (one_layer(SILICONE, height_mm=100.0), "geometry.height_mm"),
    "exponent_too_small": (one_layer(SILICONE, exponent=1.0), "geometry.exponent"),
    "exponent_too_large": (one_layer(SILICONE, exponent=8.5), "geometry.exponent"),
    "exponent_nan": (one_layer(SILICONE, exponent=math.nan), "geometry.exponent"),
    "height_string": (one_layer(SILICONE, height_mm="5.48"), "geometry.height_mm"),  # type: ignore[arg-type]
}


@pytest.mark.parametrize("case", list(INVALID))
def test_invalid_design_names_the_field(case: str) -> None:
    data, field = INVALID[case]
    with pytest.raises(DesignError) as info:
        design_from_dict(data)
    assert info.value.field == field
    assert info.value.message  # says what is allowed
    assert "\n" not in str(info.value)


@pytest.mark.parametrize(
    ("geometry", "thickness_mm"),
    [
        (REFERENCE_GEOMETRY, LIMIT_MM),  # limited by the height
        (Geometry(half_width_mm=3.0, height_mm=10.0), 3.0 - MIN_CORE_MM),  # by the half-width
        (Geometry(half_width_mm=1.0, height_mm=1.0), MIN_LAYER_MM),  # smallest body
    ],
)
def test_outer_layers_may_reach_the_core_limit(geometry: Geometry, thickness_mm: float) -> None:
    design = Design(
        (Layer(CATALOGUE[SILICONE], thickness_mm), Layer(CATALOGUE[POLYURETHANE])), geometry
    )
    assert design.thicknesses_mm == (thickness_mm,)


def test_geometry_bounds_are_inclusive() -> None:
    assert Geometry(1.0, 50.0, 1.2).to_dict() == {
        "half_width_mm": 1.0,
        "height_mm": 50.0,
        "exponent": 1.2,
    }
    assert Geometry(50.0, 1.0, 8.0).exponent == 8.0


def test_load_design_missing_file(tmp_path: Path) -> None:
    with pytest.raises(DesignError) as info:
        load_design(tmp_path / "nope.toml")
    assert info.value.field == "DESIGN"
    assert "nope.toml" in info.value.message


def test_load_design_malformed_toml(tmp_path: Path) -> None:
    path = write(tmp_path, '[[layers]\nmaterial = "silicone_gls40"\n')
    with pytest.raises(DesignError) as info:
        load_design(path)
    assert info.value.field == "DESIGN"
    assert "malformed TOML" in info.value.message
    assert "line 1" in info.value.message


def test_load_design_validates_the_content(tmp_path: Path) -> None:
    path = write(
        tmp_path,
        """\
        [[layers]]
        thickness_mm = 1.0
        material = "silicone_gls40"
        [[layers]]
        [layers.material]
        model = "hyperfoam"
        mu_MPa = [0.1]
        alpha = [5.5]
        nu = 0.5
        """,
    )
    with pytest.raises(DesignError) as info:
        load_design(path)
    assert info.value.field == "layers[1].material.nu"


def test_load_design_not_utf8(tmp_path: Path) -> None:
    path = tmp_path / "latin1.toml"
    path.write_bytes(b'[[layers]]\nmaterial = "silicone_gls40" # caf\xe9\n')
    with pytest.raises(DesignError) as info:
        load_design(path)
    assert info.value.field == "DESIGN"


def test_load_design_on_a_directory(tmp_path: Path) -> None:
    with pytest.raises(DesignError) as info:
        load_design(tmp_path)
    assert info.value.field == "DESIGN"


def test_nan_thickness_is_rejected() -> None:
    with pytest.raises(DesignError) as info:
        design_from_dict(two_layers(SILICONE, POLYURETHANE, math.nan))
    assert info.value.field == "layers[0].thickness_mm"


def test_boolean_thickness_is_rejected() -> None:
    with pytest.raises(DesignError) as info:
        design_from_dict(two_layers(SILICONE, POLYURETHANE, True))
    assert info.value.field == "layers[0].thickness_mm"


def test_boolean_geometry_is_rejected() -> None:
    with pytest.raises(DesignError) as info:
        design_from_dict(one_layer(SILICONE, half_width_mm=True))
    assert info.value.field == "geometry.half_width_mm"
