"""Seed 001's latent path (section 5.2): from one encoding to another through training
encodings, each segment split at the training encoding closest to both its endpoints."""

import numpy as np
import pytest

from procmod.core.errors import InvalidArgumentError
from procmod.strings.latent import latent_path


def _on_a_line(steps: int) -> np.ndarray:
    """Training encodings at 0, 1/steps, ..., 1 on the first axis of a 3-d latent space."""
    out = np.zeros((steps + 1, 3))
    out[:, 0] = np.arange(steps + 1) / steps
    return out


def test_a_path_of_8_points_keeps_its_endpoint():
    # the bench's and the CLI's length: the rounds give 3, 5, then 8 points by splitting
    # three of the four equal segments (the first three: equal lengths keep path order);
    # a truncated 9-point path would end at 0.875
    anchors = _on_a_line(8)
    path = latent_path(anchors[0], anchors[8], anchors, 8)
    assert np.allclose(path[:, 0], [0, 0.125, 0.25, 0.375, 0.5, 0.625, 0.75, 1])
    assert np.array_equal(path[0], anchors[0]) and np.array_equal(path[-1], anchors[8])


@pytest.mark.parametrize("length", [2, 3, 4, 5, 6, 8, 9, 17, 31, 32, 33])
def test_paths_have_the_length_asked_for_and_the_given_endpoints(length):
    rng = np.random.default_rng(length)
    anchors = rng.standard_normal((80, 4))
    za, zb = anchors[3], anchors[41]
    path = latent_path(za, zb, anchors, length)
    assert path.shape == (length, 4)
    assert np.array_equal(path[0], za) and np.array_equal(path[-1], zb)
    inner = path[1:-1]
    # every inner point is a training encoding other than the endpoints, none twice
    index = [int(np.flatnonzero((anchors == p).all(axis=1))[0]) for p in inner]
    assert len(set(index)) == len(index) and not {3, 41} & set(index)


def test_a_path_on_a_line_runs_in_order():
    anchors = _on_a_line(64)
    for length in (5, 8, 17, 32, 33):
        x = latent_path(anchors[0], anchors[64], anchors, length)[:, 0]
        assert x[0] == 0 and x[-1] == 1 and np.all(np.diff(x) > 0), (length, x)
    # 2^k + 1 points on an evenly spaced line: the evenly spaced points
    assert np.allclose(latent_path(anchors[0], anchors[64], anchors, 33)[:, 0], np.arange(33) / 32)


def test_a_segment_is_split_at_the_encoding_closest_to_both_endpoints():
    # p's farther endpoint is 5.78 away, q's 7.0; q is nearer the midpoint (2.0 vs 2.9)
    za, zb = np.array([0.0, 0.0]), np.array([10.0, 0.0])
    p, q = np.array([5.0, 2.9]), np.array([3.0, 0.0])
    path = latent_path(za, zb, np.array([za, q, p, zb]), 3)
    assert np.array_equal(path[1], p)


def test_duplicate_encodings_are_one_point():
    anchors = np.array([[0.0], [0.5], [0.5], [0.25], [1.0], [0.0]])
    x = latent_path(anchors[0], anchors[4], anchors, 4)[:, 0]
    assert len(set(x)) == 4 and np.all(np.diff(x) > 0)


def test_impossible_paths_say_why():
    anchors = _on_a_line(4)
    with pytest.raises(InvalidArgumentError, match="at least its 2 endpoints"):
        latent_path(anchors[0], anchors[4], anchors, 1)
    with pytest.raises(InvalidArgumentError, match="needs 4 training encodings besides its endpoints; got 3"):
        latent_path(anchors[0], anchors[4], anchors, 6)
