"""Targets files: the shipped human targets, user files, like-with-like readings."""

from __future__ import annotations

import numpy as np
import pytest

from sim.design import load_targets
from sim.errors import DesignError

BASE = """
[tapping]
disp_at_1N_mm = 1.0
disp_at_4N_mm = 2.0
hysteresis_Nmm = 1.5
{extra}
[conformance]
wedge_peak_force_N = 0.1
{conf}
"""


def _write(tmp_path, extra="", conf=""):
    p = tmp_path / "t.toml"
    p.write_text(BASE.format(extra=extra, conf=conf))
    return p


def test_human_targets_are_the_published_values():
    t = load_targets()
    assert t.values == {"disp_at_1N_mm": 1.83, "disp_at_4N_mm": 2.91, "hysteresis_Nmm": 2.26}
    # a living finger's displacement is read from contact: compared like with like
    assert t.reading == "from_first_touch"
    assert t.metric("disp_at_1N_mm") == "disp_at_1N_from_touch_mm"
    assert "Serina" in t.sources["tapping"]
    assert t.wedge_force_N == 0.0
    # a skin must recover between taps: at most a fifth of the human 1 N travel is sag
    assert t.max_sag_mm == pytest.approx(0.2 * 1.83, abs=0.005)
    assert t.sag_ok(0.2) and not t.sag_ok(0.5) and not t.sag_ok(float("nan"))


def test_sag_limit_is_optional_and_checked(tmp_path):
    assert load_targets(_write(tmp_path)).max_sag_mm is None
    assert load_targets(_write(tmp_path)).sag_ok(5.0)  # no limit: any sag
    assert load_targets(_write(tmp_path, "max_sag_mm = 0.2")).max_sag_mm == 0.2
    with pytest.raises(DesignError) as exc:
        load_targets(_write(tmp_path, "max_sag_mm = -1"))
    assert exc.value.field == "tapping.max_sag_mm"


def test_first_touch_reading_compares_like_with_like(tmp_path):
    t = load_targets(_write(tmp_path, 'displacement_reading = "from_first_touch"'))
    assert t.metric("disp_at_1N_mm") == "disp_at_1N_from_touch_mm"
    assert t.metric("disp_at_4N_mm") == "disp_at_4N_from_touch_mm"
    assert t.metric("hysteresis_Nmm") == "hysteresis_Nmm"


def test_measured_profile_csv(tmp_path):
    (tmp_path / "p.csv").write_text("distance_mm,deflection_mm\n0,0.9\n1,0.4\n2,0.1\n")
    t = load_targets(_write(tmp_path, conf='surface_profile_csv = "p.csv"'))
    np.testing.assert_allclose(t.profile[0], [0, 1, 2])
    np.testing.assert_allclose(t.profile[1], [0.9, 0.4, 0.1])


@pytest.mark.parametrize(
    ("extra", "conf", "csv_text", "field"),
    [
        ('displacement_reading = "sideways"', "", None, "tapping.displacement_reading"),
        ("", 'surface_profile_csv = "p.csv"', "a,b\n1,2\n", "conformance.surface_profile_csv"),
        ("", 'surface_profile_csv = "p.csv"', "distance_mm,deflection_mm\n1,0\n0,1\n",
         "conformance.surface_profile_csv"),
        ("", 'surface_profile_csv = "missing.csv"', None, "conformance.surface_profile_csv"),
    ],
)  # fmt: skip
def test_bad_targets_name_the_field(tmp_path, extra, conf, csv_text, field):
    if csv_text is not None:
        (tmp_path / "p.csv").write_text(csv_text)
    with pytest.raises(DesignError) as exc:
        load_targets(_write(tmp_path, extra, conf))
    assert exc.value.field == field


def test_missing_or_bad_values(tmp_path):
    p = tmp_path / "t.toml"
    p.write_text("[tapping]\ndisp_at_1N_mm = 1.0\ndisp_at_4N_mm = -2\nhysteresis_Nmm = 1\n")
    with pytest.raises(DesignError) as exc:
        load_targets(p)
    assert exc.value.field == "tapping.disp_at_4N_mm"
    p.write_text("[tapping]\ndisp_at_1N_mm = 1.0\n")
    with pytest.raises(DesignError) as exc:
        load_targets(p)
    assert exc.value.field == "tapping.disp_at_4N_mm"


@pytest.mark.parametrize(
    ("extra", "conf", "top", "field", "listed"),
    [
        ("", "", "softness_index = 3.0", "softness_index", "[tapping], [conformance]"),
        ("plate_force_at_1mm_N = 1.0", "", "", "tapping.plate_force_at_1mm_N", "disp_at_1N_mm"),
        ("disp_at_1n_mm = 1.83", "", "", "tapping.disp_at_1n_mm", "hysteresis_Nmm"),
        ("", "wedge_force_N = 0", "", "conformance.wedge_force_N", "wedge_peak_force_N"),
        ("", "", "[compliance]\nx = 1", "compliance", "[tapping], [conformance]"),
        ("source = 3", "", "", "tapping.source", "must be text"),
        ('loading_frequency_Hz = "fast"', "", "", "tapping.loading_frequency_Hz", "number"),
        ("", 'direction = "higher_is_better"', "", "conformance.direction", "lower_is_better"),
    ],
)  # fmt: skip
def test_unknown_keys_are_refused_naming_the_key_and_the_allowed_ones(
    tmp_path, extra, conf, top, field, listed
):
    """A misspelt or foreign key is never ignored (the default would silently stay)."""
    p = tmp_path / "t.toml"
    p.write_text(top + "\n" + BASE.format(extra=extra, conf=conf))
    with pytest.raises(DesignError) as exc:
        load_targets(p)
    assert exc.value.field == field
    assert listed in exc.value.message, exc.value.message


def test_the_shipped_targets_file_uses_only_allowed_keys():
    import tomllib

    from sim.design import ALLOWED_KEYS, DEFAULT_TARGETS_PATH

    data = tomllib.loads(DEFAULT_TARGETS_PATH.read_text())
    for table, body in data.items():
        assert set(body) <= set(ALLOWED_KEYS[table])


def test_cli_refuses_an_unknown_target_key_in_one_line(tmp_path):
    import subprocess
    import sys

    p = _write(tmp_path, extra="softness = 3.0")
    proc = subprocess.run(
        [sys.executable, "-m", "explore.cli", "optimize", "--targets", str(p), "--out",
         str(tmp_path / "run")], capture_output=True, text=True, timeout=300,
    )  # fmt: skip
    assert proc.returncode == 2 and "Traceback" not in proc.stderr
    lines = proc.stderr.splitlines()
    assert len(lines) == 1 and "tapping.softness" in lines[0] and "allowed:" in lines[0], lines
    assert not (tmp_path / "run").exists()  # refused before any folder is made
