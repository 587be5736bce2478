"""``package://`` meshes of a package that is no ancestor of the URDF: found by the
``package.xml`` that names it, as rospack and ament crawl a workspace (h156), within bounds."""

import os
import time
from pathlib import Path

import numpy as np
import pytest
import trimesh

from procmod.geometry import assets
from procmod.geometry.assets import AssetError, read_assets

from asset_writers import urdf, wedge_mesh


def write_stl(path: Path, size: float) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    trimesh.Trimesh(*wedge_mesh(size), process=False).export(path)


def package(folder: Path, name: str, meshes=(("base.stl", 0.1),)) -> Path:
    """A ROS package folder whose package.xml names it ``name`` (its folder may be named
    otherwise), holding ``meshes/FILE`` wedges of the given sizes."""
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "package.xml").write_text(f'<?xml version="1.0"?>\n<package format="3">\n  <!-- <name>template</name> -->'
                                        f'\n  <name>{name}</name>\n  <version>1.0.0</version>\n</package>\n')
    for file, size in meshes:
        write_stl(folder / "meshes" / file, size)
    return folder


def robot(ws: Path, meshes: dict) -> Path:
    """``ws/src/my_robot``: a package with its own ``meshes/base.stl`` (a wedge of 0.5) and
    ``urdf/robot.urdf`` whose links are ``meshes`` ({link: package:// URI})."""
    own = package(ws / "src" / "my_robot", "my_robot", (("base.stl", 0.5),))
    (own / "urdf").mkdir()
    links = {link: [f'<geometry><mesh filename="{uri}"/></geometry>'] for link, uri in meshes.items()}
    joints = [(f"j{i}", "base", link, (0, 0, 0.1 * i), (0, 0, 0)) for i, link in enumerate(meshes) if link != "base"]
    (own / "urdf" / "robot.urdf").write_text(urdf(links, joints))
    return own / "urdf" / "robot.urdf"


def sizes(path) -> dict:
    """The length of each link's part (a wedge's, along the world's x axis)."""
    s = read_assets(path)
    return {node.name: round(float(np.ptp(np.asarray(s.parts[node.part].vertices) @ node.transform[0, :3])), 6)
            for asset in s.assets for node in asset.nodes()}


@pytest.fixture(autouse=True)
def no_ros_environment(monkeypatch):
    monkeypatch.delenv("ROS_PACKAGE_PATH", raising=False)
    monkeypatch.delenv("AMENT_PREFIX_PATH", raising=False)


@pytest.fixture
def listed(monkeypatch):
    """The folders os.scandir lists while the test runs."""
    out = []
    scandir = os.scandir

    def counted(path="."):
        out.append(Path(path))
        return scandir(path)

    monkeypatch.setattr(os, "scandir", counted)
    return out


def test_a_sibling_package_in_a_folder_named_otherwise_is_found_by_its_package_xml(tmp_path, monkeypatch):
    """A workspace's ``src/ur_description-main`` (a GitHub download) whose package.xml names
    ``ur_description``: a URDF in ``src/my_robot`` naming ``package://ur_description/meshes/
    base.stl`` had been given my_robot's own ``meshes/base.stl`` (the bare-path fallback).
    Packages one folder further down (a repository of several), linked into ``src``, or
    named by ROS_PACKAGE_PATH / AMENT_PREFIX_PATH are found too; an ignored one is not."""
    ws = tmp_path / "ws"
    package(ws / "src" / "ur_description-main", "ur_description")
    package(ws / "src" / "universal_robot-melodic" / "ur_gripper", "ur_gripper", (("base.stl", 0.2),))
    package(tmp_path / "elsewhere" / "camera-1.2", "camera", (("base.stl", 0.3),))
    (ws / "src" / "camera").symlink_to(tmp_path / "elsewhere" / "camera-1.2", target_is_directory=True)
    path = robot(ws, {"base": "package://my_robot/meshes/base.stl", "arm": "package://ur_description/meshes/base.stl",
                      "hand": "package://ur_gripper/meshes/base.stl", "eye": "package://camera/meshes/base.stl"})
    assert sizes(path) == {"base": 0.5, "arm": 0.1, "hand": 0.2, "eye": 0.3}
    monkeypatch.chdir(path.parent)  # a bare "robot.urdf": its folder "." has no parents until resolved
    assert sizes(Path("robot.urdf")) == {"base": 0.5, "arm": 0.1, "hand": 0.2, "eye": 0.3}
    # a package catkin is told to pass over is none: the URDF's own package's file again, as before
    (ws / "src" / "ur_description-main" / "CATKIN_IGNORE").write_text("")
    assert sizes(path)["arm"] == 0.5
    # nor does a package of that name in a folder too far up count; ROS's own paths do
    ros = package(tmp_path / "opt" / "share" / "ur_description", "ur_description", (("base.stl", 0.4),))
    monkeypatch.setenv("ROS_PACKAGE_PATH", os.pathsep.join([str(tmp_path / "nowhere"), str(ros.parent)]))
    assert sizes(path)["arm"] == 0.4
    monkeypatch.delenv("ROS_PACKAGE_PATH")
    monkeypatch.setenv("AMENT_PREFIX_PATH", str(tmp_path / "opt"))
    assert sizes(path)["arm"] == 0.4
    # the package found holds no such file: where the URI was sought is named
    monkeypatch.delenv("AMENT_PREFIX_PATH")
    (ws / "src" / "ur_description-main" / "CATKIN_IGNORE").unlink()
    (ws / "src" / "my_robot" / "meshes" / "base.stl").rename(ws / "src" / "my_robot" / "meshes" / "own.stl")
    (ws / "src" / "ur_description-main" / "meshes" / "base.stl").unlink()
    with pytest.raises(AssetError, match=r"'package://my_robot/meshes/base.stl' is neither 'meshes/base.stl' nor "
                                         r"'my_robot/meshes/base.stl' under the URDF's folder .* nor in a package "
                                         r"folder nearby whose package.xml names 'my_robot'"):
        read_assets(path)


