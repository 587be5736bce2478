"""procmod.core.io: atomic writes, versioned JSON, tensor files; and the shared resampler."""

import os
import pickle
import shutil

import numpy as np
import pytest

from procmod.core.errors import ProcmodError, shown_value
from procmod.core.io import (load_tensors, open_atomic, read_versioned_json, save_tensors, write_bytes_atomic,
                             write_text_atomic)
from procmod.core.random import resample


class Refused(ProcmodError):
    pass


def test_a_writer_that_raises_leaves_the_old_file_and_no_temporary(tmp_path):
    path = tmp_path / "state.json"
    path.write_text("old\n")
    with pytest.raises(RuntimeError, match="killed"):
        with open_atomic(path, "w") as handle:
            handle.write("half of the new")
            raise RuntimeError("killed mid-write")
    assert path.read_text() == "old\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["state.json"]

    new = tmp_path / "new.bin"  # a file that did not exist stays absent
    with pytest.raises(KeyboardInterrupt):
        with open_atomic(new) as handle:
            handle.write(b"\x00" * 1000)
            raise KeyboardInterrupt
    assert sorted(p.name for p in tmp_path.iterdir()) == ["state.json"]


def test_atomic_writes_replace_whole_with_the_usual_permissions(tmp_path):
    path = tmp_path / "a.txt"
    write_text_atomic(path, "één\n")
    write_text_atomic(path, "two\n", fsync=True)
    assert path.read_text(encoding="utf-8") == "two\n"
    write_bytes_atomic(tmp_path / "b.bin", b"\x01\x02")
    assert (tmp_path / "b.bin").read_bytes() == b"\x01\x02"
    mask = os.umask(0)
    os.umask(mask)
    assert (path.stat().st_mode & 0o777) == 0o666 & ~mask  # not mkstemp's 0600
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.txt", "b.bin"]


def test_tensors_round_trip_atomically(tmp_path):
    import torch

    state = {"w": torch.arange(6.0).reshape(2, 3), "step": 3, "history": [1.5, 2.0]}
    save_tensors(state, tmp_path / "t.pt")
    back = load_tensors(tmp_path / "t.pt", Refused)
    assert torch.equal(back["w"], state["w"]) and back["step"] == 3 and back["history"] == [1.5, 2.0]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["t.pt"]


class Payload:
    """A pickled object: unpickling it could run code, so load_tensors must refuse it."""

    def __reduce__(self):
        return (os.getcwd, ())


def test_load_tensors_refuses_a_pickle_in_one_line(tmp_path):
    import torch

    path = tmp_path / "evil.pt"
    torch.save({"w": torch.zeros(2), "x": Payload()}, path)
    with pytest.raises(Refused, match="evil.pt: refused to load the weights: the file holds Python objects") as info:
        load_tensors(path, Refused, "weights", "; use one procmod wrote")
    assert "\n" not in str(info.value) and str(info.value).endswith("; use one procmod wrote")

    (tmp_path / "plain.pkl").write_bytes(pickle.dumps(Payload(), protocol=2))  # not even a torch file
    with pytest.raises(Refused, match=r"refused to load the tensors: .* \(GLOBAL \w+\.getcwd\)") as info:
        load_tensors(tmp_path / "plain.pkl", Refused)
    assert "\n" not in str(info.value)

    (tmp_path / "garbage.pt").write_text("not a torch file\n")
    with pytest.raises(Refused, match=r"garbage.pt: cannot read the tensors \(") as info:
        load_tensors(tmp_path / "garbage.pt", Refused)
    assert "\n" not in str(info.value)
    with pytest.raises(Refused, match="cannot read"):
        load_tensors(tmp_path / "missing.pt", Refused)


def test_read_versioned_json_names_the_file_and_the_format(tmp_path):
    path = tmp_path / "job.json"
    path.write_text('{"format": "procmod-x/1", "n": 2}')
    assert read_versioned_json(path, "procmod-x/1", Refused) == {"format": "procmod-x/1", "n": 2}
    with pytest.raises(Refused, match=r'job.json: format is "procmod-x/1", expected "procmod-x/2"; rerun$'):
        read_versioned_json(path, "procmod-x/2", Refused, advice="; rerun")
    path.write_text("[1, 2]")
    with pytest.raises(Refused, match=r'expected a JSON object with "format": "procmod-x/1", got \[1, 2\]$'):
        read_versioned_json(path, "procmod-x/1", Refused)
    # what the file says, as JSON (not Python's None or True), or that it says nothing
    path.write_text('{"n": 2}')
    with pytest.raises(Refused, match=r'job.json: has no "format", expected "procmod-x/1"$'):
        read_versioned_json(path, "procmod-x/1", Refused)
    path.write_text('{"format": true}')
    with pytest.raises(Refused, match=r'job.json: format is true, expected "procmod-x/1"$'):
        read_versioned_json(path, "procmod-x/1", Refused)
    path.write_text("[" * 100_000)
    with pytest.raises(Refused, match=r"job.json: JSON nested too deeply .*; rerun$"):
        read_versioned_json(path, "procmod-x/1", Refused, advice="; rerun")
    with pytest.raises(Refused, match="does not exist"):
        read_versioned_json(tmp_path / "none.json", "procmod-x/1", Refused)


