# uio-jax: models
"""The unicycle pushed by a disturbance (seed 003) under the entry names of the public API's examples.

``systems/unicycle_wind.py:range_gamma_unknown`` and friends are part of the public
contract; the models themselves live in ``unicycle_disturbance.py``.
"""

import importlib.util
import os

_path = os.path.join(os.path.dirname(os.path.abspath(__file__)), "unicycle_disturbance.py")
_spec = importlib.util.spec_from_file_location("_uio_zoo_unicycle_disturbance", _path)
_zoo = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(_zoo)


def _alias(target, doc):
    def entry():
        return getattr(_zoo, target)()

    entry.__doc__ = doc
    return entry


range_gamma_known = _alias("gamma_known_range", "y = r^2, disturbance along a known gamma.")
range_gamma_unknown = _alias("gamma_unknown_range", "y = r^2, disturbance along an unknown gamma.")
bearing_gamma_known = _alias("gamma_known_bearing", "y = tan beta, known gamma.")
bearing_gamma_unknown = _alias("gamma_unknown_bearing", "y = tan beta, unknown gamma.")
phi_gamma_known = _alias("gamma_known_phi", "y = tan phi, known gamma.")
phi_gamma_unknown = _alias("gamma_unknown_phi", "y = tan phi, unknown gamma.")
range_no_disturbance = _alias("no_disturbance_range", "y = r^2, no disturbance.")
