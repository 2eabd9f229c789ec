"""Up on a building whose largest plane is its wall (issue 32): a facade with windows and a
narrower strip of ground, at random rotations, from the mesh alone; the report names the
cue that decided and how close the runner-up was; a close call warns and names --up."""

import json
import logging

import numpy as np
import pytest

from data_synth.facades import facade_mesh
from reconstruct.surface.up import CUES, is_close, up_from_mesh


def _angle(a, b) -> float:
    return float(np.degrees(np.arccos(np.clip(np.dot(a, b), -1.0, 1.0))))


def _wall_is_largest(v, f, up) -> bool:
    n = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])
    a = np.linalg.norm(n, axis=1)
    d = (n / a[:, None]) @ up
    return a[np.abs(d) < 0.17].sum() > 1.5 * a[d > 0.94].sum()


@pytest.mark.parametrize("seed", range(6))
def test_up_of_a_facade_at_a_random_rotation(seed):
    rng = np.random.default_rng(seed)
    v, f, up = facade_mesh(rng, width=rng.uniform(12, 30), height=rng.uniform(9, 15),
                           ground_depth=rng.uniform(3, 6), floors=int(rng.integers(3, 5)),
                           bays=int(rng.integers(4, 8)))
    assert _wall_is_largest(v, f, up)  # the case area alone gets wrong
    est = up_from_mesh(v, f)
    assert _angle(est.up, up) < 5.0, est.detail
    d = est.decision
    assert d["cue"] in CUES.values() and 0 < d["margin"] <= 1
    assert d["runner_up"] is not None and d["runner_up"]["angle_deg"] > 20
    assert est.to_dict()["decision"] == d


def test_a_bare_strip_and_wall_is_a_close_call_and_the_cli_names_up(tmp_path, caplog):
    """A wall with a strip of ground as deep as the wall is tall, and nothing else (no
    windows, no roof), is an L that reads either way: the estimate says it is close, and
    the command's warning names --up."""
    from scanamp.cli.amplify import _warn_if_close

    # a 20 x 10 wall (facing -y) on a 20 x 10 strip of ground, as two quads
    v = np.array([[0, 0, 0], [20, 0, 0], [20, 0, 10], [0, 0, 10],
                  [0, -10, 0], [20, -10, 0]], float)
    f = np.array([[0, 1, 2], [0, 2, 3], [4, 5, 1], [4, 1, 0]])
    est = up_from_mesh(v, f)
    assert est.close, est.detail
    assert is_close(est.to_dict())
    (tmp_path / "report.json").write_text(json.dumps({"up": est.to_dict()}))
    with caplog.at_level(logging.WARNING):
        _warn_if_close(tmp_path)
    assert "--up" in caplog.text and "close call" in caplog.text
