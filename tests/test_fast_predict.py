"""The fast prediction path (issue 15, item 5) gives what the plain per-design path gives: each
design encoded alone, each member's nets evaluated one by one (``forward_member``), the
members mixed and mapped to metric units. To float32 round-off; on this machine bit for bit."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import torch

from sim.space import load_space
from sim.sweep import sample_points
from surrogate import load_checkpoint, read_points
from surrogate._encoding import Encoder, _per_value
from surrogate._model import EnsembleMLP, FrozenEnsemble, mixture
from surrogate._normalise import OutputNormaliser
from surrogate._surrogate import PHYSICAL, Surrogate, rule_mask

SHIPPED = Path(__file__).resolve().parents[1] / "surrogate" / "pretrained" / "default"


@pytest.fixture(scope="module")
def model() -> Surrogate:
    return load_checkpoint(SHIPPED / "model.safetensors", allow_solver_mismatch=True)


@pytest.fixture(scope="module")
def points(model: Surrogate) -> list[dict]:
    """Designs of the shipped table (catalogue and family materials, one to three layers) and
    fresh samples of its space (some outside the training domain)."""
    table = read_points(SHIPPED / "table.csv", model.space)
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
    # in metric units: the same map of the same mixture (exactly 0 where known by rule)
    pred = model.predict(points)
    ref = model.normaliser.to_physical(mean_z, std_z)
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
