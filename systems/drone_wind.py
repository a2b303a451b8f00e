# uio-jax: models
"""The 3D vehicle in wind (seed 002) under the entry names of the public API's examples.

``systems/drone_wind.py:wind_unknown`` (the paper's case: wind of unknown magnitude, 002
section III-C), ``:wind_known`` and ``:no_wind`` are the entries of the public API's
examples; the model itself lives in ``vehicle_wind.py``, under the same names.
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


def wind_unknown():
    """Wind of unknown, time-varying magnitude along z (002 section III-C): the seed
    paper's drone in wind (this entry was ``with_wind`` before)."""
    return _zoo.wind_unknown()


def wind_known():
    """Wind along z treated as a known input (an ORC sanity case)."""
    return _zoo.wind_known()
