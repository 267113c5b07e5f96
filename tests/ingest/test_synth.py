"""Tests for the synthetic DEM generators and the GeoTIFF writer."""

from __future__ import annotations

import numpy as np
import pytest
import rasterio

from geoterrain.ingest.synth import KINDS, generate, write_geotiff


def lag1_autocorrelation(h: np.ndarray) -> float:
    """Mean of the lag-1 autocorrelations along rows and along columns."""
    h = h.astype(np.float64) - h.mean()
    out = []
    for a, b in ((h[:, 1:], h[:, :-1]), (h[1:, :], h[:-1, :])):
        out.append((a * b).sum() / np.sqrt((a * a).sum() * (b * b).sum()))
    return float(np.mean(out))


@pytest.mark.fast
@pytest.mark.parametrize("kind", KINDS)
def test_deterministic_per_seed(kind: str) -> None:
    a = generate(kind, 65, seed=7)
    b = generate(kind, 65, seed=7)
    np.testing.assert_array_equal(a, b)


@pytest.mark.fast
@pytest.mark.parametrize("kind", KINDS)
def test_different_seeds_differ(kind: str) -> None:
    a = generate(kind, 65, seed=1)
    b = generate(kind, 65, seed=2)
    assert not np.array_equal(a, b)
    assert np.abs(a - b).mean() > 1.0


@pytest.mark.fast
@pytest.mark.parametrize("kind", KINDS)
@pytest.mark.parametrize("size", [(2, 3), (3, 2), 1, (1, 7), 2, 17, (33, 70), (70, 33), 100])
def test_shapes_dtype_finite(kind: str, size: int | tuple[int, int]) -> None:
    h = generate(kind, size, seed=3)
    shape = (size, size) if isinstance(size, int) else size
    assert h.shape == shape
    assert h.dtype == np.float32
    assert np.isfinite(h).all()


@pytest.mark.fast
@pytest.mark.parametrize("kind", KINDS)
def test_relief_and_base(kind: str) -> None:
    h = generate(kind, (40, 57), seed=4, relief=1234.0, base=100.0)
    assert h.min() == pytest.approx(100.0, abs=1e-3)
    assert h.max() == pytest.approx(1334.0, abs=1e-2)
    default = generate(kind, 57, seed=4)
    assert 0.0 <= default.min() and default.max() == pytest.approx(2000.0, abs=1e-2)


@pytest.mark.fast
@pytest.mark.parametrize("kind", KINDS)
@pytest.mark.parametrize("seed", [0, 11])
def test_has_relief_and_is_not_white_noise(kind: str, seed: int) -> None:
    h = generate(kind, (129, 97), seed=seed)
    assert float(h.std()) > 100.0  # metres: real relief, not a flat plate
    assert lag1_autocorrelation(h) > 0.5
    # White noise of the same values has no spatial correlation at all.
    shuffled = np.random.default_rng(0).permutation(h.ravel()).reshape(h.shape)
    assert abs(lag1_autocorrelation(shuffled)) < 0.1


@pytest.mark.fast
def test_kind_parameters_change_the_surface() -> None:
    rough = generate("fbm", 129, seed=5, H=0.2)
    smooth = generate("fbm", 129, seed=5, H=1.0)
    assert lag1_autocorrelation(smooth) > lag1_autocorrelation(rough)
    ds_smooth = generate("diamond-square", 129, seed=5, roughness=1.5)
    ds_rough = generate("diamond-square", 129, seed=5, roughness=0.5)
    assert lag1_autocorrelation(ds_smooth) > lag1_autocorrelation(ds_rough)
    a = generate("fbm", 65, seed=5, octaves=2.5)
    b = generate("fbm", 65, seed=5, octaves=3)
    assert not np.array_equal(a, b)
    for profile in ("step", "sine", "cosine"):
        f = generate("fault", 65, seed=5, faults=50, profile=profile)
        assert np.isfinite(f).all() and f.max() > 0
    r = generate("ridged", 65, seed=5, gain=1.0, offset=0.9)
    assert np.isfinite(r).all()


@pytest.mark.fast
def test_fault_count_is_capped() -> None:
    h = generate("fault", 33, seed=0, faults=10**9)
    assert np.isfinite(h).all()


@pytest.mark.fast
def test_unknown_kind_and_parameter() -> None:
    with pytest.raises(ValueError, match="unknown kind"):
        generate("perlin-xyz", 17)
    with pytest.raises(TypeError, match="unknown parameter"):
        generate("fbm", 17, octave=3)
    with pytest.raises(ValueError):
        generate("fbm", 0)


@pytest.mark.fast
def test_geotiff_round_trip(tmp_path) -> None:
    h = generate("ridged", (70, 45), seed=9, relief=2500.0)
    path = write_geotiff(tmp_path / "dem.tif", h, crs="EPSG:32633",
                         origin=(500000.0, 5000000.0), spacing=10.0)
    assert path.exists()
    with rasterio.open(path) as src:
        assert src.crs.to_epsg() == 32633
        assert src.shape == (70, 45)
        assert src.count == 1
        assert src.dtypes[0] == "float32"
        t = src.transform
        assert (t.a, t.b, t.c, t.d, t.e, t.f) == (10.0, 0.0, 500000.0, 0.0, -10.0, 5000000.0)
        assert src.profile["tiled"]
        assert src.compression is not None and src.compression.value.lower() == "deflate"
        assert src.nodata is None
        np.testing.assert_array_equal(src.read(1), h)


@pytest.mark.fast
def test_geotiff_nodata_and_anisotropic_spacing(tmp_path) -> None:
    h = generate("fbm", 20, seed=1)
    h[0, 0] = -9999.0
    path = write_geotiff(str(tmp_path / "nd.tif"), h, crs="EPSG:4326",
                         origin=(10.0, 45.0), spacing=(0.001, 0.002), nodata=-9999.0)
    with rasterio.open(path) as src:
        assert src.crs.to_epsg() == 4326
        assert src.nodata == -9999.0
        assert src.transform.a == pytest.approx(0.001)
        assert src.transform.e == pytest.approx(-0.002)
        assert src.read(1, masked=True).mask[0, 0]
        np.testing.assert_array_equal(src.read(1), h)


@pytest.mark.slow
def test_large_fbm_is_finite() -> None:
    h = generate("fbm", 8193, seed=0)
    assert h.shape == (8193, 8193) and np.isfinite(h).all()
