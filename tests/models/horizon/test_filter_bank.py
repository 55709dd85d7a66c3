"""Filter-bank profile normalisation: degrees below the threshold, divided by the maximum above, zero mean."""

import math

import numpy as np
import torch

from models.horizon.filter_bank import profile_normalize


def test_profile_normalize_rule():
    far = torch.full((1, 8), math.tan(math.radians(-0.04)))
    far[0, 3] = math.tan(math.radians(0.5))  # below the 1-degree threshold: kept in degrees
    near = far.clone()
    near[0, 3] = math.tan(math.radians(4.0))  # above: divided by the maximum
    out_far, out_near = profile_normalize(far, 1.0), profile_normalize(near, 1.0)
    deg_far = np.degrees(np.arctan(far.numpy()))
    np.testing.assert_allclose(out_far.numpy(), deg_far - deg_far.mean(), rtol=1e-5)
    deg_near = np.degrees(np.arctan(near.numpy())) / 4.0
    np.testing.assert_allclose(out_near.numpy(), deg_near - deg_near.mean(), rtol=1e-5)
