"""Run folders (issue 28.3): an --out folder is replaced whole or refused, never mixed; a
failure leaves nothing half-written (procmod.core.runfolder and the commands using it)."""

import json
import os
from pathlib import Path

import pytest

import procmod.infer
from procmod.cli import main
from procmod.core.runfolder import INFER_RUN, SAMPLE_RUN, OutputLocationError, RunFolder

ROOT = Path(__file__).resolve().parents[1]

SETS = Path(__file__).resolve().parents[1] / "examples_sets" / "strings"


def _run(capsys, *argv):
    code = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return code, out, err


def _names(folder):
    return sorted(p.name for p in Path(folder).iterdir())


def test_sample_into_an_earlier_sample_folder_replaces_it_whole(tmp_path, capsys):
    out = tmp_path / "s"
    assert _run(capsys, "sample", "chain", "-n", "16", "--size", "16", "--out", out)[0] == 0
    assert _run(capsys, "sample", "chain", "-n", "4", "--size", "16", "--out", out)[0] == 0
    # the 16-sample run's sample_004..015 are gone, not kept beside the 4 new ones
    assert _names(out) == sorted(["contact_sheet.png"] + [f"sample_{i:03d}.{e}" for i in range(4)
                                                          for e in ("json", "png", "svg")])
    assert _names(tmp_path) == ["s"]  # no temporary folder left beside it


def test_infer_into_an_earlier_run_keeps_nothing_of_it(tmp_path, capsys):
    out = tmp_path / "run"
    code, _, err = _run(capsys, "infer", "vines", "--target", "glyph:a", "--particles", "8", "--size", "32",
                        "--out", out)
    assert code == 0, err
    assert (out / "target.png").exists() and (out / "best.svg").exists()
    # a circuit run writes no target.png and a 3D-less model no .svg: the old ones must go
    code, _, err = _run(capsys, "infer", "lightning", "--target", "circuit", "--particles", "4", "--size", "32",
                        "--out", out)
    assert code == 0, err
    assert not (out / "target.png").exists()
    assert "circuit" in json.loads((out / "settings.json").read_text())["target"]
    assert "target.png" not in (out / "report.html").read_text()


def test_a_folder_that_is_not_an_earlier_run_is_refused_unless_overwrite(tmp_path, capsys):
    out = tmp_path / "mine"
    out.mkdir()
    (out / "notes.txt").write_text("keep me")
    for argv in (["sample", "chain", "-n", "2", "--size", "16"],
                 ["infer", "chain", "--target", "glyph:a", "--particles", "4", "--size", "32"]):
        code, _, err = _run(capsys, *argv, "--out", out)
        assert code == 2 and err.count("\n") == 1 and "--overwrite" in err and "notes.txt" in err, err
        assert _names(out) == ["notes.txt"]
    # an infer run is not a sample folder: refused too, named
    run = tmp_path / "run"
    assert _run(capsys, "infer", "chain", "--target", "glyph:a", "--particles", "4", "--size", "32",
                "--out", run)[0] == 0
    code, _, err = _run(capsys, "sample", "chain", "-n", "2", "--size", "16", "--out", run)
    assert code == 2 and "not an earlier procmod sample folder" in err
    # --overwrite replaces it whole
    assert _run(capsys, "sample", "chain", "-n", "2", "--size", "16", "--out", out, "--overwrite")[0] == 0
    assert "notes.txt" not in _names(out) and "contact_sheet.png" in _names(out)


def test_overwrite_never_deletes_an_input_or_the_current_folder(tmp_path, capsys, monkeypatch):
    scene = tmp_path / "scene"
    scene.mkdir()
    import shutil
    shutil.copy(Path(__file__).resolve().parents[1] / "scenes" / "spaceship_volume" / "target.json",
                scene / "target.json")
    for extra in (Path(__file__).resolve().parents[1] / "scenes" / "spaceship_volume").iterdir():
        if extra.name != "target.json":
            shutil.copy(extra, scene / extra.name)
    code, _, err = _run(capsys, "infer", "spaceship", "--target", scene, "--engine", "ga", "--population", "4",
                        "--budget", "1gens", "--out", scene, "--overwrite")
    assert code == 2 and "holds the input" in err, err
    assert (scene / "target.json").exists()
    monkeypatch.chdir(scene)
    code, _, err = _run(capsys, "sample", "chain", "-n", "1", "--out", ".", "--overwrite")
    assert code == 2 and "current folder" in err
    assert (scene / "target.json").exists()


