"""The ``lights`` fixture: every light set of :mod:`tests.photometric.errors._lights`."""

from __future__ import annotations

import pytest

from tests.photometric.errors._lights import CONFIGS


@pytest.fixture(params=sorted(CONFIGS))
def lights(request):
    return CONFIGS[request.param]
