"""The multi-fidelity surrogate (surrogate._multifidelity): the 3D model's metrics from the
shipped 2D surrogate (the low fidelity) and a few 3D designs.

No 3D dataset is shipped, and a 3D design costs minutes of FE: the 3D sweeps here are
SYNTHETIC. Their "2D model" is the shipped 2D surrogate itself (cheap: microseconds a design),
and their "3D model" a known smooth map (``synthetic_3d``) of its predictions and of the pad's
length and profile. They test the method and its machinery (on such data a multi-fidelity
model must beat one trained on the 3D designs alone), not the accuracy on FE results, which
``studies/multifidelity_study.py`` measures on a real 3D sweep.
"""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest
import torch
from mf_fixtures import DISPLACEMENTS, write_synthetic_sweep
from sweep_fixtures import SHIPPED

import explore.cli
from sim.design import DEFAULT_SPACE_3D_PATH, load_space
from sim.errors import DesignError
from sim.metrics import METRICS, METRICS_3D, SOLVER_VERSION
from sim.provenance import sha256_file
from sim.sweep import sample_points
from surrogate import (
    MULTIFIDELITY_METHODS,
    CheckpointError,
    TrainConfig,
    fit_multifidelity,
    load_checkpoint,
    load_multifidelity,
    multifidelity_curve,
    read_sweep,
    save_checkpoint,
    save_multifidelity,
)
from surrogate._multifidelity import FineTune, method_class
from surrogate._multifidelity_run import MF_TARGETS, format_curve

SHIPPED_FILE = SHIPPED / "model.safetensors"
#: small, quick trainings (the tests check the method and the machinery)
QUICK = TrainConfig(members=3, hidden=(64, 64), max_epochs=300, patience=60, decay_patience=30)
TINY = TrainConfig(members=2, hidden=(16, 16), max_epochs=15, patience=15)
ERROR_PREFIX = "fingertip: error: "


@pytest.fixture(scope="module", autouse=True)
def one_torch_thread():
    before = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(before)


@pytest.fixture(scope="module")
def low():
    return load_checkpoint(SHIPPED_FILE)


@pytest.fixture(scope="module")
def sweep3d(tmp_path_factory, low) -> Path:
    """A SYNTHETIC 3D sweep of 256 designs."""
    return write_synthetic_sweep(tmp_path_factory.mktemp("mf") / "sweep3d", 256, 7, low)


@pytest.fixture(scope="module")
def small3d(tmp_path_factory, low) -> Path:
    """A SYNTHETIC 3D sweep of 40 designs (quick trainings)."""
    return write_synthetic_sweep(tmp_path_factory.mktemp("mf") / "small3d", 40, 3, low)


@pytest.fixture(scope="module")
def low_copy(tmp_path_factory) -> Path:
    """The shipped 2D checkpoint copied outside the repository (the tests change it)."""
    path = tmp_path_factory.mktemp("low") / "model.safetensors"
    shutil.copyfile(SHIPPED_FILE, path)
    return path


def test_the_methods_are_a_registry_the_cli_names():
    """Every method by name, with what it takes from the 2D surrogate; the CLI's list (kept
    beside its parser, which does not import the surrogate) is the registry's; a 3D sweep read
    as a 2D one and a 2D sweep read as a 3D one are refused."""
    assert list(MULTIFIDELITY_METHODS) == list(explore.cli.MULTIFIDELITY_METHODS)
    assert list(MULTIFIDELITY_METHODS)[:3] == ["3d", "input", "delta"]
    for name, kind in MULTIFIDELITY_METHODS.items():
        assert kind.name == name and kind.summary and method_class(name) is kind
        assert kind.low_fidelity == (name != "3d")
    assert method_class("input").low_inputs and not method_class("input").delta
    assert method_class("delta").low_inputs and method_class("delta").delta
    assert set(method_class("delta-contact").proxies) == set(METRICS_3D)
    assert method_class("finetune").warm_start
    with pytest.raises(DesignError, match=r"--method: must be one of 3d, input, delta"):
        method_class("kriging")
    with pytest.raises(DesignError, match="sweep of the 2d model"):
        read_sweep(SHIPPED, dimension="3d")


