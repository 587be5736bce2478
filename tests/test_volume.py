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


def test_svol_matches_its_definition():
    fill = _mask(Box((2, 2, 2)))
    avoid = _mask(Box((1, 1, 1), translation(1.4, 1.4, 1.4)))
    target = Volume(GRID, [(fill, 2.0, -0.5), (avoid, -3.0, 0.0)], w_self=0.25)
    scene = target.new_output(SHIP)
    parts = [Box((1, 1, 1), translation(0.5, 0.5, 0.5)), Box((1, 1, 1), translation(1.0, 1.0, 1.0)),
             Box((1, 1, 5), translation(-1.5, 0, 0))]
    for p in parts:
        scene.add(p)
    model = scene.occupancy
    expected = (2.0 * (fill & model).sum() + -0.5 * (model & ~fill).sum()
                + -3.0 * (avoid & model).sum() + 0.0)
    expected += scene.outside * (-0.5) - 0.25 * scene.overlaps
    assert scene.outside > 0 and scene.overlaps > 0
    assert target.score(scene) == pytest.approx(expected)
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
    ({"format": "procmod-volume/1", "layers": [{"file": "open.obj"}]}, "not watertight"),
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
