"""The fast prediction path (issue 15, item 5) gives what the plain per-design path gives: each
design encoded alone, each member's nets evaluated one by one (``forward_member``), the
members mixed and mapped to metric units. To float32 round-off (the features and the mixture's
mean bit for bit on this machine), and the same bits for a design whatever batch it is in."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
import torch

from sim.design import load_space
from sim.sweep import sample_points
from surrogate import _surrogate, load_checkpoint, read_points
from surrogate._encoding import Encoder, _per_value
from surrogate._model import (
    LOGVAR_MAX,
    LOGVAR_MIN,
    EnsembleMLP,
    FrozenEnsemble,
    bounded_logvar,
    member_variance,
    mixture,
)
from surrogate._normalise import Z90, OutputNormaliser
from surrogate._surrogate import PHYSICAL, Surrogate, clip_probabilities, rule_mask

SHIPPED = Path(__file__).resolve().parents[1] / "surrogate" / "pretrained" / "default"


@pytest.fixture(scope="module")
def model() -> Surrogate:
    return load_checkpoint(SHIPPED / "model.safetensors", allow_solver_mismatch=True)


@pytest.fixture(scope="module")
def points(model: Surrogate) -> list[dict]:
    """Designs of the shipped table (catalogue and family materials, one to three layers) and
    fresh samples of its space (some outside the training domain)."""
    table = read_points(SHIPPED / "table.csv.gz", model.space)
    return table[::7] + sample_points(model.space, 24, 5)


def _per_design(model: Surrogate, point: dict) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The plain path for one design: its features, and the mixture's mean and std (z)."""
    features = model.encoder.encode([point]).features
    x = torch.from_numpy(features)
    with torch.no_grad():
        members = [model.model.forward_member(x, k) for k in range(model.members)]
        mu, sd = mixture(*(torch.stack(t) for t in zip(*members, strict=True)))
    return features[0], mu[0].double().numpy(), sd[0].double().numpy()


def test_the_fast_path_equals_the_per_design_path(model, points):
    batch = model.encoder.encode(points).features
    mean_z, std_z = model.predict_normalised(batch)
    for i, point in enumerate(points):
        features, mu, sd = _per_design(model, point)
        np.testing.assert_array_equal(batch[i], features)
        np.testing.assert_allclose(mean_z[i], mu, rtol=1e-5, atol=1e-5)
        np.testing.assert_allclose(std_z[i], sd, rtol=1e-5, atol=1e-6)
    # in metric units: the same map of the same mixture (exactly 0 where known by rule, a
    # probability within [0, 1])
    pred = model.predict(points)
    ref = model.normaliser.to_physical(mean_z, std_z)
    clip_probabilities(ref, model.metric_names)
    rule = rule_mask(model.encoder, batch, model.metric_names)
    for key in PHYSICAL:
        ref[key][rule] = 0.0
        np.testing.assert_array_equal(getattr(pred, key), ref[key])
    np.testing.assert_array_equal(pred.by_rule, rule)


def test_the_fast_path_equals_the_batched_autograd_model(model, points):
    """As ``mixture(*model(x))``, the path before the fast one (bit for bit on this machine)."""
    batch = model.encoder.encode(points).features
    mean_z, std_z = model.predict_normalised(batch)
    with torch.no_grad():
        ref_mean, ref_std = mixture(*model.model(torch.from_numpy(batch)))
    np.testing.assert_allclose(mean_z, ref_mean.numpy(), rtol=1e-6, atol=1e-6)
    np.testing.assert_allclose(std_z, ref_std.numpy(), rtol=1e-6, atol=1e-7)


@pytest.mark.parametrize(
    ("hidden", "groups"),
    [((96, 96), "split"), ((32,), "ordered"), ((), "one"), ((16, 16, 16), "split")],
)
def test_frozen_ensemble_equals_the_model_for_any_layout(hidden, groups):
    n_out = 7
    layout = {
        "split": [0, 1, 1, 0, 2, 1, 0],  # interleaved groups: put back in order
        "ordered": [0, 0, 0, 1, 1, 1, 1],
        "one": None,
    }[groups]
    net = EnsembleMLP(11, n_out, members=3, hidden=hidden, groups=layout, seed=1).eval()
    x = torch.rand(300, 11, generator=torch.Generator().manual_seed(2))
    with torch.inference_mode():
        fast = FrozenEnsemble(net)(x)
    with torch.no_grad():
        ref = mixture(*net(x))
    for a, b in zip(fast, ref, strict=True):
        torch.testing.assert_close(a, b, rtol=1e-5, atol=1e-6)


