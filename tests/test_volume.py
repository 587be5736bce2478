import json
import math

import numpy as np
import pytest

from procmod.core import InvalidArgumentError, run_forward
from procmod.geometry.solid import Box, translation
from procmod.geometry.voxel import VoxelGrid, voxelize
from procmod.models import get_model
from procmod.targets import ProxyVolume, TargetFileError, Volume, load_volume_target

GRID = VoxelGrid.around((-2, -2, -2), (2, 2, 2), 0.1)
SHIP = get_model("spaceship")


def _mask(*parts):
    return voxelize(list(parts), GRID)


def _inside_box(centres, centre, size):
    """Brute force: which voxel centres lie in the closed axis-aligned box (by coordinates)."""
    return np.all(np.abs(centres - np.asarray(centre)) <= 0.5 * np.asarray(size), axis=-1)


def test_svol_matches_its_definition():
    assert GRID.origin == (-2.0, -2.0, -2.0) and GRID.shape == (40, 40, 40)  # centres at -1.95 + 0.1 k
    centres = GRID.centres()
    fill = _inside_box(centres, (0, 0, 0), (2, 2, 2))
    avoid = _inside_box(centres, (1.4, 1.4, 1.4), (1, 1, 1))
    target = Volume(GRID, [(fill, 2.0, -0.5), (avoid, -3.0, 0.0)], w_self=0.25)
    scene = target.new_output(SHIP)
    boxes = [((0.5, 0.5, 0.5), (1, 1, 1)), ((1.0, 1.0, 1.0), (1, 1, 1)), ((-1.5, 0, 0), (1, 1, 5))]
    for (x, y, z), size in boxes:
        scene.add(Box(size, translation(x, y, z)))
    # Worked out by hand: the first two boxes share [0.5, 1]^3, 5 centres a side (0.55 ..
    # 0.95), so 125 voxels are hit twice; the third, z in [-2.5, 2.5], covers 5 lattice
    # cells beyond each end of the grid's z range [-2, 2] on 10 x 10 centres in x and y.
    overlaps, outside = 5 ** 3, 2 * 5 * 10 * 10
    hits = sum(_inside_box(centres, c, size).astype(int) for c, size in boxes)
    assert int(np.maximum(hits - 1, 0).sum()) == overlaps  # the brute force agrees
    covered = hits > 0
    expected = (2.0 * (fill & covered).sum() - 0.5 * (covered & ~fill).sum()
                - 3.0 * (avoid & covered).sum() + 0.0 * (covered & ~avoid).sum())
    expected += outside * (-0.5 + 0.0) - 0.25 * overlaps  # outside cells get the avoid weights
    assert (scene.overlaps, scene.outside) == (overlaps, outside)
    assert np.array_equal(scene.occupancy, covered)
    assert target.score(scene) == pytest.approx(expected, abs=1e-9)
    assert target.log_likelihood(scene) == pytest.approx(target.score(scene) / target.temperature)


def test_proxy_score_of_the_original_program():
    mask = _mask(Box((2, 2, 2)))
    target = ProxyVolume(GRID, mask)
    scene = target.new_output(SHIP)
    scene.add(Box((2, 2, 2)))
    assert target.score(scene) == pytest.approx(1.0)
    norm = -math.log(0.005 * math.sqrt(2 * math.pi))
    assert target.log_likelihood(scene) == pytest.approx(2 * norm)
    scene.add(Box((0.5, 0.5, 0.5)))  # intersects an earlier part
    assert target.log_likelihood(scene) == -math.inf
    poking = target.new_output(SHIP)
    poking.add(Box((1, 1, 6)))
    assert target.outside(poking) == pytest.approx(2 * (3 - 2) / 4)  # 1 beyond each end of a 4-long grid


QUARTER = VoxelGrid((-2.0, -2.0, -2.0), 0.25, (16, 16, 16))  # centres at -1.875 + 0.25 k
HALF = VoxelGrid((-2.25, -2.25, -2.25), 0.5, (9, 9, 9))  # centres at -2 + 0.5 k: on x = 0.5


def _proxy_ll(grid, *parts):
    """ProxyVolume log-likelihood of ``parts`` and the voxel overlap count they give."""
    target = ProxyVolume(grid, voxelize([Box((2, 2, 2))], grid))
    scene = target.new_output(SHIP)
    for p in parts:
        scene.add(p)
    return target.log_likelihood(scene), scene.overlaps


