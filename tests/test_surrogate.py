"""The neural surrogate (surrogate/): encoding, normalisers, the vectorised ensemble,
reproducible training, safe checkpoints, the training domain, the report, and the
``fingertip train`` / ``fingertip predict`` commands.

Everything runs on ONE small real sweep (8 designs of a tiny space, built once per session
by ``fingertip sweep``) and on short trainings: the tests check the machinery, not accuracy.
"""

from __future__ import annotations

import json
import math
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import torch
from sweep_fixtures import FAST, TINY

import explore.cli
from sim import METRICS, SOLVER_VERSION
from sim.design import is_family, load_space, param_material
from sim.errors import DesignError
from sim.materials import CATALOGUE
from sim.protocols import LAYER_STRAIN_OUTPUTS, TRUST_OUTPUTS
from sim.provenance import sha256_file
from sim.sweep import sample_points
from surrogate import (
    CheckpointError,
    Encoder,
    TrainConfig,
    load_checkpoint,
    read_points,
    read_sweep,
    save_checkpoint,
)
from surrogate._checkpoint import SCHEMA_VERSION, read_checkpoint, write_checkpoint
from surrogate._encoding import DESCRIPTOR_OMEGA_RAD_S, ELASTIC_FEATURE
from surrogate._model import EnsembleMLP
from surrogate._normalise import Z90, OutputNormaliser
from surrogate._surrogate import ZERO_IF_ELASTIC, Surrogate
from surrogate._train import calibration_factors, fit, metric_groups

REPO = Path(explore.cli.__file__).resolve().parents[1]
#: each layer's strain by role that a surrogate of the tiny space (one or two layers) learns
TWO_LAYERS = tuple(m for m in LAYER_STRAIN_OUTPUTS if "_middle_" not in m)
SHORT = TrainConfig(members=5, hidden=(16, 16), max_epochs=25, patience=25)
ERROR_PREFIX = "fingertip: error: "
CORE = "core.mu0_MPa = 0.05\ncore.alpha = 3.0\ncore.g_total = 0.2\ncore.tau_s = 0.3\n"


def run_cli(*args, cwd: Path) -> subprocess.CompletedProcess:
    # one torch thread: tiny networks gain nothing from more, and on a loaded machine
    # (a background FE sweep) idle-waiting OpenMP threads make every small op slow
    env = {**os.environ, "MPLBACKEND": "Agg", "OMP_NUM_THREADS": "1"}
    return subprocess.run(
        [sys.executable, "-m", "explore.cli", *map(str, args)],
        cwd=cwd,
        capture_output=True,
        text=True,
        timeout=600,
        env=env,
    )


@pytest.fixture(scope="module", autouse=True)
def one_torch_thread():
    """As ``run_cli``: one torch thread in this module, restored afterwards."""
    before = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(before)


def assert_one_line_error(stderr: str) -> str:
    assert "Traceback" not in stderr
    lines = stderr.strip().splitlines()
    assert len(lines) == 1, stderr
    assert lines[0].startswith(ERROR_PREFIX), lines[0]
    return lines[0]


@pytest.fixture(scope="session")
def sweep(tmp_path_factory) -> Path:
    """A real FE sweep: 8 designs (1 and 2 layers) of a tiny space, fast protocol options."""
    root = tmp_path_factory.mktemp("surrogate_sweep")
    space = root / "space.toml"
    space.write_text(TINY)
    out = root / "tiny"
    argv = ["sweep", str(space), "--n", "8", "--out", str(out), "--no-progress", *FAST]
    assert explore.cli.main(argv) == 0
    return out


@pytest.fixture(scope="session")
def data(sweep):
    return read_sweep(sweep)


@pytest.fixture(scope="session")
def cli_train(sweep, tmp_path_factory) -> tuple[subprocess.CompletedProcess, Path]:
    """``fingertip train`` as a subprocess; its checkpoint serves the checkpoint tests."""
    out = tmp_path_factory.mktemp("surrogate_run") / "run"
    args = ["train", sweep, "--out", out, "--seed", "0", "--members", "5", "--max-epochs", "40"]
    proc = run_cli(*args, "--no-progress", cwd=REPO)
    return proc, out


@pytest.fixture(scope="session")
def ckpt(cli_train) -> Path:
    proc, out = cli_train
    assert proc.returncode == 0, proc.stderr
    return out / "model.safetensors"


# ----------------------------------------------------------------------------- encoding
def test_encoding_round_trip_and_inactive_parameters(data):
    enc = Encoder(data.space)
    x = enc.encode(data.points).features
    assert x.shape == (len(data.points), enc.n_features)
    assert np.all((x >= 0) & (x <= 1))
    # fixed parameters give no feature; optional floats an active flag; choices one-hot
    assert not any(f.startswith(("geometry.", "core.nu")) for f in enc.feature_names)
    assert "skin.thickness_mm:active" in enc.feature_names
    assert "core.mu0_MPa:active" not in enc.feature_names  # the core is always "param"
    back = enc.decode(x)
    for p, q in zip(data.points, back, strict=True):
        assert p.keys() == q.keys()
        for k in p:
            if isinstance(p[k], float):
                assert (math.isnan(p[k]) and math.isnan(q[k])) or q[k] == pytest.approx(
                    p[k], rel=1e-5
                ), k
            else:
                assert p[k] == q[k], k
    one = next(i for i, p in enumerate(data.points) if p["layers.count"] == 1)
    two = next(i for i, p in enumerate(data.points) if p["layers.count"] == 2)
    cols = {f: j for j, f in enumerate(enc.feature_names)}
    skin = [j for f, j in cols.items() if f.startswith("skin.")]
    assert np.all(x[one, skin] == 0)  # inactive: value 0, flag 0, one-hot all zeros
    assert x[two, cols["skin.thickness_mm:active"]] == 1
    assert (
        x[
            two, [cols["skin.material=silicone_gls40"], cols["skin.material=polyurethane_74_45"]]
        ].sum()
        == 1
    )
    # values given for parameters a design does not use never reach the network
    noisy = dict(data.points[one], **{"skin.thickness_mm": 0.7, "skin.material": "silicone_gls40"})
    np.testing.assert_array_equal(enc.encode([noisy]).features[0], x[one])
    # log scale where the space says so: the geometric mean of the bounds is mid-range
    mid = dict(data.points[one], **{"core.mu0_MPa": math.sqrt(0.02 * 0.1)})
    assert enc.encode([mid]).features[0, cols["core.mu0_MPa"]] == pytest.approx(0.5, abs=1e-6)
    # a table (name -> column) encodes like the list of points
    table = {k: [p[k] for p in data.points] for k in data.space.names}
    np.testing.assert_array_equal(enc.encode(table).features, x)
    with pytest.raises(DesignError, match=r"core\.alpha"):
        enc.encode([{**data.points[one], "core.alpha": math.nan}])
    with pytest.raises(DesignError, match="unknown parameter"):
        enc.encode([{**data.points[one], "core.mu0_mpa": 0.05}])


# ----------------------------------------------------------------------------- descriptors
def _dynamic_moduli(material, omega: float) -> tuple[float, float]:
    """Storage and loss modulus (MPa) from the Fourier transform of the relaxation function:
    G*(w) = G0 [g_inf + i w int_0^inf (g(t) - g_inf) exp(-i w t) dt] (quadrature)."""
    from scipy.integrate import quad

    prony = material.prony
    g_inf = prony.g_inf
    g0 = material.long_term.initial_shear_modulus_MPa / g_inf
    if prony.is_elastic:
        return g0, 0.0
    end = 60.0 * max(prony.tau_s)

    def f(t: float) -> float:
        return float(prony.relaxation(t)) - g_inf

    sin = quad(f, 0.0, end, weight="sin", wvar=omega, limit=500)[0]
    cos = quad(f, 0.0, end, weight="cos", wvar=omega, limit=500)[0]
    return g0 * (g_inf + omega * sin), g0 * omega * cos