def test_the_frozen_weights_follow_the_models(model):
    """A surrogate whose weights change (e.g. copied in after training) predicts with the new
    ones, not a stale snapshot."""
    space = load_space()
    enc = Encoder(space)
    names = list(model.metric_names)
    norm = OutputNormaliser.fit(np.random.default_rng(0).lognormal(size=(40, len(names))))
    net = EnsembleMLP(enc.n_features, len(names), members=2, seed=0)
    sur = Surrogate(net, enc, norm, names)
    x = enc.encode(sample_points(space, 8, 0)).features
    before = sur.predict_normalised(x)[0]
    with torch.no_grad():
        net.biases[-1].add_(1.0)
    after = sur.predict_normalised(x)[0]
    assert not np.allclose(before, after)
    with torch.no_grad():
        expected = mixture(*net(torch.from_numpy(x)))[0].numpy()
    np.testing.assert_allclose(after, expected, rtol=1e-5, atol=1e-6)


def test_a_rule_per_distinct_value_tells_1_true_and_1_0_apart():
    values = [1, True, 1.0, "1", None, float("nan"), 1, True]
    assert _per_value(repr, values) == [repr(v) for v in values]
    assert _per_value(repr, [[1], [1]]) == ["[1]", "[1]"]  # unhashable: one by one
    assert _per_value(len, ["ab", "c", "ab"], int).tolist() == [2, 1, 2]
    assert _per_value(len, [], int).shape == (0,)