def test_a_3d_sweep_is_read_only_when_asked(small3d):
    """``read_sweep`` refuses a 3D sweep (``fingertip train``'s 2D surrogate, the search); with
    ``dimension="3d"`` it reads the 3D metrics, the contact patch among them, in the sweep's
    order, then the trust outputs."""
    with pytest.raises(DesignError, match="sweep of the 3d model; the surrogate learns from 2D"):
        read_sweep(small3d)
    data = read_sweep(small3d, dimension="3d")
    assert data.metric_names[: len(METRICS) + len(METRICS_3D)] == (*METRICS, *METRICS_3D)
    assert len(data.points) == 40 and "geometry.half_length_mm" in data.points[0]
    fe = data.scored_targets()[:, : len(METRICS) + len(METRICS_3D)]
    assert np.all(np.isnan(fe[~data.whole])) and np.isfinite(fe[data.whole]).all()


def test_multifidelity_beats_3d_only_training_at_equal_small_numbers_of_3d_designs(sweep3d):
    """On SYNTHETIC 3D data (a smooth map of the 2D metrics, c and m), with the same 48 3D
    designs, the same seed and the same training: the 2D prediction as an input and, more so,
    the 3D metric learnt as its ratio to it, predict the displacements and the hysteresis of
    held-out settled, valid designs far better than training on the 3D designs alone, and the
    contact patch (3D only) better too; as a ratio to the 2D displacement (delta-contact) better
    still; with a trend in the pad's shape (delta-trend), the ratio that is linear in its logs
    exactly. (On this machine, with the shipped checkpoint as the 2D model: median error on the
    displacements 3d 23-30 %, input 10-15 %, delta 2.4-3.5 %, delta-trend 2.0-2.7 %; hysteresis
    60, 41, 4.1, 0.2 %; contact area 27-34 %, 15-17 %, 16-18 %, delta-contact 9-10 %. The
    synthetic map is of the shipped 2D surrogate's predictions, so the figures move with it:
    with the checkpoint trained on one strain limit for every layer, input's displacements were
    8-12 % against 3d's 36-46 %.)"""
    result = multifidelity_curve(
        sweep3d,
        [48],
        low_fidelity=SHIPPED,
        methods=["3d", "input", "delta", "delta-contact", "delta-trend"],
        members=QUICK.members,
        config=QUICK,
        test_fraction=0.4,
    )
    assert result["n_test"] >= 50 and result["sizes"] == [48]
    med = {
        row["method"]: {m: row["scores"][m]["median_rel_error"] for m in MF_TARGETS}
        for row in result["rows"]
    }
    print(format_curve(result))
    for m in [*DISPLACEMENTS, "hysteresis_Nmm"]:
        assert med["delta"][m] < 0.2 * med["3d"][m], m
        assert med["delta"][m] < 0.08, m
        assert med["input"][m] < 0.8 * med["3d"][m], m
    for m in DISPLACEMENTS:  # at most 0.55 with the shipped checkpoint, 0.33 with the one before
        assert med["input"][m] < 0.65 * med["3d"][m], m
    for m in ("contact_area_at_1N_mm2", "contact_area_at_4N_mm2"):
        assert med["input"][m] < 0.6 * med["3d"][m], m
        assert med["delta"][m] < 0.6 * med["3d"][m], m
    contact = ("contact_area_at_1N_mm2", "contact_area_at_4N_mm2")
    assert sum(med["delta-contact"][m] for m in contact) < 0.85 * sum(
        med["delta"][m] for m in contact
    )
    # the synthetic hysteresis's log ratio is linear in ln c and ln m: the trend holds all of it
    # (0.2 % against delta's 4.1 %), and the displacements' (with a term in the 2D value) lose
    # nothing by it (2.0-2.7 % against 2.4-3.5 %)
    assert med["delta-trend"]["hysteresis_Nmm"] < 0.25 * med["delta"]["hysteresis_Nmm"]
    for m in DISPLACEMENTS:
        assert med["delta-trend"][m] < 1.2 * med["delta"][m], m
    for row in result["rows"]:  # the intervals: calibrated on 9 validation designs
        cover = [row["scores"][m]["coverage_90"] for m in MF_TARGETS]
        assert all(0.5 <= c <= 1.0 for c in cover), (row["method"], cover)