def test_material_descriptors_are_the_dynamic_moduli_of_the_prony_series():
    """Catalogue and "param" materials land on the same axes: long-term modulus, storage
    modulus and loss tangent, checked against a quadrature of the relaxation function."""
    space = load_space()
    enc = Encoder(space)
    core = {"mu0_MPa": 0.02, "alpha": 4.0, "nu": 0.47, "g_total": 0.5, "tau_s": 0.7}
    base = {
        "geometry.half_width_mm": 6.0,
        "geometry.height_mm": 5.5,
        "geometry.exponent": 2.0,
        "layers.count": 2,
        "skin.thickness_mm": 0.8,
        "skin.material": "polyurethane_74_45",
        "core.material": "param",
        **{f"core.{k}": v for k, v in core.items()},
    }
    x = enc.encode([base]).features[0]
    col = {f: j for j, f in enumerate(enc.feature_names)}
    w = DESCRIPTOR_OMEGA_RAD_S
    assert w == pytest.approx(2 * math.pi * 0.5)  # the default tap: 0.5 Hz
    for role, material in (
        ("skin", CATALOGUE["polyurethane_74_45"]),
        ("core", param_material(**core)),
    ):
        mu = material.long_term.initial_shear_modulus_MPa
        assert x[col[f"{role}:log10_mu_MPa"]] == pytest.approx((math.log10(mu) + 3) / 3, rel=1e-6)
        storage, _ = _dynamic_moduli(material, w)
        got = 10 ** (3 * x[col[f"{role}:log10_storage_MPa"]] - 3)
        assert got == pytest.approx(storage, rel=1e-5)
        for r in (1 / 3, 1, 3):
            s_r, l_r = _dynamic_moduli(material, r * w)
            assert x[col[f"{role}:tan_delta@{r:.3g}w"]] == pytest.approx(l_r / s_r, rel=1e-5)
        assert x[col[f"{role}:tan_delta@1w"]] > 0.01  # both relax around the tap's frequency
    assert x[col[ELASTIC_FEATURE]] == 0
    # elastic: no active layer relaxes (an Ecoflex skin over a core with g_total = 0; Ecoflex
    # alone); the skin's descriptors vanish when the skin is inactive
    elastic_two = {**base, "skin.material": "ecoflex_0030_dawood", "core.g_total": 0.0}
    one = {**base, "layers.count": 1, "core.material": "ecoflex_0010_dawood"}
    xe = enc.encode([elastic_two, one, {**base, "core.g_total": 0.0}]).features
    assert xe[:, col[ELASTIC_FEATURE]].tolist() == [1.0, 1.0, 0.0]
    assert np.all(xe[1, [j for f, j in col.items() if f.startswith("skin:")]] == 0)
    assert xe[0, col["skin:tan_delta@1w"]] == 0 and xe[0, col["core:tan_delta@1w"]] == 0
    # an unknown material is flagged out of domain, has no descriptors and is not "elastic"
    odd = enc.encode([{**elastic_two, "skin.material": "unobtainium"}])
    assert not odd.in_domain[0] and "unknown choice" in odd.reasons[0]
    assert odd.features[0, col[ELASTIC_FEATURE]] == 0
    assert np.all(odd.features[0, [j for f, j in col.items() if f.startswith("skin:")]] == 0)


def test_an_elastic_designs_hysteresis_is_exactly_zero_by_rule():
    """No relaxation, no dissipation: the surrogate gives exactly 0 (std 0, marked by_rule)
    for the hysteresis of an elastic design and a learnt value for every other entry."""
    space = load_space()
    enc = Encoder(space)
    names = list(METRICS)
    rng = np.random.default_rng(0)
    norm = OutputNormaliser.fit(rng.lognormal(size=(40, len(names))))
    model = EnsembleMLP(enc.n_features, len(names), members=5, seed=0)
    sur = Surrogate(model, enc, norm, names)
    pts = [
        {**p, "core.g_total": 0.0} if is_family(p.get("core.material")) else p
        for p in sample_points(space, 32, 0)
    ]
    elastic = enc.encode(pts).features[:, enc.feature_names.index(ELASTIC_FEATURE)] > 0.5
    assert 0 < elastic.sum() < len(pts)
    pred = sur.predict(pts)
    j = names.index("hysteresis_Nmm")
    np.testing.assert_array_equal(pred.by_rule[:, j], elastic)
    assert not np.delete(pred.by_rule, j, axis=1).any()
    for a in (pred.mean, pred.median, pred.std, pred.lower_90, pred.upper_90):
        assert np.all(a[elastic, j] == 0)
    assert np.all(pred.median[~elastic, j] > 0) and np.all(pred.std[~elastic, j] > 0)
    assert ZERO_IF_ELASTIC == {"hysteresis_Nmm"}
    records = pred.to_records()
    assert [r["by_rule"] for r in records] == [["hysteresis_Nmm"] if e else [] for e in elastic]


# ----------------------------------------------------------------------------- normaliser
def test_output_normaliser_is_fitted_on_training_designs_only(data, ckpt):
    model = load_checkpoint(ckpt)
    split = model.header["training_data"]["split_table_index"]
    rows = {int(i): r for r, i in enumerate(data.index)}
    train = [rows[i] for i in split["train"]]
    held_out = [rows[i] for i in split["val"] + split["test"]]
    assert train and held_out and not set(train) & set(held_out)
    expected = OutputNormaliser.fit(data.targets[train])
    np.testing.assert_array_equal(model.normaliser.shift, expected.shift)
    np.testing.assert_array_equal(model.normaliser.scale, expected.scale)
    np.testing.assert_array_equal(model.normaliser.log, expected.log)
    everything = OutputNormaliser.fit(data.targets)
    observed = expected.observed > 0
    assert not np.allclose(everything.shift[observed], expected.shift[observed])
    # positive metrics are learnt on a log scale; a metric never observed is not predicted
    assert model.normaliser.log[list(model.metric_names).index("disp_at_1N_mm")]
    never = ~observed
    assert never.any()  # wedge_force_at_100s_N: the fast sweep holds the wedge for 5 s only
    pred = model.predict(data.points[:2])
    assert np.isnan(pred.mean[:, never]).all() and np.isfinite(pred.mean[:, observed]).all()


def test_conformal_calibration_gives_the_90_percent_interval_its_coverage():
    """An ensemble whose spread is half (metric 0) or twice (metric 1) the true scatter: the
    calibrated factor is about 2 or 1/2, and fresh designs fall inside the calibrated 90 %
    interval 90 % of the time (split conformal); a metric with too few validation values and a
    trust output keep the ensemble's own spread."""
    rng = np.random.default_rng(0)
    names = ["disp_at_1N_mm", "hysteresis_Nmm", "sag_mm", next(iter(TRUST_OUTPUTS))]
    true_sd = np.array([2.0, 0.5, 1.0, 3.0])

    def draw(n):
        mean = rng.normal(size=(n, 4))
        std = rng.uniform(0.5, 1.5, size=(n, 4))  # per design, as an ensemble's
        return mean, std, mean + true_sd * std * rng.normal(size=(n, 4))

    mean, std, z = draw(2000)
    z[19:, 2] = np.nan  # 19 values: fewer than the minimum
    factors, info = calibration_factors(mean, std, z, names)
    assert factors[0] == pytest.approx(2.0, rel=0.06)
    assert factors[1] == pytest.approx(0.5, rel=0.06)
    assert factors[2] == 1.0 and info["n"]["sag_mm"] == 19
    assert factors[3] == 1.0  # a trust output
    # on the calibration designs themselves at least 90 % inside (the conformal quantile)
    inside = np.abs(z - mean) <= Z90 * factors * std
    assert inside[:, :2].mean(axis=0).min() >= 0.90
    # and on fresh ones 90 % up to sampling (binomial sd 0.3 % on 10000)
    mean, std, z = draw(10000)
    fresh = (np.abs(z - mean) <= Z90 * factors * std)[:, :2].mean(axis=0)
    np.testing.assert_allclose(fresh, 0.90, atol=0.015)
    uncalibrated = (np.abs(z - mean) <= Z90 * std)[:, :2].mean(axis=0)
    assert uncalibrated[0] < 0.65 and uncalibrated[1] > 0.99


