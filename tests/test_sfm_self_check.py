"""The sparse stage's truth-free self-check (reconstruct.sfm.self_check): a ring of views
around a scene with a 180-degree symmetry, its matches made by projecting the scene with
the true cameras (exact truth), the symmetric look-alikes as the false matches a repeated
structure gives. A right model explains its true matches and contradicts exactly the
false ones; the ring folded onto its half (what the mapper made of the temple) is caught
and its coincident views named."""

import numpy as np
import pytest

from acquire.camera import Camera
from reconstruct.sfm.self_check import check_model, sampson_distance

N = 12  # views on the ring; view i + 6 looks at the scene from the opposite side


def _ring():
    cams = {}
    for i in range(N):
        a = 2 * np.pi * i / N
        eye = 3.0 * np.array([np.cos(a), np.sin(a), 0.6])
        cams[f"{i:04d}.png"] = Camera.look_at(eye, [0.0, 0.0, 0.2], width=640, height=480,
                                              fov_deg=45.0)
    return cams


def _scene(rng):
    """Points with a 180-degree symmetry about the z axis (each with its twin)."""
    half = rng.uniform([-0.6, -0.4, 0.0], [0.6, 0.4, 0.5], size=(150, 3))
    return np.vstack([half, half * [-1.0, -1.0, 1.0]])


def _matches(cams, X, rng, *, false: bool, overlap: int = 3, noise_px: float = 0.3):
    """True matches between views at most ``overlap`` apart on the ring; with ``false``,
    also the symmetric look-alikes: X in view i matched to its twin in view i + 6 + k
    (|k| < overlap), which project to the same pixels as the true matches of i, i - k."""
    names = sorted(cams)
    twin = X * [-1.0, -1.0, 1.0]
    out, kinds = {}, {}
    for i in range(N):
        for j in range(i + 1, N):
            off = min(j - i, N - (j - i))
            if off <= overlap:
                kinds[(names[i], names[j])], Y = "true", X
            elif false and abs(off - N // 2) < overlap:
                kinds[(names[i], names[j])], Y = "false", twin
            else:
                continue
            p1, z1 = cams[names[i]].project(X)
            p2, z2 = cams[names[j]].project(Y)
            keep = (z1 > 0) & (z2 > 0)
            out[(names[i], names[j])] = (p1[keep] + rng.normal(scale=noise_px, size=p1[keep].shape),
                                         p2[keep] + rng.normal(scale=noise_px, size=p2[keep].shape))
    return out, kinds


def _model(cams):
    return ({n: c.cam_from_world for n, c in cams.items()},
            {n: np.array([[c.fx, 0, c.cx], [0, c.fy, c.cy], [0, 0, 1.0]]) for n, c in cams.items()})


def test_the_true_ring_explains_its_true_matches(rng):
    cams = _ring()
    matches, _ = _matches(cams, _scene(rng), rng, false=False)
    check = check_model(*_model(cams), matches)
    assert check.ok and check.contradicted == [] and check.coincident == []
    assert check.pairs == len(matches) and check.explained_share > 0.99
    assert check.warnings == []


def test_the_folded_ring_is_caught_and_its_coincident_views_named(rng):
    """Views i + 6 put at the pose of view i: the model explains the look-alike matches
    between twins (i, i + 6) and contradicts the true ones across the fold."""
    cams = _ring()
    names = sorted(cams)
    folded = {n: cams[names[k % (N // 2)]] for k, n in enumerate(names)}
    matches, kinds = _matches(cams, _scene(rng), rng, false=True)
    check = check_model(*_model(folded), matches)
    assert not check.ok and len(check.warnings) == 2
    assert sorted(check.coincident) == [(names[k], names[k + N // 2]) for k in range(N // 2)]
    bad = {(a, b) for a, b, _, _ in check.contradicted}
    twins = {(names[k], names[k + N // 2]) for k in range(N // 2)}
    assert not bad & twins  # the fold's own evidence
    across = {p for p, k in kinds.items() if k == "true"
              and (names.index(p[0]) < N // 2) != (names.index(p[1]) < N // 2)}
    assert across <= bad  # every true pair across the fold
    assert "folded onto itself" in check.warnings[1] and names[0] in check.warnings[1]


def test_the_true_ring_contradicts_exactly_the_false_matches(rng):
    """On a symmetric scene the right model cannot explain the look-alikes: the pairs it
    contradicts are those, and the share says the matches disagree with each other."""
    cams = _ring()
    matches, kinds = _matches(cams, _scene(rng), rng, false=True)
    check = check_model(*_model(cams), matches)
    assert {(a, b) for a, b, _, _ in check.contradicted} == \
        {p for p, k in kinds.items() if k == "false"}
    assert check.coincident == []
    assert not check.ok  # 24 of 60 pairs: more than the 10 % a model passes with
    share = sum(kinds[p] == "true" for p in kinds) / len(kinds)
    assert check.explained_share == pytest.approx(share, abs=0.02)


def test_sampson_distance_of_a_rectified_pair_is_the_vertical_offset():
    """Rectified views (a horizontal baseline): the epipolar lines are the rows, and the
    first-order distance of a match whose rows differ by d is d / sqrt(2) (shared
    between the two views)."""
    F = np.array([[0.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])
    x1 = np.array([[10.0, 20.0], [300.0, 5.0], [7.0, 7.0]])
    d = np.array([0.0, 2.0, -6.0])
    x2 = x1 + np.c_[[40.0, -3.0, 11.0], d]
    assert np.allclose(sampson_distance(F, x1, x2), np.abs(d) / np.sqrt(2))


def test_bad_options_are_named():
    with pytest.raises(ValueError, match="explained_px"):
        check_model({}, {}, {}, explained_px=0.0)
    with pytest.raises(ValueError, match="max_contradicted"):
        check_model({}, {}, {}, max_contradicted=2.0)



def test_no_pair_between_registered_views_passes_without_a_share():
    cams = _ring()
    poses, K = _model(cams)
    check = check_model(poses, K, {("0000.png", "unregistered.png"): (np.zeros((5, 2)),
                                                                       np.zeros((5, 2)))})
    assert check.ok and check.pairs == 0 and check.explained_share is None
    assert check.to_dict()["explained_share"] is None
