"""Shared fixtures. Heavy fixtures are rendered virtual captures, made once per session."""

import os

os.environ.setdefault("NUMBA_THREADING_LAYER", "omp")

import cv2  # noqa: E402,F401  (cv2 before pycolmap: see DESIGN.md)
import numpy as np  # noqa: E402
import pytest  # noqa: E402
from hypothesis import settings  # noqa: E402

# Property tests draw the same examples on every run, so CI is reproducible (the
# same seed gives the same result); HYPOTHESIS_PROFILE=explore searches afresh.
settings.register_profile("ci", derandomize=True, database=None)
settings.register_profile("explore")
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "ci"))


@pytest.fixture
def rng():
    return np.random.default_rng(12345)