def test_a_mirrored_picture_is_an_input_overwrite_keeps(tmp_path, capsys):
    """``--target drawings/cat.png:mirrored --out drawings --overwrite`` deleted the
    picture (the spec, as given, names no file) and everything beside it."""
    from PIL import Image, ImageDraw
    drawings = tmp_path / "drawings"
    drawings.mkdir()
    picture = Image.new("RGB", (120, 120), "white")
    ImageDraw.Draw(picture).line([(60, 115), (55, 20)], fill="black", width=16)
    picture.save(drawings / "cat.png")
    for target in (drawings / "cat.png", f"{drawings / 'cat.png'}:mirrored"):
        code, _, err = _run(capsys, "infer", "vines", "--target", target, "--particles", "2", "--out", drawings,
                            "--overwrite")
        assert code == 2 and "holds the input" in err and (drawings / "cat.png").exists(), err


def test_a_dangling_link_as_out_is_refused_before_the_work(tmp_path, capsys):
    """A symbolic link to nothing passed the checks, then the run's last rename failed on
    it with a traceback, the whole run lost."""
    (tmp_path / "run").symlink_to(tmp_path / "nowhere")
    code, _, err = _run(capsys, "infer", "vines", "--target", "glyph:a", "--particles", "2", "--out",
                        tmp_path / "run")
    assert code == 2 and err.count("\n") == 1 and "is a symbolic link to" in err and "does not exist" in err, err


def test_a_run_in_the_current_folder_interrupted_leaves_nothing_and_a_full_one_says_what_works(tmp_path, capsys,
                                                                                               monkeypatch):
    """--out . was written into directly: Ctrl-C while writing left a half-written run, and
    the refusal of a second run then advised --overwrite, which is refused for the current
    folder."""
    monkeypatch.chdir(tmp_path)
    folder = RunFolder(".", INFER_RUN)
    with pytest.raises(KeyboardInterrupt):
        with folder.writing() as out:
            (out / "best.json").write_text("{}")
            raise KeyboardInterrupt
    assert list(tmp_path.iterdir()) == []
    with RunFolder(".", INFER_RUN).writing() as out:
        (out / "best.json").write_text("{}")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["best.json"]
    code, _, err = _run(capsys, "sample", "chain", "-n", "1", "--out", ".")
    assert code == 2 and "holds the current folder, which cannot be replaced: give a new folder" in err, err
    assert "--overwrite" not in err


def test_a_failure_while_writing_leaves_the_earlier_run_and_no_temporary_folder(tmp_path, capsys, monkeypatch):
    out = tmp_path / "s"
    assert _run(capsys, "sample", "chain", "-n", "3", "--size", "16", "--out", out)[0] == 0
    before = {p.name: p.read_bytes() for p in out.iterdir()}
    import procmod.render

    def broken(*args, **kwargs):
        raise KeyboardInterrupt  # a failure half way through writing the new run

    monkeypatch.setattr(procmod.render, "write_contact_sheet", broken)
    assert _run(capsys, "sample", "chain", "-n", "5", "--size", "16", "--out", out)[0] == 130
    assert {p.name: p.read_bytes() for p in out.iterdir()} == before
    assert _names(tmp_path) == ["s"]


def _read_only(monkeypatch, folder):
    """Make ``folder`` act read-only to procmod.core.runfolder, as it does to a user who
    is not root (tests may run as root, whom chmod does not stop)."""
    import procmod.core.runfolder as runfolder

    folder = Path(folder).resolve()
    real_mkdtemp, real_rename = runfolder.tempfile.mkdtemp, runfolder.os.rename

    def inside(path):
        return path is not None and Path(path).resolve().is_relative_to(folder)

    def mkdtemp(*args, dir=None, **kwargs):
        if inside(dir):
            raise PermissionError(13, "Permission denied")
        return real_mkdtemp(*args, dir=dir, **kwargs)

    def rename(src, dst):
        if Path(src).resolve() == folder:  # moving a folder to another parent rewrites its ".."
            raise PermissionError(13, "Permission denied")
        return real_rename(src, dst)

    monkeypatch.setattr(runfolder.tempfile, "mkdtemp", mkdtemp)
    monkeypatch.setattr(runfolder.os, "rename", rename)


@pytest.mark.parametrize("command", [["sample", "chain", "-n", "2", "--size", "16"],
                                     ["infer", "chain", "--target", "glyph:a", "--particles", "5", "--size", "16"]])
