"""The LP polish's linearisation: finite-difference Jacobians against known linear maps."""

import numpy as np
import pytest
import torch

from controllers.lp_polish import PolishSettings, _constraint_matrix, jacobians, probes

H = 12


def _linear_rollout(jac: np.ndarray, offset: np.ndarray):
    """A model whose T_r is offset + jac @ u exactly, and u_phys = u (float64)."""

    def rollout(u_w: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        u = u_w.double().numpy()
        t = offset[None, :] + u @ jac.T
        return torch.from_numpy(t)[None], u_w.double()[None]

    return rollout


def _check(jac: np.ndarray, stride: int) -> None:
    rng = np.random.default_rng(0)
    offset = rng.normal(20.0, 1.0, H)
    u0 = torch.as_tensor(rng.uniform(0, 5000, H))
    u0[3] = 4990.0  # near the bound: probed downwards
    batch, step = probes(u0, 100.0, 5000.0, stride)
    assert batch.shape == (1 + len(range(0, H, stride)), H)
    assert float(batch.max()) <= 5000.0
    t_r, u_phys = _linear_rollout(jac, offset)(batch)
    t0, p0, jr, jp = jacobians(t_r, u_phys, step)
    np.testing.assert_allclose(t0[0], offset + jac @ u0.numpy(), rtol=1e-12)
    np.testing.assert_allclose(p0[0], u0.numpy())
    np.testing.assert_allclose(jr[0], jac, atol=1e-12)
    np.testing.assert_allclose(jp[0], np.eye(H), atol=1e-12)


def test_every_step_probed_recovers_any_causal_linear_map():
    jac = np.tril(np.random.default_rng(1).normal(size=(H, H))) * 1e-4
    _check(jac, stride=1)


@pytest.mark.parametrize("stride", [2, 4, 5])
def test_sparse_probes_recover_a_time_invariant_map_exactly(stride):
    # Impulse response of a stable 1st-order system: J[j, i] = g(j - i) for j >= i.
    g = 3e-4 * 0.8 ** np.arange(H)
    jac = np.array([[g[j - i] if j >= i else 0.0 for i in range(H)] for j in range(H)])
    _check(jac, stride=stride)


def test_polish_settings_are_checked():
    with pytest.raises(ValueError, match="probe_stride"):
        PolishSettings(probe_stride=0)
    with pytest.raises(ValueError, match="delta_frac"):
        PolishSettings(delta_frac=0.0)
    with pytest.raises(ValueError, match="line_search"):
        PolishSettings(line_search=(1.5,))


def test_constraint_matrix_is_the_block_matrix_with_only_its_nonzeros_stored():
    rng = np.random.default_rng(2)
    jr = np.tril(rng.normal(size=(3, H, H))).reshape(3 * H, H)
    jr[jr > 1.0] = 0.0  # zeros inside the triangle too
    a = _constraint_matrix(jr)
    eye = np.eye(3 * H)
    np.testing.assert_array_equal(a.toarray(), np.block([[-jr, -eye], [jr, -eye]]))
    assert a.nnz == 2 * (np.count_nonzero(jr) + 3 * H)
    assert a.has_canonical_format