def test_proxy_intersections_are_exact_not_shared_voxels():
    from procmod.geometry.solid import Cylinder, compose, rotation
    unit = Box((1, 1, 1))
    # Two unit boxes overlapping by 0.1 (x in [0.4, 0.5]): no voxel centre there on a 0.25 grid
    ll, overlaps = _proxy_ll(QUARTER, unit, Box((1, 1, 1), translation(0.9, 0, 0)))
    assert overlaps == 0 and ll == -math.inf
    # Touching boxes (x = 0.5 shared) are not intersecting, even where voxel centres lie on
    # the shared face and count in both parts.
    ll, overlaps = _proxy_ll(HALF, unit, Box((1, 1, 1), translation(1.0, 0, 0)))
    assert overlaps > 0 and math.isfinite(ll)
    ll, _ = _proxy_ll(QUARTER, unit, Box((1, 1, 1), translation(1.0, 0, 0)))
    assert math.isfinite(ll)
    # Rotated: a unit cube turned 45 degrees about z reaches x = 0.707; a box from x = 0.65
    # meets only its edge region (x in [0.65, 0.707], |y| < 0.057): no centre there.
    turned = Box((1, 1, 1), rotation("z", math.pi / 4))
    ll, overlaps = _proxy_ll(QUARTER, turned, Box((1, 1, 1), translation(1.15, 0, 0)))
    assert overlaps == 0 and ll == -math.inf
    ll, _ = _proxy_ll(QUARTER, turned, Box((1, 1, 1), translation(math.sqrt(0.5) + 0.5, 0, 0)))  # edge on face
    assert math.isfinite(ll)
    # A cylinder's side 0.1 into a box (x in [0.4, 0.5]) and a cylinder tangent to it
    ll, overlaps = _proxy_ll(QUARTER, Cylinder(0.5, 1.0, translation(0, 0, -0.5)), Box((1, 1, 1), translation(0.9, 0, 0)))
    assert overlaps == 0 and ll == -math.inf
    ll, _ = _proxy_ll(QUARTER, Cylinder(0.5, 1.0, translation(0, 0, -0.5)), Box((1, 1, 1), translation(1.0, 0, 0)))
    assert math.isfinite(ll)
    # and the cylinder's bounding box overlaps the box's corner region, the solids do not
    ll, _ = _proxy_ll(QUARTER, Cylinder(0.5, 1.0, translation(0, 0, -0.5)),
                      Box((0.3, 0.3, 1), compose(translation(0.55, 0.55, 0), rotation("z", 0.0))))
    assert math.isfinite(ll)


def test_proxy_scene_copies_and_removes_its_intersections():
    target = ProxyVolume(QUARTER, voxelize([Box((2, 2, 2))], QUARTER))
    scene = target.new_output(SHIP)
    scene.add(Box((1, 1, 1)))
    copy = scene.copy()
    scene.add(Box((1, 1, 1), translation(0.9, 0, 0)))
    assert target.log_likelihood(scene) == -math.inf and math.isfinite(target.log_likelihood(copy))
    assert np.array_equal(copy.occupancy, voxelize([Box((1, 1, 1))], QUARTER))  # the voxels were copied
    scene.remove(Box((1, 1, 1), translation(0.9, 0, 0)))
    assert target.log_likelihood(scene) == pytest.approx(target.log_likelihood(copy))


def test_volume_targets_need_3d_models():
    with pytest.raises(InvalidArgumentError, match="3D model"):
        Volume(GRID, [(_mask(Box((1, 1, 1))), 1, -1)]).new_output(get_model("vines"))


def test_load_volume_target_files(tmp_path):
    mask = _mask(Box((1, 1, 1)))
    np.save(tmp_path / "v.npy", mask)
    spec = {"format": "procmod-volume/1", "grid": {"origin": list(GRID.origin), "voxel_size": GRID.size},
            "layers": [{"file": "v.npy", "w_fill": 1, "w_avoid": -1}]}
    (tmp_path / "target.json").write_text(json.dumps(spec))
    target = load_volume_target(tmp_path / "target.json")
    assert isinstance(target, Volume) and target.best_attainable == mask.sum()
    d = run_forward(SHIP, np.random.default_rng(0), output=target.new_output(SHIP))
    assert math.isfinite(target.score(d.output))
    # A watertight mesh is voxelized on load.
    import trimesh
    trimesh.creation.box((1, 2, 3)).export(tmp_path / "box.obj")
    spec2 = {"format": "procmod-volume/1", "voxel_size": 0.1, "layers": [{"file": "box.obj"}], "score": "proxy"}
    (tmp_path / "mesh.json").write_text(json.dumps(spec2))
    proxy = load_volume_target(tmp_path / "mesh.json")
    assert isinstance(proxy, ProxyVolume)
    assert proxy.mask.sum() * 0.1 ** 3 == pytest.approx(6.0, rel=0.05)


