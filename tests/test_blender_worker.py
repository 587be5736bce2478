"""The Blender add-on's procmod side, which needs no Blender: the worker's jobs and results,
the job protocol, and that procmod itself never imports bpy."""

import json
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
import trimesh

from procmod.blender import jobs, worker
from procmod.core import run_forward
from procmod.geometry.solid import Box
from procmod.models import get_model
from procmod.targets import Volume, load_target_file

ROOT = Path(__file__).resolve().parents[1]


def test_procmod_and_its_help_import_no_bpy():
    code = ("import sys, procmod, procmod.cli, procmod.blender, procmod.blender.jobs, procmod.blender.worker; "
            "import procmod.blender.package; assert 'bpy' not in sys.modules, 'bpy imported'")
    subprocess.run([sys.executable, "-c", code], check=True, timeout=120)
    run = subprocess.run([sys.executable, "-m", "procmod.cli", "--help"], capture_output=True, text=True, timeout=120)
    assert run.returncode == 0 and "procmod" in run.stdout


def test_parts_of_a_derivation_follow_its_geometry_and_calls():
    derivation = run_forward(get_model("spaceship"), np.random.default_rng([0, 2]))
    data = worker.derivation_parts(derivation)
    geometry = derivation.geometry()
    assert len(data["parts"]) == len(geometry)
    for i, (part, solid) in enumerate(zip(data["parts"], geometry)):
        assert part["tag"] == solid.tag and part["transform"] == list(solid.transform)
        assert part["kind"] == ("box" if isinstance(solid, Box) else "cylinder")
        assert part["parent"] is None or 0 <= part["parent"] < i
    assert sum(p["parent"] is None for p in data["parts"]) >= 1
    assert set(data["colours"]) == {s.tag for s in geometry}


def _job(tmp_path, **spec):
    folder = tmp_path / "job"
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "job.json").write_text(json.dumps({"format": jobs.JOB_FORMAT, **spec}))
    status = worker.run_job(folder)
    return status, json.loads((folder / "result.json").read_text())


def test_a_2d_model_is_refused_in_one_line(tmp_path):
    status, result = _job(tmp_path, command="sample", model="vines", count=1)
    assert status == 2 and not result["ok"]
    assert "2D" in result["error"] and "\n" not in result["error"]


def test_an_unknown_model_names_the_known_ones(tmp_path):
    status, result = _job(tmp_path, command="sample", model="spaceshp", count=1)
    assert status == 2 and "spaceship" in result["error"]


def _box_obj(path, lo, hi):
    mesh = trimesh.creation.box(bounds=[lo, hi])
    mesh.export(path)


def test_volume_layers_share_one_grid_and_load_as_the_cli_loads_them(tmp_path):
    _box_obj(tmp_path / "fill.obj", [-1, 0, -4], [1, 1, 4])
    _box_obj(tmp_path / "avoid.obj", [-3, 0, 0], [3, 2, 1])
    spec = {"layers": [{"mesh": "fill.obj", "object": "Fill", "w_fill": 1, "w_avoid": -1},
                       {"mesh": "avoid.obj", "object": "Avoid", "w_fill": -2, "w_avoid": 0}], "voxel_size": 0.25}
    path = worker.build_volume_target(spec, tmp_path, tmp_path / "target")
    target = load_target_file(path)
    assert isinstance(target, Volume)
    grid = target.grid
    assert np.all(np.asarray(grid.origin) <= [-3, 0, -4]) and np.all(grid.upper >= [3, 2, 4])
    # fill box 2 x 1 x 8 units = 8 x 4 x 32 voxels, avoid box 6 x 2 x 1 = 24 x 8 x 4, both
    # holding 2 x 1 x 1 = 128: inside the fill box only 1 (its w_fill) + 0 (the avoid box's
    # w_avoid); inside the avoid box only -1 (the fill box's w_avoid) - 2 (its w_fill)
    assert (target.combined == 1).sum() == 8 * 4 * 32 - 128
    assert (target.combined == -3).sum() == 24 * 8 * 4 - 128