@pytest.mark.parametrize("method", ["delta", "delta-trend", "delta-slice"])
def test_a_checkpoint_round_trip_gives_the_same_bits_and_records_both_datasets(
    small3d, tmp_path, low, method
):
    """Saved and loaded, a delta surrogate (delta-trend and delta-slice: its trend too; the
    slice model's bases are computed again from the method's name) predicts the same bits
    (on this machine) for 3D points, the 3D-only metrics among them, in their units; the file
    records the method, the 3D sweep (table sha256, designs, space, solver version) and the low
    fidelity (its path in the repository, its file's sha256, its own training table); a point
    outside the 3D space is
    flagged out of domain, as the 2D surrogate flags one outside its space."""
    data = read_sweep(small3d, dimension="3d")
    fit = fit_multifidelity(data, SHIPPED, method, TINY, progress=False)
    path = save_multifidelity(fit.surrogate, tmp_path / "mf.safetensors")
    loaded = load_multifidelity(path)
    if method != "delta":
        assert np.array_equal(loaded.trend, fit.surrogate.trend)
        assert np.any(loaded.trend != 0.0) and loaded.header["trend_inputs"] == [
            "geometry.half_length_mm", "geometry.length_exponent", "geometry.half_width_mm"
        ]  # fmt: skip
    else:
        assert loaded.trend is None and loaded.header["trend_inputs"] is None
    points = sample_points(load_space(DEFAULT_SPACE_3D_PATH), 200, 11)
    a, b = fit.surrogate.predict(points), loaded.predict(points)
    for key in ("mean", "median", "std", "lower_90", "upper_90", "in_domain", "by_rule"):
        assert np.array_equal(getattr(a, key), getattr(b, key), equal_nan=True), key
    assert a.reasons == b.reasons
    names = list(b.metric_names)
    assert set(METRICS_3D) <= set(names) and set(METRICS) <= set(names)
    j = names.index("contact_area_at_4N_mm2")
    assert b.units[j] == "mm^2" and np.all(np.isfinite(b.median[:, j]) & (b.median[:, j] > 0))
    assert np.all(b.lower_90[:, j] <= b.median[:, j]) and np.all(b.median[:, j] <= b.upper_90[:, j])
    h = loaded.header
    assert h["method"] == method and h["format"] == "fingertip-multifidelity"
    assert h["training_data"]["table_sha256"] == sha256_file(small3d / "table.csv")
    assert h["training_data"]["n_rows"] == 40 and h["solver_version"] == SOLVER_VERSION
    pad = h["training_data"]["space"]["geometry"]["half_length_mm"]
    assert pad == {"low": 8.0, "high": 14.0} and h["space"] == h["training_data"]["space"]
    assert h["low_fidelity"]["path"] == "surrogate/pretrained/default/model.safetensors"
    assert h["low_fidelity"]["sha256"] == sha256_file(SHIPPED_FILE)
    assert (
        h["low_fidelity"]["training_data"]["table_sha256"]
        == low.header["training_data"]["table_sha256"]
    )
    delta_of = {m["name"]: m["delta_of"] for m in h["metrics"]}
    contact_base = None if method == "delta" else "disp_at_1N_from_touch_mm"  # the proxy
    assert delta_of["disp_at_1N_mm"] == "disp_at_1N_mm"
    assert delta_of["contact_area_at_1N_mm2"] == contact_base
    outside = dict(points[0], **{"geometry.half_length_mm": 20.0})
    pred = loaded.predict([outside, points[0]])
    assert not pred.in_domain[0] and "geometry.half_length_mm outside the space" in pred.reasons[0]
    assert pred.reasons[1] == a.reasons[0]
    with pytest.raises(DesignError, match=r"geometry\.length_exponent"):
        loaded.predict([{k: v for k, v in points[0].items() if k != "geometry.length_exponent"}])


