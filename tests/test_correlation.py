"""The FFT correlations of the plan searches (``path_search.corr_size``): half the padding a
whole image would need, the same scores and the same peaks."""

import jax.numpy as jnp
import numpy as np
import pytest

from mfcl_jax.frontend import path_search as ps


def _circular(field, img, shape):
    """``sc[s] = sum_u img[u] field[u + s]``, circular of ``shape``."""
    spec = np.fft.rfft2(field, shape) * np.conj(np.fft.rfft2(img, shape))
    return np.fft.irfft2(spec, shape)


def _linear(field, img, s):
    """The same, linear, the field zero outside its cells, at shift ``s = (sy, sx)``."""
    h, w = field.shape
    n = img.shape[0]
    pad = np.zeros((h + 2 * n, w + 2 * n))
    pad[n : n + h, n : n + w] = field
    return float(np.sum(img * pad[n + s[0] : 2 * n + s[0], n + s[1] : 2 * n + s[1]]))


# the last: a plan side under half the image (12 < 16), so the length (30) crops the image
@pytest.mark.parametrize("side,n", [((23, 37), 16), ((40, 17), 9), ((12, 50), 32)])
def test_the_correlation_size_holds_every_shift_that_puts_the_image_centre_on_the_plan(side, n):
    rng = np.random.default_rng(3)
    field, img = rng.random(side), rng.random((n, n))
    c = n // 2
    shapes = {"corr_size": (ps.corr_size(side[0], n), ps.corr_size(side[1], n)),
              "one short": (side[0] + c - 1, side[1] + c - 1)}  # fmt: skip
    for name, shape in shapes.items():
        sc = _circular(field, img, shape)
        err = max(abs(sc[sy % shape[0], sx % shape[1]] - _linear(field, img, (sy, sx)))
                  for sy in range(-c, side[0] - c) for sx in range(-c, side[1] - c))  # fmt: skip
        if name == "corr_size":
            assert err < 1e-9
            assert shape[0] < side[0] + n and shape[1] <= side[1] + n  # less than a whole image
            assert side != (12, 50) or shape[0] < n
        else:
            assert err > 1e-3  # a cell less and a shift wraps onto the field: the bound is tight


def _cloud(rng, m=300, half=9.0):
    pts = rng.uniform(-half, half, (m, 2)).astype(np.float32)
    return jnp.asarray(pts), jnp.ones(m, bool)


def test_the_path_search_finds_the_same_peaks_as_with_a_whole_image_of_padding(monkeypatch):
    """``path_search._coarse`` at ``corr_size`` against the padding it had before (``side +
    n_img``): the same placements, scores equal to float32 rounding."""
    from mfcl_jax.sim.synthetic import row_of_rooms

    fp = row_of_rooms([6.0, 9.0, 7.5])
    fields = ps.plan_fields(fp.rasterize())
    rng = np.random.default_rng(0)
    pts, pok = _cloud(rng)
    frees, fok = _cloud(rng, 600)
    p, n_img = ps.SearchParams(), 64
    new = ps._coarse(pts, pok, frees, fok, fields, p, n_img)
    monkeypatch.setattr(ps, "corr_size", lambda side, n: ps.fft_size(side + n))
    old = ps._coarse(pts, pok, frees, fok, fields, p, n_img)
    ok = np.isfinite(np.asarray(old[1]))
    assert ok.sum() > 10
    np.testing.assert_array_equal(np.isfinite(np.asarray(new[1])), ok)
    np.testing.assert_allclose(np.asarray(new[0])[ok], np.asarray(old[0])[ok], atol=1e-4)
    np.testing.assert_allclose(np.asarray(new[1])[ok], np.asarray(old[1])[ok], rtol=1e-4,
                               atol=1e-5)  # fmt: skip