def test_a_read_only_out_folder_is_refused_before_the_work(tmp_path, capsys, monkeypatch, command):
    out = tmp_path / "earlier"
    assert _run(capsys, *command, "--out", out)[0] == 0
    before = {p.name: p.read_bytes() for p in out.iterdir()}
    _read_only(monkeypatch, out)
    ran = []
    monkeypatch.setitem(procmod.infer.ENGINES, "smc", lambda *a, **k: ran.append(1))  # infer's default
    code, _, err = _run(capsys, *command, "--out", out)
    assert code == 2 and err.count("\n") == 1 and f"cannot create files in {out}" in err and "writable" in err
    assert not ran  # refused at the start, not after the engine ran
    assert {p.name: p.read_bytes() for p in out.iterdir()} == before
    assert _names(tmp_path) == ["earlier"]  # no hidden .old or .tmp folder left


def test_a_link_to_a_read_only_earlier_job_that_resumes_through_it_is_refused(tmp_path, monkeypatch):
    """A link --out is replaced, not its target; but a resumable job writes through a link
    to its earlier run, so that target must be writable."""
    from procmod.core.runfolder import TRACES_JOB

    earlier = tmp_path / "traces"
    earlier.mkdir()
    (earlier / "traces.json").write_text(json.dumps({"format": "procmod-traces/1", "model": "vines"}))
    (tmp_path / "link").symlink_to(earlier)
    _read_only(monkeypatch, earlier)
    with pytest.raises(OutputLocationError, match="cannot create files in"):
        RunFolder(tmp_path / "link", TRACES_JOB)
    RunFolder(tmp_path / "other_link_target_free", TRACES_JOB)  # a new folder: nothing to probe through


def test_a_folder_made_read_only_during_the_run_is_one_error_leaving_it_whole(tmp_path, monkeypatch):
    out = tmp_path / "run"
    with RunFolder(out, SAMPLE_RUN).writing() as tmp:
        (tmp / "contact_sheet.png").write_bytes(b"x")
    folder = RunFolder(out, SAMPLE_RUN)
    import procmod.core.runfolder as runfolder

    real_rename = runfolder.os.rename

    def rename(src, dst):
        if Path(src).resolve() == out.resolve():
            raise PermissionError(13, "Permission denied")
        return real_rename(src, dst)

    monkeypatch.setattr(runfolder.os, "rename", rename)
    with pytest.raises(OutputLocationError, match="cannot replace .*Permission denied; make it writable"):
        with folder.writing() as tmp:
            (tmp / "contact_sheet.png").write_bytes(b"y")
    assert (out / "contact_sheet.png").read_bytes() == b"x" and _names(tmp_path) == ["run"]


def test_run_folder_replacement_is_whole_and_parents_are_made(tmp_path):
    target = tmp_path / "a" / "b" / "run"
    folder = RunFolder(target, SAMPLE_RUN)
    assert not (tmp_path / "a").exists()  # checking creates nothing
    with folder.writing() as tmp:
        assert tmp.parent == target.parent and tmp.name.startswith(".run.")
        (tmp / "contact_sheet.png").write_bytes(b"x")
        (tmp / "sample_000.json").write_text("{}")
    assert _names(target) == ["contact_sheet.png", "sample_000.json"]
    with RunFolder(target, SAMPLE_RUN).writing() as tmp:  # an earlier run: replaced
        (tmp / "contact_sheet.png").write_bytes(b"y")
    assert _names(target) == ["contact_sheet.png"] and _names(target.parent) == ["run"]
    # a failure in the block removes the new folder and the parents it made
    with pytest.raises(RuntimeError):
        with RunFolder(tmp_path / "c" / "d" / "run", SAMPLE_RUN).writing() as tmp:
            (tmp / "x").write_text("half")
            raise RuntimeError("boom")
    assert not (tmp_path / "c").exists()


def test_run_kinds_recognise_only_their_own_folders(tmp_path):
    run = tmp_path / "run"
    run.mkdir()
    (run / "settings.json").write_text(json.dumps({"engine": "smc"}))
    (run / "report.html").write_text("")
    assert INFER_RUN.recognises(run) and not SAMPLE_RUN.recognises(run)
    (run / "settings.json").write_text(json.dumps({"something": "else"}))
    assert not INFER_RUN.recognises(run)  # the marker must be procmod's
    (run / "settings.json").write_text(json.dumps({"engine": "smc"}))
    (run / "thesis.tex").write_text("")
    assert not INFER_RUN.recognises(run)  # a file the command never writes
    with pytest.raises(OutputLocationError, match="overwrite=True"):  # the API's argument, not the flag
        RunFolder(run, INFER_RUN)


