"""The orbitable 3D viewer (procmod.viewer) in run reports and on contact pages of 3D samples.

The browser tests open the pages from disk in headless Chromium with every host name
unresolvable (no network at view time) and WebGL in software, take a screenshot and check
that the model is drawn: the view reports itself drawn, and enough pixels inside its
rectangle differ from the viewer's background (the legend's rows left out). A page whose
view has nothing to draw is the control: its rectangle stays background.
"""

import json
from pathlib import Path

import numpy as np
import pytest
import trimesh

from procmod.core import InvalidArgumentError, run_forward
from procmod.infer import Budget, ga
from procmod.models import get_model
from procmod.report import write_run
from procmod.render import write_contact_page
from procmod.targets import load_target_file
from procmod.viewer import BUNDLE, LICENCE, View, viewer_html, viewer_scripts, Layer
from procmod.viewer.layers import silhouette_layer, voxel_surface

import headless_browser as browser

ROOT = Path(__file__).resolve().parents[1]
LEGEND_ROWS = 90  # the legend and buttons sit in the top rows of a view

needs_chromium = pytest.mark.skipif(
    browser.chromium() is None,
    reason="Debian's chromium is not installed (apt-get install -y chromium; .ci/run installs it)")


def _run(model_name, scene, out, population=10):
    target = load_target_file(ROOT / "scenes" / scene / "target.json")
    result = ga(get_model(model_name), target, population=population, seed=0, budget=Budget(generations=2))
    write_run(result, target, out, 128, "test")
    return out / "report.html"


# ---- pages in a browser -----------------------------------------------------------------------

@needs_chromium
def test_a_volume_run_report_draws_the_best_result_and_the_target(tmp_path):
    page = _run("spaceship", "spaceship_volume", tmp_path / "run")
    text = page.read_text()
    assert "<script src" not in text and "<link" not in text  # everything inline
    dom, image = browser.load(page)
    (view,) = browser.views(dom)
    assert view["status"] == "drawn", browser.explain(dom)
    # the ship and the translucent target fill about a fifth of the view; lines alone < 1%
    assert browser.drawn_fraction(image, view["rect"], LEGEND_ROWS) > 0.05
    assert "target: covering gains" in dom


@needs_chromium
def test_a_silhouette_run_report_draws_the_cut_out_and_offers_the_target_camera(tmp_path):
    page = _run("tree", "tree_heart", tmp_path / "run")
    dom, image = browser.load(page)
    (view,) = browser.views(dom)
    assert view["status"] == "drawn", browser.explain(dom)
    assert browser.drawn_fraction(image, view["rect"], LEGEND_ROWS) > 0.05
    assert "target camera 1" in dom and "target view 1: hit" in dom


@needs_chromium
def test_the_contact_page_of_3d_samples_draws_every_sample(tmp_path):
    model = get_model("spaceship")
    samples = [run_forward(model, np.random.default_rng([0, i])) for i in range(4)]
    page = tmp_path / "contact_sheet.html"
    write_contact_page(samples, page, links=[f"sample_{i:03d}.glb" for i in range(4)])
    dom, image = browser.load(page, width=1300, height=800)
    found = browser.views(dom)
    assert [v["status"] for v in found] == ["drawn"] * 4, browser.explain(dom)
    for view in found:
        assert browser.drawn_fraction(image, view["rect"]) > 0.02


_WHEEL_PROBE = """<script>
function probe() {
  if (document.documentElement.dataset.procmodViewer !== 'drawn') { setTimeout(probe, 50); return; }
  const view = document.querySelector('[data-procmod-view]');
  const wheel = () => {
    const event = new WheelEvent('wheel', { deltaY: 120, bubbles: true, cancelable: true });
    view.dispatchEvent(event);
    return event.defaultPrevented;  // taken for zooming: the page does not scroll
  };
  const before = wheel();
  view.dispatchEvent(new PointerEvent('pointerdown', { bubbles: true, pointerType: 'mouse', button: 0 }));
  view.dispatchEvent(new PointerEvent('pointerup', { bubbles: true, pointerType: 'mouse', button: 0 }));
  const pressed = wheel();
  view.dispatchEvent(new MouseEvent('dblclick', { bubbles: true }));  // reset: the view is still pressed
  const reset = wheel();
  view.dispatchEvent(new PointerEvent('pointerleave'));
  document.body.dataset.probe = [before, pressed, reset, wheel()].join(',');
}
probe();
</script>"""