def test_the_trend_reads_the_pads_logs_and_recovers_a_map_linear_in_them(small3d, low):
    """``delta-trend``'s base: the trend's inputs read back from the encoded features are the
    logs of the pad's half-length, length exponent and half-width (to the features' float32),
    and ``fit_trend`` recovers the coefficients of FE values whose ratio to the 2D prediction
    is exactly linear in them; an output with too few values, and the contact patch, keep a zero
    trend."""
    from surrogate._multifidelity import (
        TREND_MIN_ROWS_PER_COEFFICIENT,
        MultiFidelitySurrogate,
        fit_trend,
    )

    data = read_sweep(small3d, dimension="3d")
    fit = fit_multifidelity(data, SHIPPED, "delta-trend", TINY, progress=False)
    s = fit.surrogate
    features = s.encoder.encode(data.points).features
    H = s.trend_matrix(features)
    raw = np.log([[p[n] for n in s.trend_inputs] for p in data.points])
    assert np.allclose(H[:, 0], 1.0) and np.allclose(H[:, 1:], raw, rtol=0, atol=1e-6)
    plain = MultiFidelitySurrogate(
        "delta", s.model, s.encoder, s.normaliser, s.metric_names, s.delta
    )
    base, _ = plain.base(features)  # the 2D prediction alone
    j = list(s.metric_names).index("disp_at_1N_mm")
    k = low.metric_names.index("disp_at_1N_mm")
    b = np.array([0.3, -0.7, -0.4, 0.1])
    targets = np.full((len(H), len(s.metric_names)), np.nan)
    targets[:, j] = np.exp(base[:, j] + H @ b) - low.normaliser.offset[k]
    trend = fit_trend(targets, base, H, s.delta, low, s.metric_names)
    assert np.allclose(trend[j], b, rtol=0, atol=1e-9)
    assert not np.any(np.delete(trend, j, axis=0))  # no values: no trend
    few = TREND_MIN_ROWS_PER_COEFFICIENT * H.shape[1] - 1
    assert not np.any(fit_trend(targets[:few], base[:few], H[:few], s.delta, low, s.metric_names))
    # the contact patch (a ratio to the 2D displacement) has no trend, even with values
    area = list(s.metric_names).index("contact_area_at_1N_mm2")
    assert s.delta[area] == "disp_at_1N_from_touch_mm"
    targets[:, area] = np.exp(base[:, area] + H @ b)
    assert not np.any(fit_trend(targets, base, H, s.delta, low, s.metric_names)[area])
    with pytest.raises(ValueError, match="trend's shape"):  # set after construction: checked
        s.trend = trend[:, :-1]