def test_library_messages_name_api_arguments_and_the_command_line_its_flags(tmp_path, capsys):
    """Issue 27.6: the same check reads ``out`` / ``overwrite=True`` from Python and
    ``--out`` / ``--overwrite`` from the shell."""
    from procmod.core.runfolder import check_output_file
    from procmod.learn import learn
    from procmod.parallel import SchedulerError, check_scheduler

    taken = tmp_path / "taken"
    taken.mkdir()
    (taken / "notes.txt").write_text("mine")
    with pytest.raises(OutputLocationError) as python:
        RunFolder(taken, SAMPLE_RUN)
    assert "out " in str(python.value) and "overwrite=True" in str(python.value) and "--" not in str(python.value)
    code, _, err = _run(capsys, "sample", "chain", "-n", "1", "--size", "16", "--out", taken)
    assert code == 2 and "--out " in err and "--overwrite" in err and "overwrite=True" not in err
    with pytest.raises(OutputLocationError, match=r"^out .* is a folder; give a file name"):
        check_output_file(taken)
    with pytest.raises(SchedulerError, match=r"^scheduler 'nowhere' is not a dask scheduler address"):
        check_scheduler("nowhere")
    with pytest.raises(Exception, match=r"^out .* exists and is not a folder"):
        learn(tmp_path / "missing.json", taken / "notes.txt")
    assert _names(taken) == ["notes.txt"]
    # the command line rewords what only it can say: its --format option
    code, _, err = _run(capsys, "sample", "spaceship", "--format", "examples", "--out", tmp_path / "x.json")
    assert code == 2 and "not a learned program; '--format examples' writes samples" in err


def test_a_front_end_spells_api_arguments_within_its_block_only():
    from procmod.core.errors import argument, spelled

    assert argument("out") == "out"
    with spelled({"out": "--out"}):
        assert argument("out") == "--out" and argument("seed") == "seed"
        with spelled({"seed": "--seed"}):  # nested blocks add to the outer spelling
            assert (argument("out"), argument("seed")) == ("--out", "--seed")
        assert argument("seed") == "seed"
    assert argument("out") == "out"


def test_guide_traces_refuses_another_job_leaving_it_and_overwrite_replaces_it(tmp_path, capsys):
    out = tmp_path / "traces"
    argv = ["guide", "traces", "lightning", "--count", "1", "--particles", "5", "--workers", "1", "--out", out]
    assert _run(capsys, *argv)[0] == 0
    first = {p.name: p.read_bytes() for p in out.iterdir()}
    code, _, err = _run(capsys, *argv[:-2], "--seed", "4", "--out", out)
    assert code == 2 and "another job" in err and "--overwrite" in err
    assert {p.name: p.read_bytes() for p in out.iterdir()} == first
    assert _run(capsys, *argv[:-2], "--seed", "4", "--out", out, "--overwrite")[0] == 0
    assert json.loads((out / "traces.json").read_text())["seed"] == 4
    other = tmp_path / "other"
    other.mkdir()
    (other / "notes.txt").write_text("")
    code, _, err = _run(capsys, *argv[:-1], other)
    assert code == 2 and "--overwrite" in err and _names(other) == ["notes.txt"]
    # a damaged traces.json: said so (it read as a stranger's folder holding 'trace_00000.json')
    (out / "traces.json").write_text('{"format": "procmod-guide')
    code, _, err = _run(capsys, *argv)
    assert code == 2 and "is an earlier procmod guide traces folder whose traces.json is damaged" in err, err
    assert "restore it to resume, or pass --overwrite" in err


def test_guide_traces_that_fails_before_its_first_trace_leaves_nothing(tmp_path, capsys, monkeypatch):
    import procmod.guide.traces as traces

    def broken(*args, **kwargs):
        raise procmod.core.InvalidArgumentError("the first trace failed")

    monkeypatch.setattr(traces, "generate_trace", broken)
    code, _, err = _run(capsys, "guide", "traces", "lightning", "--count", "2", "--particles", "5",
                        "--workers", "1", "--out", tmp_path / "t")
    assert code == 2 and "the first trace failed" in err
    assert _names(tmp_path) == []  # no traces.json left behind