@needs_chromium
def test_the_wheel_scrolls_a_contact_page_until_a_view_is_pressed(tmp_path):
    """The tiles cover a contact page, and each zoomed under the wheel: the page could be
    scrolled only in the gaps between them (a review found). A view takes the wheel once
    pressed, until the pointer leaves it (a double-click's reset keeps it); a page's only
    view (a report) takes it at once."""
    model = get_model("spaceship")
    samples = [run_forward(model, np.random.default_rng([0, i])) for i in range(2)]
    page = tmp_path / "contact_sheet.html"
    write_contact_page(samples, page, links=[f"sample_{i:03d}.glb" for i in range(2)])
    page.write_text(page.read_text().replace("</body>", _WHEEL_PROBE + "</body>"))
    dom, _ = browser.load(page, width=900, height=600, finished="data-probe=")
    assert 'data-probe="false,true,true,false"' in dom, dom[-1500:]
    report = _run("spaceship", "spaceship_volume", tmp_path / "run")
    report.write_text(report.read_text().replace("</body>", _WHEEL_PROBE + "</body>"))
    dom, _ = browser.load(report, finished="data-probe=")
    assert 'data-probe="true,true,true,true"' in dom, dom[-1500:]


_CAMERA_PROBE = """<script>
const seen = [];
window.addEventListener('error', (event) => seen.push(String(event.message)));
function press() {
  if (document.documentElement.dataset.procmodViewer !== 'drawn') { setTimeout(press, 50); return; }
  const buttons = [...document.querySelectorAll('.procmod-view-buttons button')];
  // a mouse press on a button or a checkbox stays there (the view's controls captured it)
  let reached = 0;
  document.querySelector('[data-procmod-view]').addEventListener('pointerdown', () => { reached += 1; });
  for (const pressed of [buttons[0], document.querySelector('.procmod-legend input')]) {
    pressed.dispatchEvent(new PointerEvent('pointerdown', { bubbles: true, pointerType: 'mouse', button: 0 }));
  }
  document.body.dataset.reached = String(reached);
  buttons.find((b) => b.textContent === 'target camera 1').click();
  buttons.find((b) => b.textContent === 'reset view').click();
  setTimeout(() => { document.body.dataset.errors = String(seen.length); }, 200);
}
press();
</script>"""


def test_a_target_camera_carries_its_pictures_aspect():
    """The view fits a target camera's whole picture: the skyline's 128x48 sketch was cut to
    its middle in a 720x480 view, the fov fitted to its height only."""
    from procmod.viewer.layers import target_view_parts

    target = load_target_file(ROOT / "scenes" / "city_skyline" / "target.json")
    _, _, cameras = target_view_parts(target)
    assert [round(c["aspect"], 3) for c in cameras] == [round(128 / 48, 3)]


@needs_chromium
def test_a_target_camera_and_back_leave_the_view_drawn(tmp_path):
    """Each target camera gets controls of its own, made for its up (a camera looking down
    could not be orbited after its button); switching to it and back raises nothing; and a
    mouse press on a button or a legend checkbox stays with it (the view's controls
    captured it, so a real click did nothing, a review found)."""
    page = _run("tree", "tree_heart", tmp_path / "run")
    page.write_text(page.read_text().replace("</body>", _CAMERA_PROBE + "</body>"))
    dom, image = browser.load(page, finished="data-errors=")
    (view,) = browser.views(dom)
    assert 'data-errors="0"' in dom and view["status"] == "drawn", dom[-1500:]
    assert 'data-reached="0"' in dom  # the presses on a button and a checkbox did not reach the view
    assert browser.drawn_fraction(image, view["rect"], LEGEND_ROWS) > 0.05


