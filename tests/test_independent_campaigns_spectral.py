"""Independent campaigns through the real workflow: the ``spectral`` generator (tests: tests/independent_campaigns.py).

One file per generator, so that ``make test`` (``--dist loadfile``) runs the two campaigns on different workers.
"""

import pytest
from independent_campaigns import *  # noqa: F403 (the tests and the module-scoped campaign fixtures)


@pytest.fixture(scope="module")
def generator() -> str:
    return "spectral"