def test_a_capped_validation_nll_is_not_ruled_by_one_unpredictable_entry():
    """Early stopping's score (``VALIDATION_NLL_CAP``): a net that fits its outputs well but is
    sure of a yes/no flag that one validation design breaks (an FE failure nothing predicts)
    beats a net that fits everything loosely; the plain NLL ranks them the other way round,
    which kept a whole net of the 4096-design sweep's ensemble at epoch 0."""
    from surrogate._model import gaussian_nll
    from surrogate._train import VALIDATION_NLL_CAP

    n, m = 40, 5
    y = torch.zeros(1, n, m)
    y[0, 0, 4] = 4.0  # the flag of one design: 4 normalised units from all the others
    mask = torch.ones(1, n, m)
    sure = (torch.zeros(1, n, m), torch.full((1, n, m), -6.0))  # sigma 0.05 everywhere
    loose = (torch.zeros(1, n, m), torch.full((1, n, m), 1.0))  # sigma 1.6 everywhere
    plain = [float(gaussian_nll(*net, y, mask)) for net in (sure, loose)]
    capped = [float(gaussian_nll(*net, y, mask, cap=VALIDATION_NLL_CAP)) for net in (sure, loose)]
    assert plain[0] > plain[1]  # 3200 nats on one entry outweigh 199 entries fitted 3 nats better
    assert capped[0] < capped[1]
    # the cap changes nothing where no entry reaches it
    assert float(gaussian_nll(*loose, y, mask, cap=VALIDATION_NLL_CAP)) == plain[1]


def test_the_interval_scale_widens_the_interval_in_the_normalised_space():
    rng = np.random.default_rng(1)
    norm = OutputNormaliser.fit(rng.lognormal(size=(50, 2)) * [1.0, 3.0])
    mean_z, std_z = rng.normal(size=(5, 2)), rng.uniform(0.1, 0.5, size=(5, 2))
    plain = norm.to_physical(mean_z, std_z)
    wide = norm.calibrated(np.array([2.0, 0.5])).to_physical(mean_z, std_z)
    np.testing.assert_array_equal(wide["median"], plain["median"])  # the point prediction stays
    half_plain = np.log(plain["upper_90"]) - np.log(plain["median"])  # Z90 x std in log space
    half_wide = np.log(wide["upper_90"]) - np.log(wide["median"])
    np.testing.assert_allclose(half_wide, half_plain * [2.0, 0.5], rtol=1e-12)
    # a checkpoint written before the calibration has no factors: the ensemble's own spread
    arrays = norm.arrays()
    del arrays["interval_scale"]
    np.testing.assert_array_equal(OutputNormaliser.from_arrays(arrays).interval_scale, [1, 1])
    with pytest.raises(ValueError, match="one positive factor per metric"):
        norm.calibrated(np.array([1.0, 0.0]))