def test_strings_augment_into_an_earlier_collection_replaces_it_whole(tmp_path, capsys):
    out = tmp_path / "col"
    base = ["strings", "augment", SETS / "moonbase.json", "--rounds", "30", "--seed", "2", "--out", out]
    assert _run(capsys, *base, "--count", "10")[0] == 0
    assert _run(capsys, *base[:-2], "--count", "4", "--out", out)[0] == 0
    shapes = json.loads((out / "shapes.json").read_text())
    graphs = _names(out / "graphs")
    assert len(graphs) == len(shapes["shapes"]) <= 4  # no graph of the 10-shape collection is left


def test_strings_graph_into_a_folder_of_more_graphs_replaces_it(tmp_path, capsys):
    out = tmp_path / "g"
    out.mkdir()
    for i in range(5):
        (out / f"shape_{i:03d}.json").write_text("{}")
    assert _run(capsys, "strings", "graph", SETS / "castle.json", "--out", out)[0] == 0
    made = _names(out)
    assert made == [f"shape_{i:03d}.json" for i in range(len(made))] and len(made) < 5
    assert all(json.loads((out / n).read_text()).get("format") == "procmod-graph/1" for n in made)


def test_only_a_traces_folder_is_resumed_past_files_it_does_not_write(tmp_path):
    """A traces job resumes past the user's files beside its traces; a learn or strings
    folder, whose marker is a bare name (a TensorFlow folder holds a `checkpoint` file, an
    API export a `collection.json`), is still someone else's folder when it holds more."""
    from procmod.core.runfolder import LEARN_RUN, STRINGS_MODEL, TRACES_JOB

    for kind, marker, text in ((LEARN_RUN, "checkpoint", 'model_checkpoint_path: "model.ckpt-1000"\n'),
                               (STRINGS_MODEL, "collection.json", '{"item": []}'),
                               (TRACES_JOB, "traces.json", '{"format": "procmod-traces/1"}')):
        folder = tmp_path / marker
        folder.mkdir()
        (folder / marker).write_text(text)
        (folder / "notes.txt").write_text("mine")
        assert kind.recognises(folder) == (kind is TRACES_JOB)
        if kind is not TRACES_JOB:
            with pytest.raises(OutputLocationError, match="is not empty and not an earlier"):
                RunFolder(folder, kind)
            RunFolder(folder, kind, overwrite=True).prepare_in_place(keep=True)  # --overwrite: replaced whole
            assert list(folder.iterdir()) == []


def test_a_learned_programs_samples_written_in_the_current_folder_name_the_program_rightly(tmp_path, capsys,
                                                                                            monkeypatch):
    """A derivation names its learned program relative to its own folder: written in place,
    it must be written where it stays (a hidden folder one level down had put a '../' too
    many in every reference)."""
    examples = {"format": "procmod-examples/1", "parts": {"base": {"box": [1, 1, 1]}, "cap": {"box": [0.5, 0.2, 0.5]}},
                "examples": [{"part": "base", "transform": [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]],
                              "children": [{"part": "cap", "transform": [[1, 0, 0, 0], [0, 1, 0, h], [0, 0, 1, 0],
                                                                          [0, 0, 0, 1]], "children": []}]}
                             for h in (0.6, 0.7, 0.65)]}
    (tmp_path / "examples.json").write_text(json.dumps(examples))
    assert _run(capsys, "learn", tmp_path / "examples.json", "--out", tmp_path / "program", "--particles", "1",
                "--workers", "1", "--samples", "1")[0] == 0
    here = tmp_path / "here"
    here.mkdir()
    monkeypatch.chdir(here)
    assert _run(capsys, "sample", tmp_path / "program", "-n", "1", "--out", ".")[0] == 0
    code, _, err = _run(capsys, "render", "sample_000.json", "--out", "again.png")
    assert code == 0, err


def test_an_empty_out_or_one_under_a_link_to_nothing_is_refused_before_the_work(tmp_path, capsys, monkeypatch):
    # --out "$UNSET" wrote the samples into the current folder; an --out under a dangling
    # link (or a loop of links) failed with a FileExistsError traceback after the work
    monkeypatch.chdir(tmp_path)
    code, _, err = _run(capsys, "sample", "vines", "-n", "1", "--size", "32", "--out", "")
    assert code == 2 and "--out is empty" in err and list(tmp_path.iterdir()) == []
    (tmp_path / "dangling").symlink_to(tmp_path / "nowhere")
    (tmp_path / "loopA").symlink_to(tmp_path / "loopB")
    (tmp_path / "loopB").symlink_to(tmp_path / "loopA")
    for parent in ("dangling", "loopA"):
        code, _, err = _run(capsys, "sample", "vines", "-n", "1", "--size", "32", "--out", tmp_path / parent / "x")
        assert code == 2 and "a symbolic link to" in err and "Traceback" not in err, err