def test_a_key_given_twice_is_refused_not_silently_the_last(tmp_path):
    # an examples file with two "wing" parts learned from the second one without a word
    from procmod.learn import ExamplesError, read_examples

    path = tmp_path / "examples.json"
    path.write_text('{"format": "procmod-examples/1", "parts": {"wing": {"box": [1, 1, 1]}, '
                    '"wing": {"box": [2, 1, 1]}}, "examples": [{"part": "wing", "transform": '
                    '[[1,0,0,0],[0,1,0,0],[0,0,1,0],[0,0,0,1]], "children": []}]}')
    with pytest.raises(ExamplesError, match=r"examples.json: the key 'wing' appears twice in one object "
                       r"\(values \{\"box\": \[1, 1, 1\]\} and \{\"box\": \[2, 1, 1\]\}\); keep one"):
        read_examples(path)
    path.write_text('{"format": "procmod-x/1", "a": {"n": 1, "m": 2}, "b": [{"n": 1}, {"n": 2}]}')
    assert read_versioned_json(path, "procmod-x/1", Refused)["b"] == [{"n": 1}, {"n": 2}]  # same key, two objects


def _learn_resample_before(objectives, rng):
    """learn.search._resample's indices as written before it used core.random.resample."""
    scores = np.array(objectives)
    w = np.exp(scores - scores.max())
    w /= w.sum()
    n = len(objectives)
    positions = (rng.random() + np.arange(n)) / n
    return np.minimum(np.searchsorted(np.cumsum(w), positions), n - 1)


class _Program:
    def copy(self):
        return _Program()


def test_learns_resampler_gives_the_indices_it_gave_before():
    from procmod.learn.search import Particle, _resample

    cases = []
    for seed in range(300):
        rng = np.random.default_rng(seed)
        n = int(rng.integers(2, 40))
        objectives = rng.normal(0.0, [0.1, 3.0, 50.0][seed % 3], n) - 1000.0
        if seed % 5 == 0:
            objectives[: n // 2] = objectives[0]  # ties: copies of one particle
        if seed % 7 == 0:
            objectives[:] = -3.0  # all equal
        cases.append(objectives.tolist())
    for seed, objectives in enumerate(cases):
        before = _learn_resample_before(objectives, np.random.default_rng([seed, 1]))
        rng = np.random.default_rng([seed, 1])
        now = resample(np.array(objectives), rng, "systematic")
        assert now.tolist() == before.tolist(), seed
        # and the search's own wrapper, which also copies the repeated particles
        particles = [Particle(program=_Program(), objective=o, loglik=o, usage={}, queue=[], rejected=[], done=False,
                              trace=[]) for o in objectives]
        kept, chosen = _resample(particles, np.random.default_rng([seed, 1]))
        assert chosen == before.tolist()
        assert [p.objective for p in kept] == [objectives[i] for i in chosen]
        # both drew one uniform: the generators are left in the same state
        assert rng.random() == np.random.default_rng([seed, 1]).random(2)[1]


def test_values_in_messages_read_as_the_user_wrote_them():
    """A value from a file shows as JSON (``null``, ``true``, ``"x"``); anything else as its
    repr; a long one cut, without dumping all of a huge list first."""
    assert shown_value(None) == "null" and shown_value(True) == "true" and shown_value("wing") == '"wing"'
    assert shown_value([1, 2.5, {"a": None}]) == '[1, 2.5, {"a": null}]'
    assert shown_value(np.float32(0.5)) == "0.5" and shown_value(np.int64(3)) == "3"
    assert shown_value(float("nan")) == "NaN" and shown_value(object).startswith("<class")
    assert shown_value("x" * 100_000) == '"' + "x" * 56 + "..."
    assert shown_value(list(range(10 ** 6)), 30) == "[0, 1, 2, 3, 4, 5, 6, 7, 8,..."


def test_json_files_with_a_byte_order_mark_or_of_absurd_size(tmp_path, monkeypatch):
    """A BOM (Windows editors) was "not valid JSON"; a huge file was read whole (a traceback
    of MemoryError)."""
    import procmod.core.io as io_module

    path = tmp_path / "job.json"
    path.write_bytes(b'\xef\xbb\xbf{"format": "procmod-x/1"}\r\n')
    assert read_versioned_json(path, "procmod-x/1", Refused) == {"format": "procmod-x/1"}
    monkeypatch.setattr(io_module, "MAX_JSON_BYTES", 10)
    with pytest.raises(Refused, match=r"job.json is 30 B, more than procmod reads as JSON \(10 B\)"):
        read_versioned_json(path, "procmod-x/1", Refused)


def test_a_name_near_the_file_systems_limit_is_written_whole(tmp_path):
    """The hidden temporary beside a file or run folder (``.NAME.XXXXXXXX.tmp``) is 14
    bytes longer than NAME: a name the file system takes was refused because of it."""
    from procmod.core.runfolder import SAMPLE_RUN, RunFolder

    name_max = os.pathconf(tmp_path, "PC_NAME_MAX")
    for name in ("a" * name_max, "é" * (name_max // 2)):  # bytes, not characters, are counted
        path = tmp_path / name
        write_text_atomic(path, "whole\n")
        assert path.read_text() == "whole\n"
        path.unlink()

        folder = RunFolder(tmp_path / name[:-1], SAMPLE_RUN)
        with folder.writing() as out:
            (out / "summary.json").write_text("{}")
        with RunFolder(tmp_path / name[:-1], SAMPLE_RUN, overwrite=True).writing() as out:  # replaced: .old
            (out / "summary.json").write_text('{"again": 1}')
        assert (tmp_path / name[:-1] / "summary.json").read_text() == '{"again": 1}'
        assert sorted(p.name for p in tmp_path.iterdir()) == [name[:-1]]  # no temporary left
        shutil.rmtree(tmp_path / name[:-1])
