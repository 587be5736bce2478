"""Review of sweep 35's fat-brush stencils (h189): whether a wide see-through piece bends was
measured from the convex hull of every one of its pixels' corners, a minute and half a
gigabyte for one wide slot in a 6000-pixel picture; the ends of its rows give the same hull."""

import numpy as np
import pytest
import scipy.spatial
from PIL import Image, ImageDraw
from scipy import ndimage

from procmod.targets import load_target_image
from procmod.targets.image import _bent_strokes


def _stencil(path, ink: np.ndarray) -> None:
    """A grey picture with alpha: white paper, see-through where ``ink`` is."""
    picture = np.zeros(ink.shape + (2,), dtype=np.uint8)
    picture[..., 0] = 255
    picture[..., 1] = np.where(ink, 0, 255)
    Image.fromarray(picture, "LA").save(path)


def _read(path) -> np.ndarray:
    target = load_target_image(path)
    top, left, height, width = target.picture
    return target.mask[top:top + height, left:left + width]


@pytest.fixture
def hulled(monkeypatch):
    """How many points each convex hull was asked to wrap."""
    sizes = []
    real = scipy.spatial.ConvexHull

    def spy(points, *args, **kwargs):
        sizes.append(len(points))
        return real(points, *args, **kwargs)

    monkeypatch.setattr(scipy.spatial, "ConvexHull", spy)
    return sizes


def _fat_letter(size: int = 400) -> np.ndarray:
    picture = Image.new("L", (size, size), 0)
    draw = ImageDraw.Draw(picture)
    s = size / 200
    draw.line([(40 * s, 160 * s), (100 * s, 40 * s), (160 * s, 160 * s)], fill=255, width=round(22 * s))
    draw.line([(70 * s, 110 * s), (130 * s, 110 * s)], fill=255, width=round(22 * s))
    return np.asarray(picture) > 127


def test_a_wide_slot_is_hulled_from_its_rows_ends_and_stays_the_page(tmp_path, hulled):
    slot = np.zeros((400, 400), dtype=bool)
    slot[170:230, 20:380] = True  # 60 x 360: long and wide, convex (a vent, not a stroke)
    _stencil(tmp_path / "slot.png", slot)
    assert np.array_equal(_read(tmp_path / "slot.png"), ~slot)
    assert hulled and max(hulled) <= 4 * 61  # two corners of each end of its 60 rows, not its 21,600 pixels'


def test_a_fat_stencil_is_hulled_from_its_rows_ends_and_reads_as_its_strokes(tmp_path, hulled):
    ink = _fat_letter()
    _stencil(tmp_path / "fat.png", ink)
    mask = _read(tmp_path / "fat.png")
    assert (mask & ink).sum() / (mask | ink).sum() > 0.95
    assert hulled and max(hulled) <= 4 * (400 + 1)


def test_bent_is_judged_as_from_every_pixels_corners():
    # the hull of the rows' ends is that of all the pixels: the same pieces read as bent
    rng = np.random.default_rng(7)
    for _ in range(20):
        holes = ndimage.binary_opening(rng.random((80, 90)) < 0.55)
        labels, count = ndimage.label(holes, structure=np.ones((3, 3), dtype=bool))
        which = np.arange(1, count + 1)
        bent = _bent_strokes(holes, labels, which)
        for piece in which:
            rows, cols = np.nonzero(labels == piece)
            corners = np.concatenate([np.stack([rows + dr, cols + dc], axis=1) for dr in (0, 1) for dc in (0, 1)])
            area = len(rows)
            extent = max(np.ptp(rows), np.ptp(cols)) + 1
            boundary = (holes & ~ndimage.binary_erosion(holes) & (labels == piece)).sum()
            if extent < 4 * 2.0 * area / max(boundary, 1):
                assert not bent[piece]
                continue
            try:
                hull = scipy.spatial.ConvexHull(np.unique(corners, axis=0)).volume
            except Exception:
                assert not bent[piece]
                continue
            assert bent[piece] == (area <= 0.8 * hull)