def test_the_package_crawl_is_bounded_in_depth_folders_and_links(tmp_path, listed, monkeypatch):
    """Finding a sibling package lists folders near the URDF only: a link back up (a loop),
    a deep tree (a package.xml naming it 30 folders down is none) and a wide one (past
    PACKAGE_CRAWL_ENTRIES nothing more is listed) cost a bounded number of listings, each
    folder listed once a run however many meshes name the package; nothing above the
    URDF's nearest ancestors (here tmp_path) or above the home folder is listed."""
    ws = tmp_path / "ws"
    package(ws / "src" / "vendor" / "ur_description-main", "ur_description")
    deep = ws / "src" / "deep" / Path(*[f"d{i}" for i in range(30)])
    package(deep, "ur_description", (("base.stl", 0.9),))
    (ws / "src" / "loop").symlink_to(ws, target_is_directory=True)
    (ws / "src" / "self").symlink_to(ws / "src", target_is_directory=True)
    (ws / "src" / "dangling").symlink_to(tmp_path / "gone", target_is_directory=True)
    for i in range(300):
        (ws / "src" / "wide" / f"w{i:03d}" / "x").mkdir(parents=True)
    uris = {"base": "package://my_robot/meshes/base.stl",
            **{f"arm{i}": "package://ur_description/meshes/base.stl" for i in range(20)}}
    path = robot(ws, uris)
    start = time.perf_counter()
    found = sizes(path)
    assert found == {"base": 0.5, **{f"arm{i}": 0.1 for i in range(20)}}
    assert time.perf_counter() - start < 5
    assert len(listed) == len(set(listed)) and len(listed) < 700, len(listed)
    assert all(p.resolve().is_relative_to(tmp_path.resolve()) for p in listed)
    assert not any("d1" in p.parts for p in listed)  # d1 is PACKAGE_CRAWL_DEPTH (3) below src: not listed
    # the one too deep is not taken for it: the bare fallback (the URDF's own package's file) as before
    (ws / "src" / "vendor" / "ur_description-main" / "package.xml").unlink()
    assert set(sizes(path).values()) == {0.5}
    # a budget of entries read: a wide tree is cut short
    listed.clear()
    monkeypatch.setattr(assets, "PACKAGE_CRAWL_ENTRIES", 50)
    assert set(sizes(path).values()) == {0.5}
    assert len(listed) <= 51
    # a URDF in the home folder: the home folder is crawled (a download beside it), not above
    listed.clear()
    monkeypatch.setattr(assets, "PACKAGE_CRAWL_ENTRIES", 20000)
    home = tmp_path / "home" / "me"
    monkeypatch.setenv("HOME", str(home))
    package(home / "Downloads" / "ur_description-main", "ur_description", (("base.stl", 0.2),))
    (home / "robot.urdf").write_text(urdf({"arm": ['<geometry><mesh filename="package://ur_description/meshes/'
                                                   'base.stl"/></geometry>']}, []))
    assert sizes(home / "robot.urdf") == {"arm": 0.2}
    assert listed and all(p.resolve().is_relative_to(home.resolve()) for p in listed)


def test_meshes_copied_beside_a_urdf_outside_any_package_come_before_a_package_nearby(tmp_path):
    """A CAD exporter's two robots in one folder, both naming ``robot_description``: armA's
    meshes copied beside its URDF (no package.xml), armB a real package of that name. armA
    had been given armB's mesh, found by the crawl (h157); a URDF inside a package of
    another name still takes a sibling package's file over its own (h156, above)."""
    write_stl(tmp_path / "armA" / "meshes" / "base_link.stl", 0.5)
    (tmp_path / "armA" / "urdf").mkdir()
    path = tmp_path / "armA" / "urdf" / "armA.urdf"
    path.write_text(urdf({"base": ['<geometry><mesh filename="package://robot_description/meshes/base_link.stl"/>'
                                   '</geometry>']}, []))
    package(tmp_path / "armB", "robot_description", (("base_link.stl", 0.1),))
    assert sizes(path) == {"base": 0.5}
    # the same folder made a package of another name: its file is that package's, not a copy
    (tmp_path / "armA" / "package.xml").write_text("<package><name>arm_a</name></package>")
    assert sizes(path) == {"base": 0.1}