def _reference_z(model: Surrogate, features: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The mixture's mean and std (z) the plain way, in float64: net by net, layer by layer."""
    net = model.model
    x = torch.from_numpy(features).double()
    w = [t.detach().double() for t in net.weights]
    b = [t.detach().double() for t in net.biases]
    means, logvars = [], []
    for k in range(net.members):
        mean = torch.empty(len(x), net.n_outputs, dtype=torch.float64)
        logvar = torch.empty_like(mean)
        for g in range(net.n_groups):
            s, cols = k * net.n_groups + g, [j for j, gj in enumerate(net.groups) if gj == g]
            h = x
            for i in range(len(w)):
                h = h @ w[i][s] + b[i][s, 0]
                if i < len(w) - 1:
                    h = torch.nn.functional.silu(h)
            mean[:, cols] = h[:, cols]
            logvar[:, cols] = bounded_logvar(h[:, net.n_outputs :])[:, cols]
        means.append(mean)
        logvars.append(logvar)
    mu, sd = mixture(torch.stack(means), torch.stack(logvars))
    return mu.numpy(), sd.numpy()


def test_the_fast_path_is_within_float32_round_off_of_a_float64_reference(model):
    """On random features (not only encoded designs): the mixture's mean and std within a few
    float32 rounding errors of the same network evaluated in float64 (largest seen: 7.6e-7
    absolute on the mean, 4.5e-6 relative on the std, as before the fast path)."""
    x = np.random.default_rng(3).random((700, model.encoder.n_features)).astype(np.float32)
    mean_z, std_z = model.predict_normalised(x)
    ref_mean, ref_std = _reference_z(model, x)
    np.testing.assert_allclose(mean_z, ref_mean, rtol=0, atol=4e-6)
    np.testing.assert_allclose(std_z, ref_std, rtol=2e-5, atol=0)


def test_a_designs_prediction_does_not_depend_on_its_batch(model, points, monkeypatch):
    """The same bits for a design alone, in a batch of any size, at any position, with any
    batch size of the path (the search compares predictions made in different batches)."""
    features = model.encoder.encode(points).features
    whole = model.predict_features(features)

    def same(out: dict, rows: np.ndarray) -> None:
        for key in (*PHYSICAL, "by_rule"):
            assert out[key].tobytes() == whole[key][rows].tobytes(), key

    for rows in ([5], [0, 1, 2], range(3, 40), range(len(points) - 1, 0, -3)):
        rows = np.asarray(rows)
        same(model.predict_features(features[rows]), rows)
    for batch in (32, 50, 96):
        monkeypatch.setattr(_surrogate, "BATCH", batch)
        same(model.predict_features(features), np.arange(len(points)))
    one = model.predict([points[7]])
    assert one.median.tobytes() == whole["median"][7:8].tobytes()


def test_member_variance_is_the_exp_of_the_bounded_log_variance():
    """The head's closed form: within float32 round-off of exp(bounded_logvar) (and closer to
    its float64 value than the composed float32 functions)."""
    raw = torch.linspace(-40.0, 40.0, 400_001)
    exact = torch.exp(bounded_logvar(raw.double()))
    fast = member_variance(raw)
    composed = torch.exp(bounded_logvar(raw))
    err_fast = ((fast.double() - exact) / exact).abs().max().item()
    err_composed = ((composed.double() - exact) / exact).abs().max().item()
    assert err_fast < 1e-6 and err_fast <= err_composed
    assert fast.min().item() == pytest.approx(math.exp(LOGVAR_MIN), rel=1e-6)
    assert fast.max().item() == pytest.approx(math.exp(LOGVAR_MAX), rel=1e-6)
    copy = raw.clone()
    assert member_variance(copy, inplace=True).data_ptr() == copy.data_ptr()
    assert torch.equal(copy, fast)


def test_to_physical_is_the_log_normal_map():
    """``to_physical`` (in place, torch's exp for the spread) against the formula written out
    in NumPy, to float64 round-off (torch's and numpy's vectorised exp may differ by an ulp
    or two, and by CPU); float32 input as float64."""
    rng = np.random.default_rng(4)
    y = rng.lognormal(size=(200, 5)) * [1, 1, 1, 1, -1]  # the last metric is linear
    y[0, 1] = 0.0  # nonnegative, reaches 0: a shifted log scale
    y[:, 2] = np.nan  # never observed: NaN predictions
    norm = OutputNormaliser.fit(y)
    assert norm.log.tolist() == [True, True, False, True, False] and norm.offset[1] > 0
    mean_z = rng.normal(size=(300, 5)).astype(np.float32)
    std_z = rng.uniform(0.01, 2.0, size=(300, 5)).astype(np.float32)
    m = norm.shift + norm.scale * mean_z.astype(np.float64)
    s = norm.scale * std_z.astype(np.float64)
    c = norm.offset
    with np.errstate(over="ignore", invalid="ignore"):
        ln_mean = np.exp(m + 0.5 * s * s)
        want = {
            "mean": np.where(norm.log, ln_mean - c, m),
            "median": np.where(norm.log, np.exp(m) - c, m),
            "std": np.where(norm.log, ln_mean * np.sqrt(np.expm1(s * s)), s),
            "lower_90": np.where(norm.log, np.exp(m - Z90 * s) - c, m - Z90 * s),
            "upper_90": np.where(norm.log, np.exp(m + Z90 * s) - c, m + Z90 * s),
        }
    for v in want.values():
        v[:, 2] = np.nan
    out = {key: np.full((300, 5), 7.0) for key in PHYSICAL}
    got = norm.to_physical(mean_z, std_z, out)
    assert all(got[key] is out[key] for key in PHYSICAL)
    for key in PHYSICAL:  # a few ulps: exp's error and the rounding of its argument's sum
        np.testing.assert_allclose(got[key], want[key], rtol=1e-13, atol=0, equal_nan=True)
    fresh = norm.to_physical(mean_z.astype(np.float64), std_z)
    for key in PHYSICAL:
        assert fresh[key].tobytes() == got[key].tobytes()


def test_a_table_a_list_and_mixed_types_encode_alike(model, points):
    """A table and a list of the points (in any order) give the same features, flags and
    reasons; a layer count given as 2, 2.0 or "2" is the same choice (and True is not)."""
    names = model.space.names
    table = {k: [p.get(k) for p in points] for k in names}
    batch = model.encoder.encode(points)
    for enc, order in (
        (model.encoder.encode(table), slice(None)),
        (model.encoder.encode(points[::-1]), slice(None, None, -1)),
    ):
        assert enc.features[order].tobytes() == batch.features.tobytes()
        assert np.array_equal(enc.in_domain[order], batch.in_domain)
        assert enc.reasons[order] == batch.reasons
    two = [p for p in points if p["layers.count"] == 2][:3]
    variants = [dict(two[0], **{"layers.count": v}) for v in (2, 2.0, "2", True)]
    enc = model.encoder.encode(variants + two)
    assert (enc.features[1:3] == enc.features[0]).all()
    assert (enc.in_domain[1:3] == enc.in_domain[0]).all()
    assert not enc.in_domain[3] and "layers.count" in enc.reasons[3]
    cols, n = model.encoder.columns(variants)
    assert n == 4 and cols["layers.count"] == ["2", "2", "2", "True"]
    assert isinstance(cols["skin.material"], list)