def test_a_deleted_current_folder_does_not_stop_replacing_a_run(tmp_path, capsys, monkeypatch):
    # Path.cwd() raised FileNotFoundError (a traceback) once the folder the shell was in was removed
    out = tmp_path / "run"
    assert _run(capsys, "sample", "vines", "-n", "1", "--size", "32", "--out", out)[0] == 0
    gone = tmp_path / "gone"
    gone.mkdir()
    monkeypatch.chdir(gone)
    gone.rmdir()
    code, _, err = _run(capsys, "sample", "vines", "-n", "1", "--size", "32", "--out", out)
    assert code == 0, err


def test_a_full_disk_is_one_line(tmp_path, capsys, monkeypatch):
    import errno

    import procmod.report
    def full(*args, **kwargs):
        raise OSError(errno.ENOSPC, "No space left on device", str(tmp_path / "run" / "report.html"))
    monkeypatch.setattr(procmod.report, "write_text_atomic", full)
    code, _, err = _run(capsys, "infer", "vines", "--target", "glyph:a", "--particles", "3", "--size", "32", "--out",
                        tmp_path / "run")
    assert code == 2 and "No space left on device; free some space, or give --out elsewhere" in err, err
    assert err.count("\n") == 1 and not (tmp_path / "run").exists()


def test_a_file_over_the_size_limit_is_one_line(tmp_path):
    """ulimit -f (or FAT32's 4 GiB) fails a write with EFBIG: a traceback from the mesh export."""
    import subprocess
    import sys

    done = subprocess.run(["bash", "-c", f"ulimit -f 20; exec {sys.executable} -m procmod sample spaceship -n 3 --out u"],
                          stderr=subprocess.PIPE, text=True, cwd=tmp_path, env={**os.environ, "PYTHONPATH": str(ROOT)})
    assert done.returncode == 2 and "File too large" in done.stderr and done.stderr.count("\n") == 1, done.stderr
    assert not (tmp_path / "u").exists()


def test_a_full_printed_output_is_one_line_that_does_not_name_a_missing_option(tmp_path):
    # procmod models > /dev/full: the advice had been to give --out elsewhere, an option it has not
    import subprocess
    import sys

    if not Path("/dev/full").exists():
        pytest.skip("no /dev/full on this system")
    with open("/dev/full", "w") as full:
        done = subprocess.run([sys.executable, "-m", "procmod", "models"], stdout=full, stderr=subprocess.PIPE,
                              text=True, cwd=tmp_path, env={**os.environ, "PYTHONPATH": str(ROOT)})
    assert done.returncode == 2 and "--out" not in done.stderr and "Traceback" not in done.stderr, done.stderr
    assert done.stderr.count("\n") == 1 and "send the printed output elsewhere" in done.stderr


def test_a_file_name_of_bytes_that_are_not_utf8_is_written_not_a_traceback(tmp_path):
    # b"\xff" in a name reaches text as a lone surrogate: report.html, the printed summary and
    # a user model's module name failed with UnicodeEncodeError
    import os
    import shutil
    import subprocess
    import sys
    odd = b"r\xff"
    example = Path(__file__).resolve().parents[1] / "examples" / "custom_model.py"
    shutil.copy(example, os.path.join(os.fsencode(tmp_path), odd + b".py"))
    env = dict(os.environ, PYTHONPATH=str(Path(__file__).resolve().parents[1]))
    for argv in ([b"infer", b"vines", b"--target", b"glyph:a", b"--particles", b"3", b"--size", b"32", b"--out", odd],
                 [b"sample", odd + b".py", b"-n", b"1", b"--size", b"32", b"--out", b"m"]):
        run = subprocess.run([os.fsencode(sys.executable), b"-m", b"procmod", *argv], cwd=tmp_path, env=env,
                             capture_output=True, timeout=300)
        assert run.returncode == 0, run.stderr.decode("utf-8", "replace")[-2000:]
    assert os.path.isfile(os.path.join(os.fsencode(tmp_path), odd, b"report.html"))
