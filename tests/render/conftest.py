import numpy as np
import pytest

from .worlds import make_world


@pytest.fixture
def street_world():
    specs = [
        (1, 0.0, -2.0, 0.0, 4.5, 1.8, 1.5),
        (7, 8.0, 2.0, np.pi, 4.2, 1.8, 1.45),
        (300, -10.0, -2.0, 0.3, 9.0, 2.5, 3.2),
        (70000, 15.0, -2.0, 0.0, 4.5, 1.8, 1.5),
    ]
    return make_world(specs)
