"""``python -m uio_jax``: the same as the ``uio-jax`` command."""

import sys

from .cli import main

sys.exit(main())
