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


_TIMING = ("time", "timing", "second", "elapsed", "cpu")


def _without_timings(obj, roots):
    """A report with its wall-clock figures dropped (they differ from run to run) and
    the two runs' output folders named alike."""
    if isinstance(obj, dict):
        return {k: _without_timings(v, roots) for k, v in obj.items()
                if not (any(w in k.lower() for w in _TIMING) or k.endswith("_s"))}
    if isinstance(obj, list):
        return [_without_timings(v, roots) for v in obj]
    if isinstance(obj, str):
        for r in roots:
            obj = obj.replace(r, "<out>")
    return obj


@pytest.fixture
def output_differences():
    """``f(a, b)``: the files of output folders ``a`` and ``b`` whose bytes differ (JSON
    reports compared without their timings), or whose set differs: ``[]`` when two runs
    with the same seed wrote the same outputs. The stage caches (``stages/``: each
    stage's result pickled with its own timings, and its signature) are left out: what
    they hold is compared in the outputs made from them."""
    import json
    from pathlib import Path

    def differ(a, b):
        a, b = Path(a), Path(b)
        fa, fb = ({p.relative_to(x) for p in x.rglob("*")
                   if p.is_file() and p.relative_to(x).parts[0] != "stages"} for x in (a, b))
        out = sorted(str(p) for p in fa ^ fb)
        roots = (str(a), str(b))
        for rel in sorted(fa & fb):
            x, y = (a / rel).read_bytes(), (b / rel).read_bytes()
            if rel.suffix == ".json" and x != y:
                try:
                    x, y = (_without_timings(json.loads(t), roots) for t in (x, y))
                except ValueError:
                    pass
            if x != y:
                out.append(str(rel))
        return out

    return differ