def test_the_slice_methods_bases_are_the_slice_models_values(small3d, low):
    """``delta-slice``'s base, before its trend: each displacement reading is ln of the slice
    model's depth at its force from the 2D prediction's pair, the hysteresis the 2D one times
    the work ratio, and the contact patch the plate's overlap at the depth from touch
    (``surrogate._slice``, fed here with ``Surrogate.predict``'s medians and the points' pad);
    the other delta outputs keep the 2D prediction (the plate force), and so does a design whose
    2D readings give no power law (d_4 <= d_1: one design's pair from the undeformed top)."""
    from surrogate._multifidelity import MultiFidelitySurrogate
    from surrogate._slice import line_load_law, overlap, slice_depth, work_ratio

    data = read_sweep(small3d, dimension="3d")
    fit = fit_multifidelity(data, SHIPPED, "delta-slice", TINY, progress=False)
    s = fit.surrogate
    names = list(s.metric_names)
    features = s.encoder.encode(data.points).features
    bare = MultiFidelitySurrogate(
        "delta-slice", s.model, s.encoder, s.normaliser, s.metric_names, s.delta
    )
    plain = MultiFidelitySurrogate(
        "delta-contact", s.model, s.encoder, s.normaliser, s.metric_names, s.delta
    )
    base, plain_base = bare.base(features)[0], plain.base(features)[0]
    pred = low.predict([{k: v for k, v in p.items() if k in low.space.names} for p in data.points])
    two = {m: pred.median[:, j] for j, m in enumerate(pred.metric_names)}
    keys = ("half_width_mm", "height_mm", "exponent", "half_length_mm", "length_exponent")
    pad = {k: np.array([p[f"geometry.{k}"] for p in data.points]) for k in keys}
    pairs = {
        "touch": (two["disp_at_1N_from_touch_mm"], two["disp_at_4N_from_touch_mm"]),
        "top": (two["disp_at_1N_mm"], two["disp_at_4N_mm"]),
    }
    ok = {key: d4 > d1 for key, (d1, d4) in pairs.items()}  # elsewhere: the 2D base
    assert ok["touch"].all() and 0 < (~ok["top"]).sum() < 3  # the top pair: one design here
    with np.errstate(all="ignore"):
        touch, top = (line_load_law(*pairs[key]) for key in ("touch", "top"))
    shape = (pad["height_mm"], pad["half_length_mm"], pad["length_exponent"])
    close = {"rtol": 0, "atol": 1e-5}  # ln units: the features are float32
    for f in (1, 4):
        depth = slice_depth(float(f), *touch, *shape)
        got = base[:, names.index(f"disp_at_{f}N_from_touch_mm")]
        np.testing.assert_allclose(got, np.log(depth), **close)
        j = names.index(f"disp_at_{f}N_mm")
        top_ok = ok["top"]
        with np.errstate(all="ignore"):
            want = np.log(slice_depth(float(f), *(v[top_ok] for v in (*top, *shape))))
        np.testing.assert_allclose(base[top_ok, j], want, **close)
        assert np.array_equal(base[~top_ok, j], plain_base[~top_ok, j])
        patch = overlap(depth, pad["half_width_mm"], pad["height_mm"], pad["exponent"],
                        pad["half_length_mm"], pad["length_exponent"])  # fmt: skip
        for what, unit in (("area", "mm2"), ("width", "mm"), ("length", "mm")):
            got = base[:, names.index(f"contact_{what}_at_{f}N_{unit}")]
            np.testing.assert_allclose(got, np.log(patch[what]), **close)
    h = names.index("hysteresis_Nmm")
    ratio = work_ratio(two["disp_at_1N_from_touch_mm"], two["disp_at_4N_from_touch_mm"], *shape)
    np.testing.assert_allclose(np.exp(base[:, h] - plain_base[:, h]), ratio, rtol=1e-5)
    j = names.index("plate_force_at_1mm_N")
    assert np.array_equal(base[:, j], plain_base[:, j])


def test_a_few_values_a_log_scale_cannot_take_are_left_out_not_the_delta(low):
    """A delta output on a log scale keeps its base when at most ``DELTA_UNMAPPED_MAX`` of its
    training values are <= 0 (a failed reading: those values are not learnt, ``unmapped``), and
    is learnt directly when more are (its scale is wrong)."""
    from surrogate._multifidelity import DELTA_UNMAPPED_MAX, delta_outputs, unmapped

    names = ["disp_at_1N_mm", "contact_area_at_1N_mm2"]
    proxies = {"contact_area_at_1N_mm2": "disp_at_1N_from_touch_mm"}
    y = np.column_stack([np.linspace(0.2, 1.0, 40), np.linspace(5.0, 90.0, 40)])
    y[3, 1] = 0.0  # one failed reading of 40: 2.5 %
    delta = delta_outputs(names, low, y, proxies)
    assert delta == ("disp_at_1N_mm", "disp_at_1N_from_touch_mm")
    assert np.array_equal(np.flatnonzero(unmapped(y, delta, low)), [3 * 2 + 1])
    y[: int(DELTA_UNMAPPED_MAX * 40) + 1, 1] = 0.0  # more than the share
    assert delta_outputs(names, low, y, proxies) == ("disp_at_1N_mm", None)
    assert not unmapped(y, ("disp_at_1N_mm", None), low).any()


