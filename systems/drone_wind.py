# uio-jax: models
"""The 3D vehicle in wind (seed 002) under the entry names of the public API's examples.

``systems/drone_wind.py:with_wind`` (unknown wind) and ``:no_wind`` are part of the public
contract; the model itself lives in ``vehicle_wind.py`` (where ``with_wind`` treats the
wind as a *known* input and ``wind_unknown`` is the paper's case).
"""

import importlib.util
import os

_path = os.path.join(os.path.dirname(os.path.abspath(__file__)), "vehicle_wind.py")
_spec = importlib.util.spec_from_file_location("_uio_zoo_vehicle_wind", _path)
_zoo = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(_zoo)


def no_wind():
    """No disturbance (002 section III-B)."""
    return _zoo.no_wind()


def with_wind():
    """Wind of unknown, time-varying magnitude along z (002 section III-C)."""
    return _zoo.wind_unknown()


def known_wind():
    """Wind along z treated as a known input."""
    return _zoo.with_wind()