def test_layers_of_the_same_weights_are_one_layer_and_messages_name_their_objects(tmp_path):
    _box_obj(tmp_path / "a.obj", [0, 0, 0], [1, 1, 1])
    _box_obj(tmp_path / "b.obj", [0.5, 0, 0], [1.5, 1, 1])  # overlapping a by half
    _box_obj(tmp_path / "c.obj", [3, 0, 0], [4, 1, 1])
    spec = {"layers": [{"mesh": "a.obj", "object": "A", "w_fill": 1, "w_avoid": -1},
                       {"mesh": "c.obj", "object": "C", "w_fill": -2, "w_avoid": 0},
                       {"mesh": "b.obj", "object": "B", "w_fill": 1, "w_avoid": -1}], "voxel_size": 0.25}
    target = load_target_file(worker.build_volume_target(spec, tmp_path, tmp_path / "t"))
    # the union of a and b (1.5 x 1 x 1 units) gains 1 a voxel, overlap included; c costs 2 + 1
    assert (target.combined == 1).sum() == 6 * 4 * 4 and (target.combined == -3).sum() == 4 * 4 * 4
    assert worker._name_layers("layers[0].file: no inside", spec).startswith("target layers 'A', 'B'")
    assert worker._name_layers("layers[1].file: no inside", spec).startswith("target layer 'C'")


def test_a_cube_on_the_lattice_gets_every_voxel(tmp_path):
    # a 2-unit cube at the origin: at voxel size 0.25 its faces' diagonals pass through the
    # centres of 64 of its 512 voxels (plain ray parity lost them)
    _box_obj(tmp_path / "cube.obj", [-1, -1, -1], [1, 1, 1])
    spec = {"layers": [{"mesh": "cube.obj", "w_fill": 1, "w_avoid": 0}], "voxel_size": 0.25}
    target = load_target_file(worker.build_volume_target(spec, tmp_path, tmp_path / "t"))
    assert (target.combined == 1).sum() == 512


def test_a_target_layer_without_an_inside_is_named_by_its_object(tmp_path):
    folder = tmp_path / "mesh"
    folder.mkdir()
    trimesh.Trimesh([[0, 0, 0], [1, 0, 0], [0, 1, 0.5], [1, 1, 0.5]], [[0, 1, 2], [1, 3, 2]]).export(folder / "sheet.obj")
    status, result = _job(tmp_path / "run", command="infer", model="spaceship", engine="ga", budget="1gens",
                          out=str(tmp_path / "out"), target_folder=str(tmp_path / "out.target"),
                          target={"kind": "volume", "layers": [{"mesh": str(folder / "sheet.obj"), "object": "Sheet"}],
                                  "voxel_size": 0.1})
    assert status == 2 and "target layer 'Sheet'" in result["error"] and "inside" in result["error"]
    assert not (tmp_path / "out").exists()


def test_a_grid_too_large_is_refused_before_voxelizing(tmp_path):
    _box_obj(tmp_path / "big.obj", [0, 0, 0], [100, 100, 100])
    with pytest.raises(Exception, match="larger Voxel size in the panel"):
        worker.build_volume_target({"layers": [{"mesh": "big.obj"}], "voxel_size": 0.1}, tmp_path, tmp_path / "t")


def test_a_sheared_example_names_its_object_not_the_jobs_temporary_file(tmp_path):
    folder = tmp_path / "job"
    (folder / "parts").mkdir(parents=True)
    _box_obj(folder / "parts" / "part0.obj", [-1, -1, -1], [1, 1, 1])
    shear = [[1, 0.5, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]]
    identity = np.eye(4).tolist()
    examples = {"format": "procmod-examples/1", "parts": {"Cube": {"mesh": "parts/part0.obj"}},
                "examples": [{"part": "Cube", "transform": identity,
                              "children": [{"part": "Cube", "transform": shear}]}]}
    (folder / "examples.json").write_text(json.dumps(examples))
    (folder / "names.json").write_text(json.dumps({"examples[0]": "Body", "examples[0].children[0]": "Leg.001"}))
    status, result = _job(tmp_path, command="learn", examples="examples.json", names="names.json",
                          out=str(tmp_path / "learned"), count=1)
    assert status == 2 and result["error"].startswith("object 'Leg.001': ")
    assert "shears" in result["error"] and "Apply > Scale" in result["error"]
    assert str(folder) not in result["error"] and "\n" not in result["error"]