@pytest.mark.parametrize("spec,message", [
    ({"format": "other"}, "procmod-volume/1"),
    ({"format": "procmod-volume/1", "layers": []}, "non-empty"),
    ({"format": "procmod-volume/1", "layers": [{"file": "nope.obj"}]}, "does not exist"),
    ({"format": "procmod-volume/1", "layers": [{"file": "v.npy"}]}, "needs \"grid\""),
    ({"format": "procmod-volume/1", "layers": [{"file": "open.obj"}]}, "need \"voxel_size\""),
])
def test_malformed_volume_targets(tmp_path, spec, message):
    import trimesh
    np.save(tmp_path / "v.npy", _mask(Box((1, 1, 1))))
    open_mesh = trimesh.creation.box((1, 1, 1))
    open_mesh.faces = open_mesh.faces[:-2]
    open_mesh.export(tmp_path / "open.obj")
    (tmp_path / "t.json").write_text(json.dumps(spec))
    with pytest.raises(TargetFileError, match=message):
        load_volume_target(tmp_path / "t.json")


def test_an_open_mesh_is_a_volume_layer(tmp_path):
    # a box with one side missing used to be refused ("not watertight"); its winding number
    # keeps the box's inside (procmod.geometry.inside; tests/test_mesh_targets.py for the rest)
    import trimesh
    open_mesh = trimesh.creation.box((1, 1, 1))
    open_mesh.faces = open_mesh.faces[:-2]
    open_mesh.export(tmp_path / "open.obj")
    (tmp_path / "t.json").write_text(json.dumps({"format": "procmod-volume/1", "voxel_size": 0.1,
                                                 "layers": [{"file": "open.obj"}], "score": "proxy"}))
    proxy = load_volume_target(tmp_path / "t.json")
    assert 900 < proxy.mask.sum() <= 1000  # of the 10 x 10 x 10 voxel centres in the box


def test_part_cache_gives_the_same_scene_as_voxelizing():
    # Engines that replay whole derivations look parts up instead of voxelizing again; the
    # counts, gains, overlaps and outside counts must be those of plain voxelization.
    import numpy as np
    from procmod.core import run_forward
    from procmod.geometry.voxel import VoxelGrid, VoxelScene
    from procmod.models import get_model
    grid = VoxelGrid((-6.0, -4.0, -7.0), 0.4, (30, 20, 40))
    gain = np.random.default_rng(0).normal(size=30 * 20 * 40)
    parts = [g for s in range(6) for g in run_forward(get_model("spaceship"), np.random.default_rng(s)).geometry()]
    plain, cached = VoxelScene(grid, gain), VoxelScene(grid, gain)
    cached.use_part_cache()
    for round_ in range(2):  # the second round is served from the cache
        for part in parts:
            assert plain.add(part) == cached.add(part)
        assert cached.part_cache.hits >= round_ * len(set(parts))
    assert np.array_equal(plain.counts, cached.counts)
    assert (plain.overlaps, plain.outside, plain.filled_count) == (cached.overlaps, cached.outside, cached.filled_count)
    assert abs(plain.gain_total - cached.gain_total) < 1e-9


def test_a_part_far_larger_than_the_targets_voxels_is_refused_not_run_for_hours():
    """A 5 cm target at 1 mm voxels against parts of metres: the kernels would visit some
    10^10 cells a part (and the record buffer asked for 55 GiB)."""
    from procmod.geometry.voxel import VoxelScene

    grid = VoxelGrid((-0.06, -0.06, -0.06), 0.001, (121, 121, 121))
    part = Box((3.0, 1.0, 1.0), translation(0.0, 0.0, 0.0))
    for cached in (False, True):
        scene = VoxelScene(grid)
        if cached:
            scene.use_part_cache()
        with pytest.raises(InvalidArgumentError, match="far smaller than the model's parts"):
            scene.add(part)
    small = Box((0.02, 0.02, 0.02), translation(0.0, 0.0, 0.0))  # a part of the target's scale is fine
    assert VoxelScene(grid).add(small) > 0