@needs_chromium
def test_control_a_view_with_nothing_to_draw_stays_background(tmp_path):
    page = tmp_path / "empty.html"
    page.write_text("<!doctype html><html><body>" + viewer_html([View(())], 400, 300) + "</body></html>")
    dom, image = browser.load(page, width=800, height=600)
    (view,) = browser.views(dom)
    assert view["status"] == "drawn"
    assert browser.drawn_fraction(image, view["rect"], LEGEND_ROWS) < 0.001


# ---- without a browser ------------------------------------------------------------------------

def test_the_bundle_is_package_data_with_the_three_js_licence():
    text = BUNDLE.read_text(encoding="utf-8")
    assert "three.js authors" in text[:2000] and "Permission is hereby granted" in text[:2000]
    assert "MIT License" in LICENCE.read_text(encoding="utf-8")
    assert "</script" not in text.lower()


def test_data_cannot_close_the_script_that_holds_it_and_stays_json():
    """``<!--`` had been written ``<\\!--``, which is no JSON escape: JSON.parse refused the data."""
    html = viewer_scripts([View((Layer("</script><b>x<!--y", b"glb"),), "</script>")])
    data = html.split('id="procmod-viewer-data">', 1)[1].split("</script>", 1)[0]
    assert "<" not in data  # nothing in it can end the script or open a comment
    parsed = json.loads(data)  # as the page reads it
    assert "</script><b>x<!--y" in json.dumps(parsed, ensure_ascii=False)  # the label whole, inside the data


def test_the_voxel_surface_is_closed_faces_out_and_encloses_the_voxels():
    mask = np.zeros((6, 7, 8), bool)
    mask[1:4, 2:6, 1:7] = True
    mask[4, 3, 3] = True  # a voxel on one face
    mask[0, 0, 0] = True  # a separate one, in a corner of the grid
    vertices, faces = voxel_surface(mask, (0.5, -1.0, 2.0), 0.25)
    mesh = trimesh.Trimesh(vertices, faces, process=False)
    assert mesh.is_watertight and mesh.is_winding_consistent
    assert mesh.volume == pytest.approx(mask.sum() * 0.25 ** 3)  # positive: faces point out
    single = np.zeros((1, 1, 1), bool)
    single[0, 0, 0] = True
    assert voxel_surface(single, (0, 0, 0), 1.0)[1].shape == (12, 3)


def test_a_silhouette_cut_out_lies_where_the_camera_sees_its_pixels():
    from procmod.geometry.camera import Camera
    camera = Camera((1.0, 2.0, 20.0), (1.0, 2.0, 0.0), (0, 1, 0), "perspective", 30.0, 40, 30)
    image = np.zeros((30, 40), bool)
    image[5:9, 10:20] = True
    layer = silhouette_layer("hit", image, camera, "#00f")
    mesh = trimesh.load(trimesh.util.wrap_as_stream(layer.glb), file_type="glb", force="mesh")
    pixels = camera.project(np.asarray(mesh.vertices))
    assert np.allclose(pixels[:, 2], 20.0)  # in the plane through look_at
    assert pixels[:, 0].min() == pytest.approx(10) and pixels[:, 0].max() == pytest.approx(20)
    assert pixels[:, 1].min() == pytest.approx(5) and pixels[:, 1].max() == pytest.approx(9)


def test_a_2d_run_report_has_no_viewer(tmp_path):
    from procmod.data import target_image
    from procmod.infer import smc
    from procmod.targets import ShapeMatch
    target = ShapeMatch(target_image("glyph:a"))
    result = smc(get_model("vines"), target, particles=5, seed=0)
    write_run(result, target, tmp_path, 64, "test")
    assert "procmod-viewer-data" not in (tmp_path / "report.html").read_text()


def test_a_contact_page_is_for_3d_samples(tmp_path):
    sample = run_forward(get_model("vines"), np.random.default_rng(0))
    with pytest.raises(InvalidArgumentError, match="3D"):
        write_contact_page([sample], tmp_path / "x.html")