def test_a_job_whose_python_cannot_start_ends_with_one_line(tmp_path):
    job = jobs.Job("sample", {"model": "spaceship"}, str(tmp_path / "no-python"), folder=tmp_path / "j").start()
    result = job.wait(timeout=30)
    assert not result["ok"] and "Python preference" in result["error"]


def test_a_worker_that_dies_is_reported_with_its_last_line(tmp_path):
    fake = tmp_path / "python"
    fake.write_text("#!/bin/sh\necho 'Segmentation fault' >&2\nexit 139\n")
    fake.chmod(0o755)
    job = jobs.Job("sample", {"model": "spaceship"}, str(fake), folder=tmp_path / "j").start()
    result = job.wait(timeout=30)
    assert not result["ok"] and "status 139" in result["error"] and "Segmentation fault" in result["error"]


def test_a_job_killed_before_its_result_removes_the_run_folders_it_began(tmp_path):
    # a worker that makes its run folders then hangs (learning, say), and is stopped
    fake = tmp_path / "python"
    fake.write_text(f"#!/bin/sh\nmkdir -p {tmp_path}/learn-001/checkpoint {tmp_path}/learn-001.target\n"
                    f"touch {tmp_path}/made\nsleep 60\n")
    fake.chmod(0o755)
    (tmp_path / "earlier").mkdir()
    job = jobs.Job("learn", {"out": str(tmp_path / "learn-001"), "target_folder": str(tmp_path / "learn-001.target")},
                   str(fake), folder=tmp_path / "j").start()
    for _ in range(300):
        if (tmp_path / "made").exists():
            break
        job.poll()
        time.sleep(0.05)
    assert (tmp_path / "learn-001" / "checkpoint").is_dir()
    job.stop()
    assert job.result["cancelled"]
    assert not (tmp_path / "learn-001").exists() and not (tmp_path / "learn-001.target").exists()
    # a folder that was there before the job started is the user's, and stays
    kept = jobs.Job("learn", {"out": str(tmp_path / "earlier")}, str(fake), folder=tmp_path / "k").start()
    kept.kill()
    assert (tmp_path / "earlier").is_dir()
    # but the examples the operator exported for a learn job are removed with it (h66: left behind)
    (tmp_path / "learn-002.examples" / "examples").mkdir(parents=True)
    failed = jobs.Job("learn", {"out": str(tmp_path / "learn-002"),
                                "prepared_folder": str(tmp_path / "learn-002.examples")},
                      str(fake), folder=tmp_path / "p").start()
    failed.kill()
    assert not (tmp_path / "learn-002.examples").exists()


def test_the_addon_zip_holds_the_blender_side_and_its_python(tmp_path):
    import zipfile

    from procmod.blender.package import write_addon_zip
    path = write_addon_zip(tmp_path / "addon.zip", "/opt/env/bin/python")
    with zipfile.ZipFile(path) as archive:
        names = set(archive.namelist())
        assert names == {f"procmod_blender/{n}" for n in ("__init__.py", "addon.py", "scene.py", "jobs.py",
                                                          "default_python.txt")}
        assert archive.read("procmod_blender/default_python.txt").decode().strip() == "/opt/env/bin/python"
        assert "bl_info" in archive.read("procmod_blender/__init__.py").decode()


@pytest.mark.parametrize("out, says", [("addon.tar", "--out must be a .zip file"), ("none/x/addon.zip", "cannot write")])
def test_the_addon_packager_refuses_in_one_line(tmp_path, capsys, out, says):
    """A zip named .tar (Blender's installer wants a .zip), and a place it cannot write,
    are one line and exit 2 (they wrote a zip named .tar, and a traceback)."""
    from procmod.blender.package import main

    target = tmp_path / out
    if "none" in out:
        (tmp_path / "none").write_text("a file where a folder should be")
    assert main(["--out", str(target)]) == 2
    err = capsys.readouterr().err
    assert says in err and err.count("\n") == 1 and not target.exists()


