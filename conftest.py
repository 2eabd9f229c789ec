"""Loaded before anything is collected, the package doctests included (``make test`` runs
``--doctest-modules`` over the library): the process-wide settings of tests/conftest.py
that must precede the first import of our packages."""

import os

os.environ.setdefault("NUMBA_THREADING_LAYER", "omp")

import cv2  # noqa: E402,F401  (cv2 before pycolmap: see DESIGN.md)