def test_a_changed_low_fidelity_file_or_checkpoint_is_refused(small3d, low_copy, tmp_path):
    """The low fidelity is read from the recorded path and refused unless its sha256 is the
    recorded one (another valid checkpoint there, or none), with one line; a tampered
    multi-fidelity file, a 2D checkpoint given as one and one given to ``load_checkpoint`` are
    refused as ``load_checkpoint`` refuses files."""
    data = read_sweep(small3d, dimension="3d")
    fit = fit_multifidelity(data, low_copy, "input", TINY, progress=False)
    path = save_multifidelity(fit.surrogate, tmp_path / "mf.safetensors")
    assert load_multifidelity(path).header["low_fidelity"]["path"] == str(low_copy.resolve())
    original = low_copy.read_bytes()
    other = load_checkpoint(low_copy)
    other.header["note"] = "another checkpoint, valid on its own"
    save_checkpoint(other, low_copy)
    try:
        with pytest.raises(CheckpointError, match="not the one it was trained with") as err:
            load_multifidelity(path)
        assert len(str(err.value).splitlines()) == 1
        load_multifidelity(path, low_fidelity=SHIPPED_FILE)  # the same bytes elsewhere
        low_copy.unlink()
        with pytest.raises(CheckpointError, match="is missing"):
            load_multifidelity(path)
    finally:
        low_copy.write_bytes(original)
    blob = bytearray(path.read_bytes())
    blob[-3] ^= 0xFF  # a weight's last byte
    (tmp_path / "tampered.safetensors").write_bytes(bytes(blob))
    with pytest.raises(CheckpointError, match="tampered or corrupted"):
        load_multifidelity(tmp_path / "tampered.safetensors")
    with pytest.raises(CheckpointError, match="a 2D surrogate checkpoint"):
        load_multifidelity(SHIPPED_FILE)
    with pytest.raises(CheckpointError, match=r"load it with surrogate\.load_multifidelity"):
        load_checkpoint(path)
    (tmp_path / "junk.safetensors").write_text("not a checkpoint")
    with pytest.raises(CheckpointError, match="not a multi-fidelity checkpoint"):
        load_multifidelity(tmp_path / "junk.safetensors")


def test_the_finetune_starts_as_the_2d_surrogate(low):
    """The finetune method's start: the 2D ensemble with the pad's inputs at zero weight, so
    that every 2D output of a 3D point is the 2D surrogate's for its section and layers (to
    float32 round-off), whatever the pad; the 3D-only outputs get fresh weights."""
    from surrogate._encoding import Encoder
    from surrogate._model import EnsembleMLP
    from surrogate._train import metric_groups

    space = load_space(DEFAULT_SPACE_3D_PATH)
    own = Encoder(space, omega_rad_s=low.encoder.omega_rad_s, log_tangents=low.encoder.log_tangents)
    names = (*METRICS, *METRICS_3D, *low.metric_names[len(METRICS) :])
    model = EnsembleMLP(
        own.n_features, len(names), members=low.model.members, hidden=low.model.hidden,
        groups=metric_groups(names, "tapping_metrics"), seed=1,
    )  # fmt: skip
    FineTune.start(model, low, own, names)
    points = sample_points(space, 64, 5)
    x3 = torch.from_numpy(own.encode(points).features)
    section = [{k: v for k, v in p.items() if k in low.space.names} for p in points]
    x2 = torch.from_numpy(low.encoder.encode(section).features)
    with torch.no_grad():
        mean3, logvar3 = model(x3)
        mean2, logvar2 = low.model(x2)
    shared = [names.index(m) for m in low.metric_names]
    torch.testing.assert_close(mean3[:, :, shared], mean2, rtol=1e-5, atol=1e-5)
    torch.testing.assert_close(logvar3[:, :, shared], logvar2, rtol=1e-5, atol=1e-5)
    first = model.weights[0].detach()
    pad = [own.feature_names.index(f"geometry.{k}") for k in ("half_length_mm", "length_exponent")]
    assert torch.all(first[:, pad, :] == 0)


def run_main(argv: list, capsys) -> tuple[int, str, str]:
    code = explore.cli.main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return code, out, err


def one_line(err: str) -> str:
    assert "Traceback" not in err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(ERROR_PREFIX), err
    return lines[0].removeprefix(ERROR_PREFIX)


@pytest.mark.parametrize(
    ("extra", "message"),
    [
        (["--low-fidelity", SHIPPED, "--method", "kriging"],
         "--method: must be one of 3d, input, delta, delta-contact, delta-trend, delta-slice, "
         "finetune, got "
         "'kriging'"),
        (["--method", "delta"], "--low-fidelity: --method delta needs the 2D surrogate"),
        (["--low-fidelity", SHIPPED, "--method", "3d"],
         "--method: 3d trains on the 3D designs alone: drop --low-fidelity"),
        (["--low-fidelity", "no/such/model.safetensors"], "no such checkpoint file"),
        (["--low-fidelity", SHIPPED / "report.md"], "not a surrogate checkpoint"),
        (["--seeds", "0", "1"], "--seeds: one training per seed is for 2D sweeps"),
    ],
)  # fmt: skip
def test_cli_bad_multifidelity_input_is_one_line(small3d, tmp_path, capsys, extra, message):
    code, _, err = run_main(["train", small3d, "--out", tmp_path / "out", *extra], capsys)
    assert code == 2 and message in one_line(err)
    assert not (tmp_path / "out").exists()