def test_automatic_voxel_size_counts_the_margin_and_resolves_every_layer(tmp_path):
    """Voxel size 0 aimed at 40,000 voxels by the layers' box alone: a 100 x 100 floor 5 mm
    thick got a size whose two-voxel margin made 4.35 million voxels, refused with advice
    about a value the user never set; and a 2-unit cube on a 200-unit ground slab got a
    size of 1.27, so no voxel centre fell inside the cube."""
    _box_obj(tmp_path / "floor.obj", [-50, -50, 0], [50, 50, 0.005])
    spec = {"layers": [{"mesh": "floor.obj", "object": "Floor"}], "voxel_size": 0}
    written = json.loads(worker.build_volume_target(spec, tmp_path, tmp_path / "t1").read_text())
    lo, hi = np.array([-50, -50, 0]), np.array([50, 50, 0.005])
    count = worker._grid_voxels(written["voxel_size"], lo, hi)
    assert 0.5 * worker.AUTO_VOXELS <= count <= worker.AUTO_VOXELS  # about the aim, margin counted

    _box_obj(tmp_path / "ground.obj", [-100, -100, -1], [100, 100, 0])
    _box_obj(tmp_path / "cube.obj", [-1, -1, 0], [1, 1, 2])
    spec = {"layers": [{"mesh": "ground.obj", "object": "Ground", "w_fill": -1, "w_avoid": 0},
                       {"mesh": "cube.obj", "object": "Cube", "w_fill": 1, "w_avoid": 0}], "voxel_size": 0}
    target = load_target_file(worker.build_volume_target(spec, tmp_path, tmp_path / "t2"))
    # as fine as the voxel limit allows (8 across the cube would need ~10 million)
    assert target.grid.size == pytest.approx(worker._size_for(worker.MAX_VOXELS, [-100, -100, -1], [100, 100, 2]))
    assert (target.combined > 0).sum() >= 4 ** 3  # the cube is in the grid


def test_a_layer_under_two_voxels_is_told_in_the_panels_terms(tmp_path):
    _box_obj(tmp_path / "big.obj", [0, 0, 0], [10, 10, 10])
    _box_obj(tmp_path / "small.obj", [10.5, 0, 0], [11.3, 0.8, 0.8])
    spec = {"layers": [{"mesh": "big.obj", "object": "Big"}, {"mesh": "small.obj", "object": "Pebble"}],
            "voxel_size": 0.5}
    with pytest.raises(Exception) as info:
        worker.build_volume_target(spec, tmp_path, tmp_path / "t")
    message = str(info.value)
    assert "target layer 'Pebble'" in message and "Voxel size of 0.1 in the panel" in message
    assert "mesh_scale" not in message and "target.json" not in message
    # too small for its own 8 voxels within the limit, but automatic finds a size that holds it
    _box_obj(tmp_path / "huge.obj", [0, 0, 0], [100, 100, 100])
    _box_obj(tmp_path / "stone.obj", [101, 0, 0], [103, 2, 2])
    spec = {"layers": [{"mesh": "huge.obj", "object": "Huge"}, {"mesh": "stone.obj", "object": "Stone"}],
            "voxel_size": 1.5}
    with pytest.raises(Exception, match=r"target layer 'Stone' .*give a Voxel size of 0 in the panel \(automatic"):
        worker.build_volume_target(spec, tmp_path, tmp_path / "t2")


def test_a_target_files_message_names_the_layers_object_and_the_panels_field():
    spec = {"layers": [{"mesh": "a.obj", "object": "A", "w_fill": 1, "w_avoid": -1}]}
    said = worker._name_layers("/tmp/j/infer-ga-009.target/target.json: layers[0].file: no voxel centre of the grid "
                               "lies inside the mesh; use a smaller voxel_size, or close the mesh", spec)
    assert said == ("target layer 'A': no voxel centre of the grid lies inside the mesh; use a smaller Voxel size "
                    "(in the panel), or close the mesh")
    said = worker._name_layers("/tmp/j/t.target/target.json: layers[0].w_fill must be between -1e+06 and 1e+06", spec)
    assert said == "target layer 'A': its Inside weight must be between -1e+06 and 1e+06"
    # of the whole target (a Fill layer inside an Avoid one: nothing to fill)
    said = worker._name_layers("/tmp/j/t.target/target.json: nothing to fill: no voxel gains from being covered "
                               "(w_fill and w_avoid are 0 or less everywhere); give a layer a positive w_fill", spec)
    assert said.startswith("nothing to fill") and "target.json" not in said and "w_fill" not in said
    assert "Inside weight" in said


