"""SR-UKF (van der Merwe & Wan 2001) equals the UKF on a NONLINEAR bearings-only run (SEEDS 1.5).

alpha = 1, beta = 0 and kappa <= -1 give a negative centre weight Wc0 (-1/3 for the toolbox's
kappa = 3 - n, -1 and -7 for kappa = -2, -3.5), so every predict and every update performs
a rank-1 Cholesky DOWNDATE of the QR factor; the test checks that those downdates really
ran (spy on cholupdate_each) and that none fell back to the full-covariance path.
Compared: posterior mean and covariance S S' after every step of the seed-000 turning run,
absolute tolerance 1e-10 (observed ~1e-14).
"""

import numpy as np
import pytest
import seed000 as S

import vtrack.estimation.sigma_filters as filters_mod


@pytest.mark.parametrize("kappa", [-1.0, -2.0, -3.5])
def test_srukf_equals_ukf_with_negative_centre_weight(kappa, monkeypatch):
    rng = np.random.default_rng(0)
    zs = S.bearings(S.turning_truth(rng), rng)
    opts = dict(alpha=1.0, beta=0.0, kappa=kappa)

    calls = {"down": 0, "up": 0}
    real = filters_mod.cholupdate_each

    def spy(L, v, sign=1.0):
        calls["down" if sign < 0 else "up"] += 1
        return real(L, v, sign)

    monkeypatch.setattr(filters_mod, "cholupdate_each", spy)
    x_ukf, P_ukf, _ = S.run("ukf", zs, **opts)
    x_sr, P_sr, sr = S.run("srukf", zs, **opts)

    assert sr.rule.Wc[0] < 0
    assert sr.fallbacks == 0
    # per step: one Wc0 downdate in predict, one in the update's S_y, m = 2 for the gain
    assert calls["down"] == 4 * len(zs)
    np.testing.assert_allclose(x_sr, x_ukf, rtol=0, atol=1e-10)
    np.testing.assert_allclose(P_sr, P_ukf, rtol=0, atol=1e-10)
    # the factor is a proper lower Cholesky factor all along
    assert np.allclose(np.triu(sr.S, 1), 0.0) and np.all(np.diag(sr.S) > 0)
