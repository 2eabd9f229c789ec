"""Shared fixtures. Heavy fixtures are rendered virtual captures, made once per session."""

import os

os.environ.setdefault("NUMBA_THREADING_LAYER", "omp")

import cv2  # noqa: E402,F401  (cv2 before pycolmap: see DESIGN.md)
import numpy as np  # noqa: E402
import pytest  # noqa: E402


@pytest.fixture
def rng():
    return np.random.default_rng(12345)