def test_cli_low_fidelity_with_a_2d_sweep_is_one_line(tmp_path, capsys):
    code, _, err = run_main(
        ["train", SHIPPED, "--low-fidelity", SHIPPED, "--out", tmp_path / "o"], capsys
    )
    assert code == 2
    assert "--low-fidelity:" in one_line(err) and "not a sweep of the 3D model" in err


def test_cli_trains_a_3d_sweep_with_the_2d_surrogate(small3d, tmp_path, capsys, monkeypatch):
    """``fingertip train SWEEP3D --low-fidelity CHECKPOINT``: the default method (delta-slice), a
    run folder whose checkpoint loads with ``load_multifidelity`` and whose report scores the
    3D metrics; without --low-fidelity the same sweep trains 3D-only."""
    import surrogate._multifidelity_run as run

    monkeypatch.setattr(run, "SPEED_N", 64)
    out = tmp_path / "mf"
    argv = ["train", small3d, "--low-fidelity", SHIPPED, "--out", out, "--members", "2",
            "--max-epochs", "10", "--no-progress"]  # fmt: skip
    code, stdout, err = run_main(argv, capsys)
    assert code == 0, err
    assert "method: delta-slice" in stdout and "contact_area_at_1N_mm2" in stdout
    model = load_multifidelity(out)
    assert model.method.name == "delta-slice" and model.members == 2
    report = json.loads((out / "report.json").read_text())
    assert report["method"] == "delta-slice" and "contact_area_at_4N_mm2" in report["metrics"]
    assert json.loads((out / "meta.json").read_text())["kind"] == "train"
    argv = ["train", small3d, "--out", tmp_path / "3d", "--members", "2", "--max-epochs", "5",
            "--no-progress"]  # fmt: skip
    code, stdout, err = run_main(argv, capsys)
    assert code == 0, err
    assert "method: 3d (low fidelity: none, 3D only)" in stdout
    assert load_multifidelity(tmp_path / "3d").header["low_fidelity"] is None
    # fingertip predict reads the multi-fidelity checkpoint: the 3D sweep's own points get the
    # 3D metrics, contact patch included
    code, stdout, err = run_main(["predict", out, small3d / "table.csv", "--json"], capsys)
    assert code == 0, err
    designs = json.loads(stdout)["designs"]
    assert len(designs) == 40
    assert all(d["median"]["contact_area_at_1N_mm2"] > 0 for d in designs)


def test_the_ratio_study_recovers_the_pad_shapes_exponents_of_a_known_map(small3d):
    """``studies/ratio3d.py`` fits ln(3D / 2D) ~ b0 + b1 ln c + b2 ln m + b3 ln a. The synthetic
    3D hysteresis is the 2D one times exp(0.1 + 0.2 ln(c / 11) - 0.04 ln(m / 4)) with 0.2 %
    noise (``mf_fixtures.synthetic_3d``): the fit must give those exponents back."""
    import importlib.util
    import math

    path = Path(__file__).resolve().parents[1] / "studies" / "ratio3d.py"
    spec = importlib.util.spec_from_file_location("ratio3d", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    rows = module.ratios(small3d, SHIPPED)
    h = rows["hysteresis_Nmm"]
    b0, b1, b2, b3 = h["coef"]
    assert h["n"] >= 20
    assert b1 == pytest.approx(0.2, abs=0.01) and b2 == pytest.approx(-0.04, abs=0.01)
    assert b3 == pytest.approx(0.0, abs=0.01)
    assert b0 == pytest.approx(0.1 - 0.2 * math.log(11.0) + 0.04 * math.log(4.0), abs=0.03)
    assert h["residual_std"] < 0.005 < h["std"]  # the noise alone is left; the shape was not
