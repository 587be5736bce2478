"""The vines bench's similarity summaries: seed 004's Fig. 5 measure (per-target medians
averaged over targets), the guided-against-WebPPL difference on shared runs, and the
Fig. 5b times by either measure."""

import importlib.util
import json
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def bench():
    spec = importlib.util.spec_from_file_location("_bench_vs_webppl", ROOT / "bench" / "vs_webppl.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _row(system, n, target, seed, similarity, seconds=0.1):
    return {"set": "s", "system": system, "method": "SMC" if system == "webppl" else "smc", "n": n,
            "target": target, "seed": seed, "similarity": similarity, "seconds": seconds,
            "beyond_seconds": seconds, "infer_seconds": seconds}


def test_interval_resamples_targets(bench):
    # one target far from five alike: a draw without it (probability (5/6)^6 = 0.33) has
    # mean 0, one with it twice or more (probability 0.26) has mean 0.1 or more
    point, low, high = bench.mean_over_targets([0.3, 0, 0, 0, 0, 0], np.random.default_rng(0))
    assert point == pytest.approx(0.05)
    assert low == 0.0 and high >= 0.1
    with pytest.raises(ValueError):
        bench.mean_over_targets([], np.random.default_rng(0))


def test_summary_gives_the_mean_of_per_target_medians_not_the_pooled_median(bench):
    # one hard target among easy ones: the pooled median hides it, Fig. 5's measure does not
    runs = {"hard": [0.1, 0.12, 0.08, 0.1], "easy1": [0.8, 0.82, 0.79, 0.8], "easy2": [0.7, 0.71, 0.69, 0.7]}
    rows = [_row("webppl", 200, t, seed, v) for t, values in runs.items() for seed, v in enumerate(values)]
    (summary,) = bench.summarise(rows, ("system", "method", "set", "n"))
    assert summary["similarity_median"][0] == pytest.approx(0.7)
    assert summary["similarity_target_mean"][0] == pytest.approx(np.mean([0.1, 0.8, 0.7]))


def test_difference_is_of_medians_on_shared_runs(bench):
    ours = {"a": [0.9, 0.1, 0.5], "b": [0.6, 0.7, 0.2], "c": [0.5, 0.4, 0.3]}
    theirs = {"a": [0.2, 0.8, 0.4], "b": [0.65, 0.1, 0.3], "c": [0.45, 0.5, 0.35]}
    rows = [_row("procmod+guide", 10, t, seed, v) for t, values in ours.items() for seed, v in enumerate(values)]
    rows += [_row("webppl", 200, t, seed, v) for t, values in theirs.items() for seed, v in enumerate(values)]
    rows.append(_row("webppl", 200, "a", 7, 0.9))  # no guided run of that seed: left out
    (d,) = bench.paired_similarity_differences(rows, ["s"])
    json.dumps(d)  # the results file holds it
    # median(ours) - median(theirs) per target; the median of the runs' differences would
    # give "b" -0.05 instead of 0.3
    per_target = [0.5 - 0.4, 0.6 - 0.3, 0.4 - 0.45]
    assert (d["pairs"], d["targets"], d["targets_guided_ahead"]) == (9, 3, 2)
    assert d["target_mean_difference"][0] == pytest.approx(np.mean(per_target))
    assert (d["guided_median"], d["webppl_median"]) == (0.5, 0.4)


def test_fig5b_times_follow_the_measure_asked_for(bench):
    # pooled median and per-target mean disagree at 10 particles: 0.55 against 0.4
    summary = [{"set": "s", "system": "webppl", "method": "SMC", "n": n, "beyond_seconds_median": t,
                "similarity_median": [m, 0, 0], "similarity_target_mean": [tm, 0, 0]}
               for n, t, m, tm in ((10, 1.0, 0.55, 0.4), (20, 2.0, 0.65, 0.6))]
    pooled = bench.time_to_similarity(summary, "s", "webppl", "beyond_seconds_median")
    fig5 = bench.time_to_similarity(summary, "s", "webppl", "beyond_seconds_median", "similarity_target_mean")
    assert pooled[0.5] == 1.0 and pooled[0.6] == pytest.approx(1.5) and pooled[0.7] is None
    assert fig5[0.5] == pytest.approx(1.5) and fig5[0.6] == 2.0


def test_the_bench_writes_targets_procmod_reads_as_the_scorer_does(bench, tmp_path, capsys):
    """A shape cut out on a transparent ground and touching most of the border reached
    procmod inverted (the bench wrote it black on white; procmod took the border's colour
    for the paper); a picture that vanished at 50x50 stopped the bench with a traceback;
    a folder named like a built-in set replaced it; .webp and .pgm were left out."""
    from PIL import Image

    from procmod.targets import load_target_image

    folder = tmp_path / "glyphs"
    folder.mkdir()
    house = np.zeros((120, 100, 4), dtype=np.uint8)
    house[10:, :, 3] = 255  # an opaque house filling the picture's width and bottom
    house[:10, 30:70, 3] = 255
    Image.fromarray(house, "RGBA").save(folder / "house.webp", lossless=True)
    thin = np.full((400, 400), 255, dtype=np.uint8)
    thin[200:203, 200:203] = 0  # a dot under half a canvas pixel: gone at 50x50 (a line is widened)
    Image.fromarray(thin).save(folder / "thin.pgm")
    (folder / "notes.txt").write_text("not a picture")
    # a picture whose name has no suffix, as procmod infer --target reads it (h51: left out)
    Image.fromarray(house[..., 3]).save(folder / "IMG_0042", format="PNG")
    images = bench.target_images([], 1, folder, 49)
    assert list(images) == ["dir-glyphs"] and len(images["dir-glyphs"]) == 2
    err = capsys.readouterr().err
    assert "skipping thin.pgm" in err and "not pictures, left out: notes.txt" in err
    written = bench.write_targets(images, tmp_path / "targets")
    assert [row[1] for row in written["dir-glyphs"]] == ["IMG_0042", "house.webp"]
    (name, label, png, mask_json, mask, digest) = written["dir-glyphs"][1]
    assert label == "house.webp" and mask.mean() > 0.6  # the house (padded to a square), not its complement
    assert np.array_equal(load_target_image(png).at_size(bench.SIZE, bench.SIZE), mask)
    assert json.loads(mask_json.read_text())["mask"] == mask.astype(int).ravel().tolist()


def test_the_bench_skips_what_it_cannot_measure_and_says_so(bench, tmp_path, capsys):
    """A picture filling the frame at 50x50 stopped the whole bench with a traceback (its
    mask, written opaque everywhere, read back empty); a dot of a few pixels was benched,
    its normalised similarity near -9 swamping the per-target means; subfolders were
    passed over without a word."""
    from PIL import Image

    folder = tmp_path / "mine"
    (folder / "more").mkdir(parents=True)
    page = np.full((200, 200), 255, dtype=np.uint8)
    page[1:-1, 1:-1] = 0  # black to a 1-pixel white border: the whole frame at 50x50
    Image.fromarray(page).save(folder / "full.png")
    dot = np.full((200, 200), 255, dtype=np.uint8)
    dot[100:104, 100:104] = 0
    Image.fromarray(dot).save(folder / "dot.png")
    bar = np.full((200, 200), 255, dtype=np.uint8)
    bar[40:160, 90:110] = 0
    Image.fromarray(bar).save(folder / "bar.png")
    images = bench.target_images([], 1, folder, 49)
    err = capsys.readouterr().err
    assert [t.name for t in images["mine"]] == ["bar.png"]
    assert "skipping dot.png: the shape covers" in err and "skipping full.png: the shape covers 100%" in err
    assert "subfolders not read" in err and "more" in err
    written = bench.write_targets(images, tmp_path / "targets")
    assert len(written["mine"]) == 1


def test_work_rows_are_reused_only_under_the_same_settings_and_pictures(bench):
    import argparse

    args = argparse.Namespace(leaves=True, repeats=1, workers=None, guide=None)
    same = bench.run_settings_digest(args, "procmod", "t1", None)
    assert same == bench.run_settings_digest(args, "procmod", "t1", None)
    assert same != bench.run_settings_digest(args, "procmod", "t2", None)  # another picture, same name
    assert same != bench.run_settings_digest(argparse.Namespace(**{**vars(args), "leaves": False}), "procmod", "t1",
                                             None)
    guided = argparse.Namespace(**{**vars(args), "guide": "vines-scribbles"})
    assert bench.run_settings_digest(guided, "procmod+guide", "t1", "a") != \
        bench.run_settings_digest(guided, "procmod+guide", "t1", "b")  # another guide's files
    # the MCMC comparison takes neither --repeats nor --workers: changing them reran it
    other = argparse.Namespace(**{**vars(args), "repeats": 3, "workers": 2})
    assert bench.run_settings_digest(args, "mcmc", "t1", None, mh_samples=50) == \
        bench.run_settings_digest(other, "mcmc", "t1", None, mh_samples=50)
    assert bench.run_settings_digest(args, "mcmc", "t1", None, mh_samples=50) != \
        bench.run_settings_digest(args, "mcmc", "t1", None, mh_samples=60)


@pytest.mark.parametrize("argv, message", [
    (["--particles", "0"], "--particles takes positive counts"),
    (["--seeds", "0"], "--seeds must be 1 or more"),
    (["--name", "sub/x"], "--name is a file stem"),
    (["--sets"], "nothing to bench"),
    (["--guide", "no-such-guide"], "--guide: guide file no-such-guide.json does not exist"),
])
def test_arguments_that_would_fail_late_are_refused_first(bench, monkeypatch, capsys, argv, message):
    monkeypatch.setattr("sys.argv", ["vs_webppl.py", *argv])
    monkeypatch.setattr(bench, "ensure_webppl", lambda: pytest.fail("ran past the checks"))
    with pytest.raises(SystemExit):
        bench.main()
    assert message in capsys.readouterr().err


def test_a_target_whose_written_mask_reads_back_wrong_is_left_out(bench, tmp_path, capsys, monkeypatch):
    # the read-back refusal named an exception the bench had not imported (a NameError)
    import procmod.targets
    from procmod.targets import TargetFileError

    images = {"glyphs": bench.target_images(["glyphs"], 2, None, 49)["glyphs"]}
    real = procmod.targets.load_target_image

    def first_fails(path):
        if path.name.endswith("_00.png"):
            raise TargetFileError(f"{path}: the target mask is empty")
        return real(path)

    monkeypatch.setattr(procmod.targets, "load_target_image", first_fails)
    written = bench.write_targets(images, tmp_path / "targets")
    assert [row[0] for row in written["glyphs"]] == ["glyphs_01"]
    assert "reads back as" in capsys.readouterr().err


def test_a_folder_of_peoples_pictures_is_read_as_procmod_would_and_each_note_names_its_file(bench, tmp_path, capsys):
    """h67: notes named no picture (a folder of 40 could not be read back); a page read as
    the shape, its drawing as holes, was benched; a link to another picture counted it
    twice; a link to nothing, a sidecar of no picture and an iPhone's HEIC photo (listed
    as "not pictures") vanished without the reason; --bottom-centre started a wide
    picture's vine in the padding below it."""
    import dataclasses

    from PIL import Image

    folder = tmp_path / "mine"
    folder.mkdir()
    bar = np.full((200, 200), 255, dtype=np.uint8)
    bar[40:160, 90:110] = 0
    Image.fromarray(bar).save(folder / "bar.png")
    (folder / "again.png").symlink_to(folder / "bar.png")
    (folder / "gone.png").symlink_to(folder / "nothing.png")
    (folder / "stray.json").write_text('{"start": [0.5, 0.5]}')
    (folder / "IMG_0001.HEIC").write_bytes(b"\0\0\0\x18ftypheic\0\0\0\0mif1heic" + bytes(64))
    framed = np.full((300, 300), 20, dtype=np.uint8)  # a page in a dark frame, its ink as dark as the frame
    framed[15:285, 15:285] = 235
    framed[80:220, 140:150] = 20
    Image.fromarray(framed).save(folder / "panel.png")
    wide = np.full((100, 300), 255, dtype=np.uint8)  # translucent strokes of a wide picture
    wide[20:90, 140:160] = 0
    rgba = np.zeros((100, 300, 4), dtype=np.uint8)
    rgba[..., 3] = np.where(wide == 0, 255, 0)
    rgba[20:30, 40:260, 3] = 70  # a light stroke: left out, with a note naming the file
    Image.fromarray(rgba, "RGBA").save(folder / "wide.png")
    images = bench.target_images([], 1, folder, 49)
    err = capsys.readouterr().err
    assert sorted(t.name for t in images["mine"]) == ["again.png", "wide.png"], err  # (the link comes first)
    assert "skipping bar.png: the same target as again.png" in err
    assert "links to nothing, left out: gone.png" in err and "no picture's sidecar" in err and "stray.json" in err
    assert "skipping IMG_0001.HEIC: " in err and "HEIC/HEIF photo" in err and "convert it to JPEG or PNG" in err
    assert "skipping panel.png: the shape read is one light rectangle" in err
    assert "note: wide.png: translucent strokes" in err
    target = next(t for t in images["mine"] if t.name == "wide.png")
    x, y = bench.bottom_centre(target)
    top, left, height, width = target.picture
    assert x == pytest.approx(0.5) and top / 300 < y < (top + height) / 300  # in the picture, not the padding
    assert dataclasses.replace(target, start=(x, y)).start[1] < 0.7


def test_soft_edges_shadows_and_glows_get_no_translucent_note(tmp_path):
    """h68: the translucent-strokes note fired on a soft brush's edge, a drop shadow and a
    glow, and told the user to export them opaque, into the shape."""
    from PIL import Image, ImageDraw, ImageFilter

    from procmod.targets import load_target_image

    layer = Image.new("L", (500, 500), 0)
    ImageDraw.Draw(layer).line([(100, 400), (250, 100), (400, 380)], fill=255, width=14)
    stroke = np.asarray(layer, dtype=float)
    shadow = np.asarray(Image.fromarray(np.roll(stroke, 8, (0, 1)).astype(np.uint8)).filter(
        ImageFilter.GaussianBlur(4)), dtype=float) * 0.4
    glow = np.minimum(np.asarray(layer.filter(ImageFilter.GaussianBlur(8)), dtype=float) * 1.35, 110)
    for name, alpha in (("soft.png", np.asarray(layer.filter(ImageFilter.GaussianBlur(3)), dtype=float)),
                        ("shadow.png", np.maximum(stroke, shadow)), ("glow.png", np.maximum(stroke, glow))):
        pixels = np.zeros((500, 500, 4), dtype=np.uint8)
        pixels[..., 3] = np.clip(alpha, 0, 255).astype(np.uint8)
        Image.fromarray(pixels, "RGBA").save(tmp_path / name)
        notes = load_target_image(tmp_path / name).notes
        assert not any(n.startswith("translucent") for n in notes), (name, notes)


def test_a_sidecar_is_found_in_another_case_or_after_the_pictures_own_suffix(tmp_path):
    """NAME.JSON and NAME.png.json were passed over without a word: the start came from the
    picture, not the user's file (h67)."""
    from PIL import Image

    from procmod.targets import TargetFileError, load_target_image

    bar = np.full((200, 200), 255, dtype=np.uint8)
    bar[40:160, 90:110] = 0
    for name, sidecar in (("upper.png", "upper.JSON"), ("double.png", "double.png.json"), ("plain.png", None)):
        Image.fromarray(bar).save(tmp_path / name)
        if sidecar:
            (tmp_path / sidecar).write_text('{"start": [0.3, 0.2], "direction": [1, 0]}')
        target = load_target_image(tmp_path / name)
        expected = (0.3, 0.2) if sidecar else None
        assert (target.start == pytest.approx(expected)) if expected else target.start[1] > 0.7, (name, target.start)
    # procmod's own best.json beside best.png is no sidecar and hides none (h68: the user's
    # best.png.json was passed over); two sidecars of the user's are one too many
    Image.fromarray(bar).save(tmp_path / "best.png")
    (tmp_path / "best.json").write_text('{"format": "procmod-derivation/2"}')
    (tmp_path / "best.png.json").write_text('{"start": [0.3, 0.2]}')
    assert load_target_image(tmp_path / "best.png").start == pytest.approx((0.3, 0.2))
    (tmp_path / "plain.json").write_text('{"start": [0.3, 0.2]}')
    (tmp_path / "plain.png.json").write_text('{"start": [0.6, 0.2]}')
    with pytest.raises(TargetFileError, match="has two sidecars, plain.json and plain.png.json"):
        load_target_image(tmp_path / "plain.png")
