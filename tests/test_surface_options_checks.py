"""``SurfaceOptions`` refuses a bad conditioning or segmentation option when it is made, in
one line naming the option, instead of when a surface is built from it (``detrend="yes"``
was taken as true)."""

import numpy as np
import pytest

from twoscale.surface import SurfaceError, SurfaceOptions


@pytest.mark.parametrize(
    "given, named",
    [
        ({"detrend": "yes"}, "surface.detrend"),
        ({"invert": 1}, "surface.invert"),
        ({"fill": "linear"}, "surface.fill"),
        ({"units": "inch"}, "surface.units"),
        ({"spacing": 0.0}, "surface.spacing"),
        ({"spacing": True}, "surface.spacing"),
        ({"min_distance": -0.5}, "surface.min_distance"),
        ({"prominence": float("nan")}, "surface.prominence"),
        ({"prominence": "0.1"}, "surface.prominence"),
    ],
)
def test_a_bad_option_is_refused_when_made(given, named):
    with pytest.raises(SurfaceError) as err:
        SurfaceOptions(**given)
    assert str(err.value).startswith(named) and "\n" not in str(err.value)


def test_good_options_and_numpy_scalars_are_taken():
    opts = SurfaceOptions(spacing=np.float64(0.1), units="um", detrend=np.True_, min_distance=np.int64(0), prominence=0)
    assert opts.spacing == 0.1 and opts.detrend and opts.min_distance == 0