def test_one_sample_is_one_sample(tmp_path):
    status, result = _job(tmp_path, command="sample", model="spaceship", count=1)
    assert status == 0 and result["message"].startswith("1 sample of spaceship ")


def test_a_relative_or_home_python_is_made_absolute_for_the_workers_folder(tmp_path, monkeypatch):
    """A relative path was resolved from the job's temporary folder, where the worker starts:
    'cannot start the procmod worker with rel/python (No such file or directory)'."""
    (tmp_path / "rel").mkdir()
    (tmp_path / "rel" / "python").write_text(f"#!/bin/sh\nexec {sys.executable} \"$@\"\n")  # a link loses the venv
    (tmp_path / "rel" / "python").chmod(0o755)
    monkeypatch.chdir(tmp_path)
    monkeypatch.setenv("HOME", str(tmp_path))
    assert jobs.find_python("rel/python") == str(tmp_path / "rel" / "python")
    assert jobs.find_python("~/rel/python") == str(tmp_path / "rel" / "python")
    assert jobs.find_python("python3") == "python3"  # a bare name: the system's search path
    result = jobs.Job("sample", {"model": "spaceship", "count": 1}, jobs.find_python("rel/python"),
                      folder=tmp_path / "j").start().wait(timeout=120)
    assert result["ok"], result


def test_the_packager_stores_an_absolute_python_and_refuses_one_that_is_not_there(tmp_path, capsys, monkeypatch):
    import zipfile

    from procmod.blender.package import main
    (tmp_path / "rel").mkdir()
    (tmp_path / "rel" / "python").symlink_to(sys.executable)
    monkeypatch.chdir(tmp_path)
    assert main(["--out", "a.zip", "--python", "rel/python"]) == 0
    with zipfile.ZipFile(tmp_path / "a.zip") as archive:
        assert archive.read("procmod_blender/default_python.txt").decode().strip() == str(tmp_path / "rel" / "python")
    capsys.readouterr()
    assert main(["--out", "b.zip", "--python", "/nonexistent/python"]) == 2
    err = capsys.readouterr().err
    assert "is not a program" in err and err.count("\n") == 1 and not (tmp_path / "b.zip").exists()


def test_avoid_layers_alone_are_refused_in_the_panels_terms(tmp_path):
    # the target file's refusal ("nothing to fill") would name the job's temporary file
    _box_obj(tmp_path / "rock.obj", [0, 0, 0], [1, 1, 1])
    spec = {"layers": [{"mesh": "rock.obj", "object": "Rock", "w_fill": -2, "w_avoid": 0}], "voxel_size": 0.25}
    with pytest.raises(Exception, match=r"nothing to fill: no layer has a positive Inside or Outside weight \(Avoid "
                                        r"layers only\); add a mesh as Fill"):
        worker.build_volume_target(spec, tmp_path, tmp_path / "t")


def test_killing_a_job_whose_worker_had_ended_keeps_its_result_and_run(tmp_path):
    """A stopped Control run that no operator read any more (a file was opened) was killed
    at Blender's exit as if cancelled, deleting the run folder it had written (h137)."""
    stand_in = tmp_path / "python"  # stands in for "python -m procmod.blender.worker FOLDER"
    stand_in.write_text('#!/bin/sh\nfolder="$3"\nout=$(sed -n \'s/.*"out": "\\(.*\\)".*/\\1/p\' "$folder/job.json")\n'
                        'mkdir -p "$out" && echo best > "$out/best.json"\n'
                        'echo \'{"ok": true, "message": "stopped", "samples": []}\' > "$folder/result.json"\n')
    stand_in.chmod(0o755)
    out = tmp_path / "runs" / "infer-ga-001"
    job = jobs.Job("infer", {"out": str(out)}, str(stand_in)).start()
    job.process.wait(timeout=60)
    jobs._kill_running()  # what Blender's exit does to every job still listed
    assert job.result == {"ok": True, "message": "stopped", "samples": []}
    assert (out / "best.json").read_text() == "best\n"
    job.cleanup()
