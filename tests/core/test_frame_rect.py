"""A frame's scene x, y and its scene check on a rectangle (a root grid's extent, issue 45)
are the square's, cut to the rectangle."""

import numpy as np
import pytest
from pyproj import CRS

from geoterrain.core.frame import Frame
from geoterrain.exceptions import InputError

pytestmark = pytest.mark.fast  # the whole file is in the fast tier

FRAMES = {
    "pixel": lambda: Frame.pixel(20, 40, 3.0),
    "projected": lambda: Frame.from_raster((30.0, 0.0, 500000.0, 0.0, -30.0, 4.1e6),
                                           CRS.from_epsg(32633).to_wkt(), 20, 40),
    "geographic": lambda: Frame.from_raster((0.05, 0.0, -110.0, 0.0, -0.05, 45.0),
                                            CRS.from_epsg(4326).to_wkt(), 20, 40),
}


@pytest.mark.parametrize("kind", sorted(FRAMES))
@pytest.mark.parametrize("shape", [(17, 33), (33, 17), (9, 9)])
def test_grid_xy_of_a_rectangle_is_the_square_s_cut_to_it(kind, shape):
    f = FRAMES[kind]()
    X, Y = f.grid_xy(shape)
    SX, SY = f.grid_xy(max(shape))
    assert X.shape == Y.shape == shape
    np.testing.assert_array_equal(X, SX[:shape[0], :shape[1]])
    np.testing.assert_array_equal(Y, SY[:shape[0], :shape[1]])


def test_check_scene_reads_the_rectangle_s_far_corner():
    f = Frame.pixel(3, 3, 2e7)  # the origin at the centre sample; 7 samples off: 1.4e8 m
    f.check_scene((2, 3), 0.0, 1.0)
    with pytest.raises(InputError, match="the scene would reach"):
        f.check_scene((2, 9), 0.0, 1.0)
    with pytest.raises(InputError, match="the scene would reach"):
        f.check_scene((9, 2), 0.0, 1.0)