def test_a_nonnegative_metric_that_reaches_zero_is_learnt_on_a_shifted_log_scale():
    """Hysteresis is 0 (up to round-off, even -1e-4) for elastic skins and spans decades for the
    rest: log(y + offset) keeps both; a genuinely signed metric stays linear."""
    rng = np.random.default_rng(0)
    hyst = np.concatenate([rng.lognormal(-1.5, 1.0, 80), [0.0, -1e-4, 0.0, 2e-5]])
    signed = rng.normal(0.0, 1.0, hyst.size)
    positive = rng.lognormal(0.0, 0.5, hyst.size)
    y = np.column_stack([hyst, signed, positive])
    norm = OutputNormaliser.fit(y)
    assert norm.log.tolist() == [True, False, True]
    assert norm.offset[0] > 1e-4 and norm.offset[1] == 0 and norm.offset[2] == 0
    z = norm.transform(y)
    assert np.isfinite(z).all()
    back = norm.to_physical(z, np.zeros_like(z))  # a zero-width Gaussian maps back exactly
    np.testing.assert_allclose(back["mean"], y, rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(back["lower_90"], y, rtol=1e-12, atol=1e-15)
    # the log-normal mean is above the median by exp(s^2/2), the offset taken off after
    s = np.full_like(z, 0.3)
    out = norm.to_physical(z, s)
    m = norm.shift[0] + norm.scale[0] * z[:, 0]
    sd = norm.scale[0] * 0.3
    np.testing.assert_allclose(out["mean"][:, 0], np.exp(m + sd**2 / 2) - norm.offset[0])


# ----------------------------------------------------------------------------- ensemble
def test_the_tapping_metrics_have_nets_of_their_own():
    """By default ("tapping_metrics") the tapping protocol's FE metrics have a net of their own
    and every trust output goes with the plate and wedge metrics; "tapping" (the grouping of
    the checkpoints trained before) puts the tapping's trust outputs with its metrics."""
    from surrogate._train import TrainConfig

    assert TrainConfig().groups == "tapping_metrics"
    names = list(METRICS)
    for grouping in ("tapping_metrics", "tapping"):
        groups = metric_groups(names, grouping)
        for name, g in zip(names, groups, strict=True):
            assert g == (0 if METRICS[name][0] == "tapping" else 1), (grouping, name)
    # the trust outputs: by default with the plate and wedge metrics; with "tapping" in their
    # protocol's net ("any": the plate/wedge one)
    assert set(metric_groups([*names, *TRUST_OUTPUTS], "tapping_metrics")[len(names) :]) == {1}
    trust = metric_groups([*names, *TRUST_OUTPUTS], "tapping")[len(names) :]
    for name, g in zip(TRUST_OUTPUTS, trust, strict=True):
        assert g == (0 if TRUST_OUTPUTS[name] == "tapping" else 1), name
    layers = metric_groups([*names, *LAYER_STRAIN_OUTPUTS], "tapping")[len(names) :]
    for name, g in zip(LAYER_STRAIN_OUTPUTS, layers, strict=True):
        assert g == (0 if name.startswith("tapping_") else 1), name
    assert set(metric_groups(names, "none")) == {0}
    for grouping in ("tapping_metrics", "tapping"):
        pair = ["wedge_peak_force_N", "plate_force_at_1mm_N"]
        assert metric_groups(pair, grouping) == (0, 0)
    with pytest.raises(ValueError, match="groups"):
        metric_groups(names, "by_unit")


def test_ensemble_is_vectorised_and_equals_a_loop_over_members(ckpt, data):
    model = load_checkpoint(ckpt)
    assert model.members >= 5
    net = model.model
    # stacked weights: one net per member and metric group (tapping | plate and wedge)
    assert net.n_groups == 2
    assert net.weights[0].shape[0] == model.members * net.n_groups
    x = torch.from_numpy(model.encoder.encode(data.points).features)
    with torch.no_grad():
        mean, logvar = net(x)
        for k in range(model.members):
            m_k, lv_k = net.forward_member(x, k)
            torch.testing.assert_close(mean[k], m_k, rtol=1e-5, atol=1e-6)
            torch.testing.assert_close(logvar[k], lv_k, rtol=1e-5, atol=1e-6)
        # members differ (independent initialisations), so the ensemble has a spread
        assert not torch.allclose(mean[0], mean[1])


def test_training_is_reproducible_from_the_seed(data):
    a = fit(data, SHORT, progress=False)
    b = fit(data, SHORT, progress=False)
    c = fit(data, TrainConfig(**{**SHORT.__dict__, "seed": 1}), progress=False)
    sa, sb, sc = (r.surrogate.model.state_dict() for r in (a, b, c))
    assert all(torch.equal(sa[k], sb[k]) for k in sa)
    assert not all(torch.equal(sa[k], sc[k]) for k in sa)
    assert a.history == b.history
    np.testing.assert_array_equal(a.split.train, b.split.train)


def test_the_learning_rate_decays_net_by_net_on_a_plateau():
    """``_LearningRate``: a net whose validation NLL last improved at epoch b has its rate cut
    by ``lr_decay`` at epochs b + k ``decay_patience`` (k = 1..lr_decays), going back to its
    best weights each time; a cut net's update is the optimiser's scaled by its factor; training
    stops when every net is ``patience`` epochs past its last improvement or cut with no cut
    left. ``lr_decay = 1``: a constant rate, stopping ``patience`` epochs after the last
    improvement of any net (the rule before)."""
    from surrogate._train import _Best, _LearningRate

    model = EnsembleMLP(3, 2, members=2, hidden=(4,), seed=0)  # 2 nets
    best = _Best.start(model)
    best.epoch = torch.tensor([9, 20])  # the nets' last improvements
    base = TrainConfig(lr=1.0, patience=30, decay_patience=7, lr_decays=3, lr_decay=1.0)

    def run(config):
        for p in model.parameters():
            p.data.fill_(1.0)  # the "current" weights; the best are the initial ones
        rate, cuts = _LearningRate(model, config), []
        for epoch in range(21, 10_000):
            before = rate.scale.clone()
            stop = rate.stop_after(epoch, best)
            cuts += [(s, epoch) for s in torch.nonzero(rate.scale != before).flatten().tolist()]
            if stop:
                return epoch, cuts, rate
        raise AssertionError("never stopped")

    stop, cuts, rate = run(TrainConfig(**{**base.__dict__, "lr_decay": 0.5}))
    # net 0: quiet since 9, at epoch 21 already past 7: cut at once, then every 7 epochs
    assert sorted(cuts) == [(0, 21), (0, 28), (0, 35), (1, 27), (1, 34), (1, 41)]
    assert stop == 41 + 30
    torch.testing.assert_close(rate.scale, torch.tensor([0.125, 0.125]))
    for kept, p in zip(best.state, model.parameters(), strict=True):  # back to the best
        torch.testing.assert_close(p, kept)
    # a net's update is scaled by its factor: net 0 alone cut at epoch 16, then SGD on a
    # gradient of ones
    rate = _LearningRate(model, TrainConfig(**{**base.__dict__, "lr_decay": 0.5}))
    assert not rate.stop_after(16, best)
    torch.testing.assert_close(rate.scale, torch.tensor([0.5, 1.0]))
    opt = torch.optim.SGD(model.parameters(), lr=1.0)
    w = model.weights[0]
    start = w.detach().clone()
    rate.before_step()
    w.grad = torch.ones_like(w)
    opt.step()
    rate.after_step()
    torch.testing.assert_close(w.detach() - start, -torch.tensor([0.5, 1.0]).view(2, 1, 1) * w.grad)
    stop, cuts, _ = run(base)  # lr_decay = 1
    assert cuts == [] and stop == 20 + 30


def _warm_start_as_before(surrogate, data, points, targets, weight, epochs, seed):
    """What ``explore``'s retraining did before ``fine_tune`` (commit fb8dc93, with
    ``surrogate._train.fit`` and the sweep copied field by field): the reference."""
    import dataclasses

    from surrogate._train import Split

    new_points = [p for p in points for _ in range(weight)]
    new_targets = np.array([t for t in targets for _ in range(weight)]).reshape(
        -1, len(data.metric_names)
    )
    base = len(data.points)
    aug = dataclasses.replace(
        data,
        points=[*data.points, *new_points],
        targets=np.vstack([data.targets, new_targets]),
        index=np.concatenate([data.index, -1 - np.arange(len(new_points))]),
        n_rows=data.n_rows + len(new_points),
    )
    split_idx = surrogate.header["training_data"]["split_table_index"]
    row_of = {int(i): r for r, i in enumerate(data.index)}

    def rows(key: str) -> np.ndarray:
        return np.array([row_of[i] for i in split_idx.get(key, []) if i in row_of], dtype=int)

    train = np.concatenate([rows("train"), base + np.arange(len(new_points))])
    fields = {f.name for f in dataclasses.fields(TrainConfig)}
    old = {k: v for k, v in surrogate.header["training"].items() if k in fields}
    old = {k: tuple(v) if isinstance(v, list) else v for k, v in old.items()}
    config = TrainConfig(**{**old, "seed": seed, "max_epochs": epochs, "patience": epochs})
    split = Split(train, rows("val"), rows("test"))
    return fit(aug, config, progress=False, split=split, init=surrogate).surrogate


def test_fine_tune_is_the_warm_start_explore_made_before(data):
    """``surrogate.fine_tune`` (the public entry explore's retraining calls) gives the very
    weights, header and training rows of the private warm start it replaces."""
    from surrogate import fine_tune

    base = fit(data, SHORT, progress=False).surrogate
    points = [dict(data.points[0]), dict(data.points[3])]
    targets = data.targets[[0, 3]] * 1.05
    targets[1, 0] = np.nan  # a metric not learnt
    ticks: list[int] = []
    tuned = fine_tune(base, data, points, targets, epochs=7, seed=2, weight=3,
                      progress=ticks.append)  # fmt: skip
    before = _warm_start_as_before(base, data, points, targets, 3, 7, 2)
    sa, sb = tuned.model.state_dict(), before.model.state_dict()
    assert sa.keys() == sb.keys() and all(torch.equal(sa[k], sb[k]) for k in sa)
    drop = ("created_utc", "git_commit")
    assert {k: v for k, v in tuned.header.items() if k not in drop} == {
        k: v for k, v in before.header.items() if k not in drop
    }
    assert tuned.header["training_data"]["n_rows"] == data.n_rows + 6
    added = tuned.header["training_data"]["split_table_index"]["train"][-6:]
    assert added == [-1, -2, -3, -4, -5, -6]  # each new design three times, after the sweep's
    assert ticks == [1] * tuned.header["training"]["epochs"]
    with pytest.raises(ValueError, match="weight"):
        fine_tune(base, data, points, targets, epochs=1, seed=0, weight=0)
    # another minibatch size: recorded, and other weights (fewer optimiser steps per epoch)
    big = fine_tune(base, data, points, targets, epochs=7, seed=2, weight=3, batch_size=4)
    assert big.header["training"]["batch_size"] == 4 != tuned.header["training"]["batch_size"]
    sc = big.model.state_dict()
    assert not all(torch.equal(sa[k], sc[k]) for k in sa)
    # a rehearsal (4 sweep designs an epoch besides the new ones): recorded, other weights
    rehearsed = fine_tune(base, data, points, targets, epochs=7, seed=2, weight=3, replay=4)
    assert rehearsed.header["training"]["replay"] == 4 and tuned.header["training"]["replay"] == 0
    sd = rehearsed.model.state_dict()
    assert not all(torch.equal(sa[k], sd[k]) for k in sa)


def test_a_rehearsal_passes_over_every_new_design_and_a_fresh_draw_of_the_others():
    from surrogate._train import _epoch_order

    def gen() -> torch.Generator:
        return torch.Generator().manual_seed(3)

    # no rehearsal: the order the training always drew (the same random numbers)
    reference = torch.argsort(torch.rand(3, 50, generator=gen()), dim=1)
    assert torch.equal(_epoch_order(3, 50, 5, 0, gen()), reference)
    g = gen()
    first, second = _epoch_order(3, 50, 5, 10, g), _epoch_order(3, 50, 5, 10, g)
    for epoch in (first, second):
        assert epoch.shape == (3, 15)
        for row in epoch.tolist():
            assert len(set(row)) == 15 and set(range(45, 50)) <= set(row)
            assert all(0 <= r < 50 for r in row)
    old = [{r for r in row if r < 45} for row in first.tolist()]
    assert old != [{r for r in row if r < 45} for row in second.tolist()]  # drawn afresh
    assert len({frozenset(o) for o in old}) == 3  # each member its own draw
    # asking for as many as there are: every row
    assert sorted(_epoch_order(2, 50, 5, 45, gen())[0].tolist()) == list(range(50))


def test_sweep_data_with_rows_appends_designs_outside_the_table(data):
    more = data.with_rows([dict(data.points[1])], data.targets[[1]])
    assert len(more.points) == len(data.points) + 1 and more.n_rows == data.n_rows + 1
    assert more.index[-1] == -1 and np.array_equal(more.index[:-1], data.index)
    np.testing.assert_array_equal(more.targets[-1], data.targets[1])
    assert (more.space, more.table_sha256) == (data.space, data.table_sha256)
    with pytest.raises(ValueError, match="2 points but 1 rows"):
        data.with_rows([data.points[0], data.points[1]], data.targets[[1]])


# ----------------------------------------------------------------------------- checkpoints
def test_checkpoint_round_trip_gives_identical_predictions(data, sweep, tmp_path):
    trained = fit(data, SHORT, progress=False).surrogate
    # the tiny sweep's few validation designs leave every interval as the ensemble's ...
    assert set(trained.header["calibration"]["interval_scale"].values()) == {1.0}
    # ... so set factors by hand: they travel with the checkpoint
    factors = np.linspace(0.5, 1.5, len(trained.metric_names))
    trained.normaliser = trained.normaliser.calibrated(factors)
    path = save_checkpoint(trained, tmp_path / "m.safetensors")
    loaded = load_checkpoint(path)
    np.testing.assert_array_equal(loaded.normaliser.interval_scale, factors)
    p0, p1 = trained.predict(data.points), loaded.predict(data.points)
    for field in ("mean", "std", "lower_90", "upper_90", "in_domain"):
        np.testing.assert_array_equal(getattr(p0, field), getattr(p1, field))
    h = loaded.header
    assert h["schema_version"] == SCHEMA_VERSION and h["solver_version"] == SOLVER_VERSION
    assert h["training_data"]["table_sha256"] == sha256_file(sweep / "table.csv")
    assert h["training_data"]["sweep"] == str(sweep.resolve())  # outside the repository
    # each layer's strain by role: the roles the sweep's designs have (no middle layer here)
    assert [m["name"] for m in h["metrics"]] == [*METRICS, *TRUST_OUTPUTS, *TWO_LAYERS]
    units = {m["name"]: m["unit"] for m in h["metrics"]}
    trust = dict.fromkeys([*TRUST_OUTPUTS, *TWO_LAYERS], "")
    assert units == {k: v[1] for k, v in METRICS.items()} | trust
    assert h["space"] == data.space.to_dict() and h["git_commit"]
    assert {"ensemble_nll", "r2", "member_nll"} <= set(h["validation"])
    assert {p["name"]: p["unit"] for p in h["parameters"]}["core.mu0_MPa"] == "MPa"
    # re-saving the loaded model gives the same file content
    again = save_checkpoint(loaded, tmp_path / "again.safetensors")
    assert read_checkpoint(again)[1] == read_checkpoint(path)[1]


def _expect_refused(path: Path, match: str, **kw) -> None:
    with pytest.raises(CheckpointError, match=match) as info:
        load_checkpoint(path, **kw)
    assert "\n" not in str(info.value)


def test_tampered_checkpoint_is_refused(ckpt, tmp_path):
    raw = bytearray(ckpt.read_bytes())
    header_len = int.from_bytes(raw[:8], "little")
    raw[8 + header_len + 100] ^= 0x01  # one bit of one weight
    bad = tmp_path / "tampered.safetensors"
    bad.write_bytes(bytes(raw))
    _expect_refused(bad, "tampered")
    # editing the header (e.g. the recorded solver version) without the hash is caught too
    tensors, header = read_checkpoint(ckpt)
    from safetensors.numpy import save_file

    header["validation"]["ensemble_nll"] = -99.0
    save_file(tensors, str(bad), metadata={"fingertip_surrogate": json.dumps(header)})
    _expect_refused(bad, "tampered")


def test_wrong_schema_and_solver_versions_are_refused(ckpt, tmp_path):
    tensors, header = read_checkpoint(ckpt)
    path = write_checkpoint(
        tmp_path / "schema.safetensors", tensors, {**header, "schema_version": 99}
    )
    _expect_refused(path, "schema version 99")
    other = write_checkpoint(
        tmp_path / "solver.safetensors", tensors, {**header, "solver_version": "0.1-other"}
    )
    _expect_refused(other, "solver version '0.1-other'")
    assert load_checkpoint(other, allow_solver_mismatch=True).members == 5


def test_non_checkpoint_files_are_refused(tmp_path, ckpt):
    junk = tmp_path / "junk.safetensors"
    junk.write_bytes(np.random.default_rng(0).bytes(4096))
    _expect_refused(junk, "not a surrogate checkpoint")
    text = tmp_path / "design.toml"
    text.write_text('material = "silicone_gls40"\n')
    _expect_refused(text, "not a surrogate checkpoint")
    from safetensors.numpy import save_file

    plain = tmp_path / "plain.safetensors"
    save_file({"w": np.zeros(3, dtype=np.float32)}, str(plain))
    _expect_refused(plain, "not a surrogate checkpoint")
    _expect_refused(tmp_path / "missing.safetensors", "no such")
    truncated = tmp_path / "truncated.safetensors"
    truncated.write_bytes(ckpt.read_bytes()[:-50])
    _expect_refused(truncated, "not a surrogate checkpoint|tampered")


# ----------------------------------------------------------------------------- domain
def test_predict_flags_designs_outside_the_training_domain(ckpt, data):
    model = load_checkpoint(ckpt)
    split = model.header["training_data"]["split_table_index"]
    rows = {int(i): r for r, i in enumerate(data.index)}
    train = [data.points[rows[i]] for i in split["train"]]
    assert model.predict(train).in_domain.all()  # every training design is inside
    base = next(p for p in train if p["layers.count"] == 2)
    _, hi = model.encoder.ranges["core.alpha"]
    cases = {
        "outside the space": {"core.mu0_MPa": 0.5},
        "outside the training range": {"core.alpha": hi + 0.5 * (6.0 - hi)},
        "unknown choice": {"skin.material": "unobtainium"},
        "fixed in training": {"core.nu": 0.4},
    }
    assert hi < 6.0, "the training range must leave room inside the space"
    pred = model.predict([base] + [{**base, **c} for c in cases.values()])
    assert pred.in_domain.tolist() == [True] + [False] * len(cases)
    assert all(r for r in pred.reasons[1:]) and pred.reasons[0] == ""
    assert np.isfinite(pred.mean[:, 0]).all()  # flagged, still predicted
    ok = np.isfinite(pred.mean).all(axis=0)  # metrics the fast sweep reached
    assert (pred.std[:, ok] > 0).all() and (pred.lower_90[:, ok] < pred.upper_90[:, ok]).all()


# ----------------------------------------------------------------------------- report
def test_report_has_accuracy_calibration_parity_plots_and_speed(ckpt):
    run = ckpt.parent
    report = json.loads((run / "report.json").read_text())
    assert set(report["metrics"]) == set(METRICS) | set(TRUST_OUTPUTS) | set(TWO_LAYERS)
    assert 0 <= report["trust"]["accuracy"] <= 1 and report["trust"]["n"] > 0
    for s in report["metrics"].values():
        assert set(s) >= {"r2", "median_rel_error", "p95_rel_error", "coverage_90", "n"}
        assert s["coverage_90"] is None or 0 <= s["coverage_90"] <= 1
    speed = report["speed"]
    assert speed["model_designs_per_s"] > 0 and speed["end_to_end_designs_per_s"] > 0
    assert report["n_test"] >= 1
    for name in METRICS:
        png = run / "figures" / f"parity_{name}.png"
        assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    md = (run / "report.md").read_text()
    assert "designs/s" in md and "disp_at_1N_mm" in md
    for name in ("config.json", "meta.json", "history.json"):
        assert json.loads((run / name).read_text())
    meta = json.loads((run / "meta.json").read_text())
    assert meta["solver_version"] == SOLVER_VERSION and "torch" in meta["packages"]
    # torch's threads of the training (surrogate._threads: 1), in config.json and the header
    config = json.loads((run / "config.json").read_text())
    assert config["torch_threads"] == 1
    assert load_checkpoint(ckpt).header["training"]["torch_threads"] == 1


# ----------------------------------------------------------------------------- CLI
def test_cli_train_and_predict(cli_train, ckpt, data, sweep, tmp_path):
    proc, _ = cli_train
    assert proc.returncode == 0 and "checkpoint:" in proc.stdout
    point = data.points[0]
    lines = []
    for k, v in point.items():
        if (isinstance(v, float) and math.isnan(v)) or v == "":
            continue  # inactive
        lines.append(f"{k} = {json.dumps(v)}")  # dotted keys: a flat table of point names
    design = tmp_path / "point.toml"
    design.write_text("\n".join(lines) + "\n")
    res = run_cli("predict", ckpt, design, "--json", cwd=tmp_path)
    assert res.returncode == 0, res.stderr
    obj = json.loads(res.stdout)
    assert set(obj) == {"checkpoint", "units", "designs"} and len(obj["designs"]) == 1
    d = obj["designs"][0]
    assert set(d) == {
        "in_domain", "domain_note", "median", "mean", "std", "lower_90", "upper_90", "by_rule"
    }  # fmt: skip
    assert d["by_rule"] == []  # the tiny space has no elastic design
    assert set(d["mean"]) == set(METRICS) | set(TRUST_OUTPUTS) | set(TWO_LAYERS)
    expected = load_checkpoint(ckpt).predict([point])
    assert d["mean"]["disp_at_1N_mm"] == pytest.approx(expected.metric("disp_at_1N_mm")[0][0])
    # a CSV (the sweep's own table works) gives a table with mean ± std and the domain flag
    res = run_cli("predict", ckpt, sweep / "table.csv", cwd=tmp_path)
    assert res.returncode == 0, res.stderr
    assert res.stdout.count("design ") == len(read_points(sweep / "table.csv", data.space))
    assert "±" in res.stdout and "in domain" in res.stdout


def test_cli_refuses_a_corrupt_checkpoint_with_one_line(ckpt, tmp_path):
    bad = tmp_path / "corrupt.safetensors"
    bad.write_bytes(ckpt.read_bytes()[:2000])
    design = tmp_path / "p.toml"
    design.write_text("layers.count = 1\n")
    res = run_cli("predict", bad, design, cwd=tmp_path)
    assert res.returncode == 2
    assert "not a surrogate checkpoint" in assert_one_line_error(res.stderr)


def test_a_predicted_probability_and_its_interval_lie_in_0_1():
    """Issue 31, item 6b: the 0/1 trust outputs (``sim.protocols.trust.PROBABILITY_OUTPUTS``) are
    predicted as probabilities: the shipped surrogate's Gaussian puts their 90 % intervals as
    low as -3 and as high as 3; every prediction of one is now within [0, 1], and only those
    are clipped (the other outputs keep their bits)."""
    from explore._config import DEFAULT_CHECKPOINT
    from sim.protocols import PROBABILITY_OUTPUTS

    model = load_checkpoint(DEFAULT_CHECKPOINT, allow_solver_mismatch=True)
    space = model.space
    points = space.points(np.random.default_rng(0).random((2000, len(space.sampled))))
    features = model.encoder.encode(points).features
    raw = model.normaliser.to_physical(*model.predict_normalised(features))
    pred = model.predict_features(features)
    prob = np.array([m in PROBABILITY_OUTPUTS for m in model.metric_names])
    assert prob.sum() == 3 and (raw["lower_90"][:, prob] < 0).any()  # what was shown before
    assert (raw["upper_90"][:, prob] > 1).any()
    for key in ("mean", "median", "lower_90", "upper_90"):
        assert ((pred[key][:, prob] >= 0) & (pred[key][:, prob] <= 1)).all(), key
        learnt = ~prob & ~pred["by_rule"].any(axis=0)
        np.testing.assert_array_equal(pred[key][:, learnt], raw[key][:, learnt])
    np.testing.assert_array_equal(pred["std"][:, prob], raw["std"][:, prob])


def test_cli_predict_takes_a_training_folder_and_names_the_file_it_expects(tmp_path, capsys):
    """Issue 31, item 6e: `fingertip predict FOLDER` reads the folder's model.safetensors (a
    training run folder, the shipped one); a folder without it is one error line saying which
    file is expected (it said "no such checkpoint file")."""
    from explore._config import PRETRAINED

    space = load_space()
    point = space.point(np.full(len(space.sampled), 0.5))
    design = tmp_path / "point.toml"
    design.write_text(
        "".join(
            f"{k} = {json.dumps(v)}\n"
            for k, v in point.items()
            if v != "" and not (isinstance(v, float) and math.isnan(v))
        )
    )
    assert explore.cli.main(["predict", str(PRETRAINED), str(design), "--json"]) == 0
    by_folder = json.loads(capsys.readouterr().out)
    assert explore.cli.main(["predict", str(PRETRAINED / "model.safetensors"), str(design),
                             "--json"]) == 0  # fmt: skip
    assert json.loads(capsys.readouterr().out)["designs"] == by_folder["designs"]
    empty = tmp_path / "empty"
    empty.mkdir()
    assert explore.cli.main(["predict", str(empty), str(design)]) == 2
    line = assert_one_line_error(capsys.readouterr().err)
    assert str(empty) in line and "without model.safetensors" in line
    assert explore.cli.main(["predict", str(tmp_path / "nothing"), str(design)]) == 2
    assert "model.safetensors" in assert_one_line_error(capsys.readouterr().err)


@pytest.mark.parametrize(
    ("text", "field"),
    [
        ("layers.count = 1\n", "core.mu0_MPa"),  # missing active value
        ("layers.count = 1\n" + CORE.replace("0.05", "5.0"), "core.mu0_MPa"),  # outside
        (CORE + "layers.count = 4\n", "layers.count"),
        ("layers.count = 2\n" + CORE + 'skin.material = "silicone_gls40"\n', "skin.thickness_mm"),
        ("layers.count = 1\ncore.mu0 = 0.05\n", "core.mu0"),  # unknown name
        ("layers.count = [1\n", "DESIGNS"),  # malformed TOML
    ],
)
def test_cli_predict_bad_designs_in_process(ckpt, tmp_path, capsys, text, field):
    design = tmp_path / "p.toml"
    design.write_text(text)
    assert explore.cli.main(["predict", str(ckpt), str(design)]) == 2
    line = assert_one_line_error(capsys.readouterr().err)
    assert line.startswith(f"{ERROR_PREFIX}{field}")


def test_unsettled_or_invalid_designs_are_left_out_and_counted(sweep, tmp_path):
    """A copy of the sweep whose table marks one design unsettled, one invalid without a
    figure that says why, and one invalid through its wedge's J: their FE metrics are left out
    by default and counted, but those of a protocol whose own result is trusted are kept (the
    unsettled design's plate and wedge, the third design's taps and plate), while what made
    them untrusted (the trust outputs of ``sim.protocols.trust``) is still learnt;
    ``trusted_only=False`` keeps every metric; a table without the flags (a sweep made before they
    were recorded) is used whole and counted as unchecked, with no trust outputs."""
    import csv
    import shutil

    copy = tmp_path / "flagged"
    shutil.copytree(sweep, copy)
    with (copy / "table.csv").open(newline="") as fh:
        reader = csv.DictReader(fh)
        fields, rows = reader.fieldnames, list(reader)
    full = read_sweep(sweep)
    usable = [r for r in rows if int(r["index"]) in set(full.index.tolist())]
    usable[0]["settled"] = "False"
    usable[1]["valid"] = "False"
    usable[2]["valid"] = "False"
    usable[2]["wedge_min_J"] = "0.1"
    with (copy / "table.csv").open("w", newline="") as fh:
        writer = csv.DictWriter(fh, fields)
        writer.writeheader()
        writer.writerows(rows)
    data = read_sweep(copy)
    assert len(data.points) == len(full.points)  # kept, for their trust outputs
    n_fe = sum(m in METRICS for m in data.metric_names)
    assert data.metric_names[n_fe:] == (*TRUST_OUTPUTS, *TWO_LAYERS)
    protocol = np.array([METRICS[m][0] for m in data.metric_names[:n_fe]])
    for row, kept in zip(
        usable[:3], ({"plate", "wedge"}, set(), {"tapping", "plate"}), strict=True
    ):
        pos = data.index.tolist().index(int(row["index"]))
        mine = np.isin(protocol, sorted(kept))
        assert np.isnan(data.targets[pos, :n_fe][~mine]).all()
        np.testing.assert_array_equal(
            data.targets[pos, :n_fe][mine], full.targets[pos, :n_fe][mine]
        )
        assert np.isfinite(data.targets[pos, :n_fe][mine]).any() or not kept
        # every trust output (a layer's strain where the design has that layer)
        assert np.isfinite(data.targets[pos, n_fe : n_fe + len(TRUST_OUTPUTS)]).all()
    assert data.excluded.get("unsettled", 0) == full.excluded.get("unsettled", 0) + 1
    assert data.excluded.get("invalid", 0) == full.excluded.get("invalid", 0) + 2
    assert data.partial == full.partial + 2
    # the accuracy is scored on the designs trusted whole: their FE metrics only
    scored = data.scored_targets()
    for row in usable[:3]:
        pos = data.index.tolist().index(int(row["index"]))
        assert not data.whole[pos]
        assert np.isnan(scored[pos, :n_fe]).all()
        np.testing.assert_array_equal(scored[pos, n_fe:], data.targets[pos, n_fe:])
    assert data.whole.sum() == full.whole.sum() - 3
    assert data.unchecked == 0
    everything = read_sweep(copy, trusted_only=False)
    assert len(everything.points) == len(full.points)
    assert np.isfinite(everything.targets[:, :n_fe]).any(axis=1).all()
    old = [f for f in fields if f not in ("settled", "valid")]
    with (copy / "table.csv").open("w", newline="") as fh:
        writer = csv.DictWriter(fh, old, extrasaction="ignore")
        writer.writeheader()
        writer.writerows(rows)
    legacy = read_sweep(copy)
    assert len(legacy.points) == len(everything.points) == legacy.unchecked
    assert not set(TRUST_OUTPUTS) & set(legacy.metric_names)


def test_the_protocols_trusted_on_their_own_follow_the_validity_rules():
    """``_trusted_protocols`` judges each protocol's own figures with the sweep's validity
    options (the strain limit only where ``strain_limit_protocols`` says), the taps only when
    settled; a failed protocol (no figures) is not kept; when no figure says why the design is
    untrusted, nothing is kept."""
    from sim.protocols import ValidityOptions
    from surrogate._io import _trusted_protocols

    def row(**over):
        r = {"settled": "True", "valid": "False"}
        for p in ("tapping", "plate", "wedge"):
            r.update({f"{p}_max_compressive_log_strain": "0.3", f"{p}_min_J": "0.9",
                      f"{p}_reached_base": "False", f"{p}_folded": "False"})  # fmt: skip
        return {**r, **over}

    v = ValidityOptions(max_compressive_log_strain=0.6)  # a sweep made with the one limit
    assert _trusted_protocols(row(), v) == frozenset()  # nothing says why: keep nothing
    both = {"tapping", "plate"}
    assert _trusted_protocols(row(wedge_min_J="0.2"), v) == both
    # the wedge is not strain-limited by default: a strain beyond the limit does not blame it
    strained = row(tapping_max_compressive_log_strain="0.9")
    assert _trusted_protocols(strained, v) == {"plate", "wedge"}
    assert _trusted_protocols(row(wedge_max_compressive_log_strain="0.9"), v) == frozenset()
    limited = ValidityOptions(0.6, strain_limit_protocols="tapping,plate,wedge")
    high = row(wedge_max_compressive_log_strain="0.9")
    assert _trusted_protocols(high, limited) == both
    assert _trusted_protocols(row(plate_reached_base="True"), v) == {"tapping", "wedge"}
    assert _trusted_protocols(row(tapping_folded="True"), v) == {"plate", "wedge"}
    assert _trusted_protocols(row(settled="False", valid="True"), v) == {"plate", "wedge"}
    failed = row(wedge_min_J="", wedge_max_compressive_log_strain="", plate_min_J="0.3")
    assert _trusted_protocols(failed, v) == {"tapping"}
    # each layer held to its own limit: a table has no per-layer strains, so whether a
    # protocol's layers stayed within theirs is the verdict its record wrote (violations)
    own = ValidityOptions()
    core = "layer 1 (core, family.gel) compressive log strain 0.55 > 0.53 (argued)"
    beyond_own = row(tapping_max_compressive_log_strain="0.55", violations=f"{core} (tapping)")
    assert _trusted_protocols(beyond_own, own) == {"plate", "wedge"}
    assert _trusted_protocols(beyond_own, v) == frozenset()  # within the one 0.60
    within_own = row(tapping_max_compressive_log_strain="0.9")  # e.g. a foam core's 1.05
    assert _trusted_protocols(within_own, own) == frozenset()
    assert _trusted_protocols(within_own, v) == {"plate", "wedge"}


def test_the_encoding_takes_the_tap_frequency_of_the_sweep(tmp_path):
    """A sweep made with ``--set tapping.frequency_Hz=1`` is encoded at 1 Hz: the loss tangents
    of its relaxing materials are taken at the taps' frequency, in training, in prediction and
    after a checkpoint round trip; the other features do not depend on it."""
    import dataclasses
    import math

    from surrogate._io import SweepData

    space = load_space()
    rng = np.random.default_rng(0)
    pts = [space.point(rng.random(len(space.sampled))) for _ in range(40)]
    slow = Encoder(space, log_tangents=True)  # as trained by default
    fast = Encoder(space, omega_rad_s=2 * math.pi * 1.0, log_tangents=True)
    a, b = slow.encode(pts).features, fast.encode(pts).features
    tan = [j for j, f in enumerate(slow.feature_names) if "tan_delta" in f or "storage" in f]
    rest = [j for j in range(a.shape[1]) if j not in tan]
    np.testing.assert_array_equal(a[:, rest], b[:, rest])
    assert np.abs(a[:, tan] - b[:, tan]).max() > 0.01  # relaxing materials: they differ
    names = ("disp_at_1N_mm", "hysteresis_Nmm")
    data = SweepData(
        folder=tmp_path, space=space, solver_version=SOLVER_VERSION, points=pts,
        targets=rng.lognormal(size=(40, 2)), index=np.arange(40), metric_names=names,
        table_sha256="", n_rows=40, tapping_frequency_Hz=1.0,
    )  # fmt: skip
    config = dataclasses.replace(SHORT, max_epochs=2, patience=2)
    trained = fit(data, config, progress=False).surrogate
    assert trained.encoder.omega_rad_s == pytest.approx(2 * math.pi)
    loaded = load_checkpoint(save_checkpoint(trained, tmp_path / "m.safetensors"))
    assert loaded.encoder.omega_rad_s == pytest.approx(2 * math.pi)
    assert loaded.header["material_descriptors"]["omega_rad_s"] == pytest.approx(2 * math.pi)
    np.testing.assert_array_equal(loaded.encoder.encode(pts).features, b)


def test_log_loss_tangents_are_extra_features_that_survive_a_round_trip(tmp_path):
    """``log_tangents``: each layer's three loss tangents once more as log10, scaled so that
    tan d = 1e-5 (and below: an elastic layer) gives 0 and tan d = 1 gives 1; the other
    features are unchanged; training records it, a checkpoint round trip keeps it, and a
    checkpoint written before it existed (no ``log_tangents`` entry) encodes without it."""
    import dataclasses

    from surrogate._io import SweepData

    space = load_space()
    rng = np.random.default_rng(1)
    pts = [space.point(rng.random(len(space.sampled))) for _ in range(40)]
    plain, logged = Encoder(space), Encoder(space, log_tangents=True)
    a, b = plain.encode(pts).features, logged.encode(pts).features
    assert logged.n_features == plain.n_features + 3 * len(plain.material_roles)
    names = logged.feature_names
    for j, name in enumerate(plain.feature_names):  # the old features, unchanged
        np.testing.assert_array_equal(b[:, names.index(name)], a[:, j])
    for role in plain.material_roles:
        for r in ("0.333", "1", "3"):
            tan = b[:, names.index(f"{role}:tan_delta@{r}w")].astype(np.float64)
            log = b[:, names.index(f"{role}:log10_tan_delta@{r}w")].astype(np.float64)
            expect = (np.log10(np.maximum(tan, 1e-5)) + 5.0) / 5.0
            on = tan > 0  # inactive and elastic layers: 0 in both
            assert on.sum() > 10
            np.testing.assert_allclose(log[on], expect[on], atol=1e-6)
            assert np.all(log[~on] == 0.0)
    data = SweepData(
        folder=tmp_path, space=space, solver_version=SOLVER_VERSION, points=pts,
        targets=rng.lognormal(size=(40, 2)), index=np.arange(40),
        metric_names=("disp_at_1N_mm", "hysteresis_Nmm"), table_sha256="", n_rows=40,
    )  # fmt: skip
    config = dataclasses.replace(SHORT, max_epochs=2, patience=2, log_tangents=True)
    trained = fit(data, config, progress=False).surrogate
    assert trained.encoder.log_tangents and trained.model.n_inputs == logged.n_features
    loaded = load_checkpoint(save_checkpoint(trained, tmp_path / "m.safetensors"))
    assert loaded.encoder.log_tangents
    np.testing.assert_array_equal(loaded.encoder.encode(pts).features, b)
    old = dict(loaded.encoder.to_dict())
    del old["log_tangents"]
    assert not Encoder.from_dict(space, old).log_tangents


def test_predict_reads_the_design_file_of_simulate(tmp_path, capsys):
    """``fingertip predict`` takes the design TOML ``fingertip simulate`` takes: the same
    prediction as the design's point; outside the space, one line naming the parameter and its
    bounds; a material of no family of the space, one line naming the layer."""
    import math

    from sim.design import point_to_design

    ckpt = REPO / "surrogate" / "pretrained" / "default" / "model.safetensors"
    model = load_checkpoint(ckpt, allow_solver_mismatch=True)
    space = model.space
    point = space.check(
        {"geometry.half_width_mm": 5.8, "geometry.height_mm": 6.3, "geometry.exponent": 1.6,
         "layers.count": 1, "core.material": "gel", "core.mu0_MPa": 0.02, "core.alpha": 2.1,
         "core.g_total": 0.5, "core.tau_s": 0.05}
    )  # fmt: skip
    mat = point_to_design(point, space.catalogue).layers[0].material.to_dict()
    text = "[geometry]\nhalf_width_mm = 5.8\nheight_mm = 6.3\nexponent = 1.6\n[[layers]]\n"
    text += "[layers.material]\n" + "".join(
        f"{k} = {json.dumps(v)}\n" for k, v in mat.items() if v is not None
    )
    design = tmp_path / "d.toml"
    design.write_text(text)
    from_file = read_points(design, space)[0]
    assert all(
        (isinstance(v, float) and math.isnan(v) and math.isnan(from_file[k]))
        or from_file[k] == pytest.approx(v)
        for k, v in point.items()
    )
    p0, p1 = model.predict([point]), model.predict([from_file])
    np.testing.assert_allclose(p0.median, p1.median, rtol=1e-6)
    soft = tmp_path / "soft.toml"
    soft.write_text(text.replace("mu_MPa = [0.02]", "mu_MPa = [0.001]"))
    for path, field in ((soft, "core.mu0_MPa"), (None, "layers[0].material")):
        if path is None:
            path = tmp_path / "compressible.toml"
            path.write_text(text.replace("nu = 0.499", "nu = 0.45"))
        code = explore.cli.main(["predict", str(ckpt), str(path)])
        err = capsys.readouterr().err
        assert code == 2 and err.count("\n") == 1 and field in err, err
        assert field != "core.mu0_MPa" or "0.0025" in err  # the bound it breaks


def test_a_warm_start_keeps_the_grouping_of_its_checkpoint(data):
    """A checkpoint trained with the grouping of before ("tapping": the tapping's trust outputs
    in its metrics' net) is warm-started in that grouping whatever the config's default says,
    and starts from exactly its weights."""
    from surrogate._train import Split, TrainConfig, split_indices

    split = split_indices(len(data.points), 0)
    old = fit(data, TrainConfig(members=2, max_epochs=2, groups="tapping"), progress=False)
    assert old.surrogate.model.groups == metric_groups(data.metric_names, "tapping")
    assert old.surrogate.model.groups != metric_groups(data.metric_names, "tapping_metrics")
    config = TrainConfig(members=2, max_epochs=1, patience=1, lr=0.0)
    new = fit(data, config, progress=False, split=Split(split.train, split.val, split.test),
              init=old.surrogate)  # fmt: skip
    assert new.surrogate.model.groups == old.surrogate.model.groups
    x = old.surrogate.encoder.encode(data.points).features
    a = old.surrogate.predict_features(x)["mean"]
    np.testing.assert_allclose(new.surrogate.predict_features(x)["mean"], a, rtol=1e-6)


@pytest.mark.parametrize("before", [False, True])
def test_a_warm_start_keeps_the_descriptors_of_its_checkpoint(data, before):
    """A checkpoint trained with or without the log loss tangents is warm-started with its own
    descriptors whatever the config says, and starts from exactly its weights."""
    from surrogate._train import Split, TrainConfig, split_indices

    split = split_indices(len(data.points), 0)
    old = fit(data, TrainConfig(members=2, max_epochs=2, log_tangents=before), progress=False)
    config = TrainConfig(members=2, max_epochs=1, patience=1, lr=0.0, log_tangents=not before)
    new = fit(data, config, progress=False, split=Split(split.train, split.val, split.test),
              init=old.surrogate)  # fmt: skip
    assert new.surrogate.encoder.log_tangents is before
    assert new.surrogate.header["training"]["log_tangents"] is before
    x = old.surrogate.encoder.encode(data.points).features
    a = old.surrogate.predict_features(x)["mean"]
    np.testing.assert_allclose(new.surrogate.predict_features(x)["mean"], a, rtol=1e-6)


def test_censored_entries_are_tobit_terms():
    """A bound's entry of the NLL is -log P(value beyond the bound) under the member's
    Gaussian (scipy's normal survival function), an exact entry the Gaussian NLL; a lower
    bound pulls the mean up past it, never down to it."""
    from scipy.stats import norm

    from surrogate._model import gaussian_nll

    mean = torch.tensor([[[0.3, -0.2, 1.0]]], dtype=torch.float64, requires_grad=True)
    logvar = torch.tensor([[[0.2, -0.4, 0.0]]], dtype=torch.float64)
    y = torch.tensor([[0.5, 0.1, 1.0]], dtype=torch.float64)
    mask = torch.ones(1, 3, dtype=torch.float64)
    censor = torch.tensor([[1.0, -1.0, 0.0]], dtype=torch.float64)
    got = gaussian_nll(mean, logvar, y, mask, censor=censor)
    sd = np.exp(0.5 * logvar.detach().numpy()[0, 0])
    m = mean.detach().numpy()[0, 0]
    want = (
        -norm.logsf(0.5, m[0], sd[0])  # P(value > 0.5)
        - norm.logcdf(0.1, m[1], sd[1])  # P(value < 0.1)
        + 0.5 * 0.0  # the exact entry: 0.5 (logvar + 0) = 0
    ) / 3
    assert float(got.detach()[0]) == pytest.approx(want, rel=1e-12)
    got.sum().backward()
    assert mean.grad[0, 0, 0] < 0 and mean.grad[0, 0, 1] > 0  # up past 0.5, down below 0.1
    plain = gaussian_nll(mean.detach(), logvar, y, mask)
    assert float(plain[0]) != pytest.approx(float(got.detach()[0]))


def test_a_stopped_protocols_trust_figures_are_bounds():
    from sim.protocols import trust_censoring, trust_values

    row = {
        "status": "ok",
        "stopped": "tapping",
        "tapping_max_compressive_log_strain": "0.61",
        "tapping_min_J": "0.9",
        "plate_max_compressive_log_strain": "0.3",
        "tapping_reached_base": "False",
        "plate_reached_base": "False",
        "tapping_folded": "False",
    }
    c = trust_censoring(row)
    assert c["tapping_max_compressive_log_strain"] == 1 and c["tapping_min_J"] == -1
    assert c["plate_max_compressive_log_strain"] == 0
    v = trust_values(row)
    assert np.isnan(v["reached_base"]) and np.isnan(v["folded"]) and np.isnan(v["failed"])
    assert v["tapping_max_compressive_log_strain"] == 0.61
    whole = trust_values({**row, "stopped": ""})
    assert whole["reached_base"] == 0.0 and whole["failed"] == 0.0
    assert trust_censoring({**row, "stopped": ""}) == dict.fromkeys(c, 0)


def test_a_3d_sweep_is_refused_for_training(sweep, tmp_path):
    """The search confirms its answers with the 2D FE: a sweep of the 3D model (its
    config.json says so) is one clear error, not a surrogate of the wrong fidelity."""
    import json
    import shutil

    copy = tmp_path / "pad"
    shutil.copytree(sweep, copy)
    config = json.loads((copy / "config.json").read_text())
    config["options"]["model"] = {"dimension": "3d"}
    (copy / "config.json").write_text(json.dumps(config))
    with pytest.raises(DesignError, match="sweep of the 3d model"):
        read_sweep(copy)


def test_recorded_paths_are_relative_inside_the_repository(tmp_path) -> None:
    """A path inside the repository is recorded relative to it (the same on every checkout:
    a checkpoint trained on ``runs/sweep`` names it so wherever the clone is), any other
    absolute, and the low fidelity's recorded path leads back to its file."""
    from sim.provenance import REPO, recorded_path
    from surrogate._multifidelity_checkpoint import low_fidelity_path

    shipped = REPO / "surrogate" / "pretrained" / "default" / "model.safetensors"
    assert recorded_path(shipped) == "surrogate/pretrained/default/model.safetensors"
    assert recorded_path(REPO / "runs" / ".." / "runs" / "sweep") == "runs/sweep"
    assert recorded_path(tmp_path / "sweep") == str((tmp_path / "sweep").resolve())
    assert low_fidelity_path(recorded_path(shipped)) == shipped
