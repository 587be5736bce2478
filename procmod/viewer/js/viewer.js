// procmod's orbitable 3D viewer: the source of procmod/viewer/procmod-viewer.js (bundled with
// three.js by procmod/viewer/build.py; see its docstring for the exact versions and command).
//
// A page holds one JSON data block (<script type="application/json" id="procmod-viewer-data">)
// and any number of view elements (<div class="procmod-view" data-procmod-view="I">). Each view is
// a list of layers, each a GLB file (base64) with a legend name, an opacity and an optional flat
// colour; translucent layers (volume targets) are drawn after the opaque ones.
//
// All views share one WebGL renderer whose canvas lies fixed behind the page; each view is drawn
// into its element's rectangle (scissor), so a contact page of 64 samples needs one WebGL
// context (browsers allow about 16). Frames are drawn on demand: after loading, on orbiting,
// scrolling and resizing. Nothing is fetched: file:// pages cannot fetch, and the data is inline.
//
// When every view is drawn, <html data-procmod-viewer="drawn"> and each view element carries
// data-status="drawn" and data-rect="left,top,width,height" (CSS pixels), which the tests read.

import {
  AmbientLight, Box3, Box3Helper, Color, DirectionalLight, DoubleSide, FrontSide, Group,
  HemisphereLight,
  MeshStandardMaterial, PerspectiveCamera, Scene, Vector3, WebGLRenderer,
} from 'three';
import { OrbitControls } from 'three/addons/controls/OrbitControls.js';
import { GLTFLoader } from 'three/addons/loaders/GLTFLoader.js';

const BACKGROUND = 0xf3f4f6;

function decodeBase64(text) {
  const binary = atob(text);
  const bytes = new Uint8Array(binary.length);
  for (let i = 0; i < binary.length; i++) bytes[i] = binary.charCodeAt(i);
  return bytes.buffer;
}

function material(layer, hasColours) {
  // glTF's default material is fully metallic (black without an environment map), and
  // procmod's GLB files carry colours per vertex and no normals: flat-shaded, matte.
  const translucent = layer.opacity < 1;
  return new MeshStandardMaterial({
    color: layer.colour ? new Color(layer.colour) : new Color(0xffffff),
    vertexColors: hasColours && !layer.colour,
    metalness: 0.0,
    roughness: 0.8,
    flatShading: true,
    transparent: translucent,
    opacity: layer.opacity,
    depthWrite: !translucent,
    side: translucent || layer.double_sided ? DoubleSide : FrontSide,
  });
}

async function loadLayer(loader, layer) {
  const gltf = await loader.parseAsync(decodeBase64(layer.glb), '');
  const root = gltf.scene;
  root.traverse((node) => {
    if (node.isMesh) {
      node.material = material(layer, 'color' in node.geometry.attributes);
      node.renderOrder = layer.opacity < 1 ? 1 : 0;
    }
  });
  root.visible = layer.visible !== false;
  return root;
}

function legend(element, layers, roots, redraw) {
  const box = document.createElement('div');
  box.className = 'procmod-legend';
  layers.forEach((layer, i) => {
    const label = document.createElement('label');
    const check = document.createElement('input');
    check.type = 'checkbox';
    check.checked = roots[i].visible;
    check.addEventListener('change', () => { roots[i].visible = check.checked; redraw(); });
    const swatch = document.createElement('span');
    swatch.className = 'procmod-swatch';
    swatch.style.background = layer.colour || '#888';
    if (!layer.colour) swatch.style.background = 'linear-gradient(135deg,#9aa3b5,#4f6ea8,#d0a04a)';
    label.append(check, swatch, document.createTextNode(' ' + layer.name));
    box.append(label);
  });
  keepPointer(box);
  element.append(box);
  return box;
}

function keepPointer(element) {
  // The view's orbit controls capture the pointer on pointerdown: a mouse click on a button
  // or a checkbox inside the view went to the view instead (touch and keys worked).
  element.addEventListener('pointerdown', (event) => event.stopPropagation());
}

function frame(camera, controls, box, direction) {
  const centre = box.getCenter(new Vector3());
  const radius = Math.max(box.getSize(new Vector3()).length() / 2, 1e-3);
  const distance = radius / Math.sin((camera.fov * Math.PI) / 360) * 1.05;
  camera.position.copy(centre).addScaledVector(direction.clone().normalize(), distance);
  camera.near = distance / 100;
  camera.far = distance * 100;
  camera.updateProjectionMatrix();
  controls.target.copy(centre);
  controls.update();
}

function viewFromTargetCamera(camera, controls, spec) {
  // A target's camera (a silhouette view): perspective cameras as they are; orthographic ones
  // approximated from far away with the fov that shows the same height at look_at. The
  // camera's whole picture is shown: a picture wider than the view (a 128x48 skyline) gets
  // the taller fov that fits its width. ``controls`` must have been made for ``spec.up``.
  const eye = new Vector3(...spec.eye);
  const lookAt = new Vector3(...spec.look_at);
  let fov;
  if (spec.projection === 'orthographic') {
    const forward = lookAt.clone().sub(eye).normalize();
    const distance = spec.fov * 20;
    fov = 2 * Math.atan(spec.fov / 2 / distance);
    camera.position.copy(lookAt).addScaledVector(forward, -distance);
  } else {
    fov = spec.fov * Math.PI / 180;
    camera.position.copy(eye);
  }
  const wider = (spec.aspect || 1) / (camera.aspect || 1);
  if (wider > 1) fov = 2 * Math.atan(Math.tan(fov / 2) * wider);
  camera.fov = fov * 180 / Math.PI;
  camera.near = camera.position.distanceTo(lookAt) / 100;
  camera.far = camera.position.distanceTo(lookAt) * 100;
  camera.updateProjectionMatrix();
  controls.target.copy(lookAt);
  controls.update();
}

async function start() {
  const dataElement = document.getElementById('procmod-viewer-data');
  if (!dataElement) return;
  const data = JSON.parse(dataElement.textContent);
  const elements = [...document.querySelectorAll('[data-procmod-view]')];
  const fail = (message) => {
    document.documentElement.dataset.procmodViewer = 'error';
    for (const element of elements) {
      element.dataset.status = 'error';
      const note = document.createElement('p');
      note.className = 'procmod-view-error';
      note.textContent = message;
      element.append(note);
    }
  };
  const canvas = document.createElement('canvas');
  canvas.className = 'procmod-canvas';
  document.body.prepend(canvas);
  let renderer;
  try {
    renderer = new WebGLRenderer({ canvas, antialias: true, alpha: true, preserveDrawingBuffer: true });
  } catch (error) {
    canvas.remove();
    fail('This browser cannot draw WebGL, so the 3D view is not shown; the PNG pictures and the GLB '
         + 'files beside this page hold the same models.');
    return;
  }
  renderer.setPixelRatio(window.devicePixelRatio || 1);
  const loader = new GLTFLoader();
  const views = [];
  let pending = false;
  const redraw = () => {
    if (!pending) { pending = true; requestAnimationFrame(draw); }
  };

  function draw() {
    pending = false;
    const width = canvas.clientWidth;
    const height = canvas.clientHeight;
    if (canvas.width !== Math.floor(width * renderer.getPixelRatio())
        || canvas.height !== Math.floor(height * renderer.getPixelRatio())) {
      renderer.setSize(width, height, false);
    }
    renderer.setScissorTest(false);
    renderer.setClearColor(0x000000, 0);
    renderer.clear();
    renderer.setScissorTest(true);
    for (const view of views) {
      const rect = view.element.getBoundingClientRect();
      if (rect.bottom < 0 || rect.top > height || rect.right < 0 || rect.left > width) continue;
      const bottom = height - rect.bottom;
      renderer.setViewport(rect.left, bottom, rect.width, rect.height);
      renderer.setScissor(rect.left, bottom, rect.width, rect.height);
      renderer.setClearColor(BACKGROUND, 1);
      renderer.clear();
      if (view.camera.aspect !== rect.width / rect.height) {
        view.camera.aspect = rect.width / rect.height;
        view.camera.updateProjectionMatrix();
      }
      renderer.render(view.scene, view.camera);
      view.element.dataset.rect = [rect.left, rect.top, rect.width, rect.height].map(Math.round).join(',');
      view.element.dataset.status = 'drawn';
    }
    if (views.length === elements.length) document.documentElement.dataset.procmodViewer = 'drawn';
  }

  try {
    for (const element of elements) {
      const spec = data.views[Number(element.dataset.procmodView)];
      const scene = new Scene();
      scene.add(new HemisphereLight(0xffffff, 0x606070, 1.3));
      scene.add(new AmbientLight(0xffffff, 0.3));
      const camera = new PerspectiveCamera(35, 1, 0.01, 1000);
      const sun = new DirectionalLight(0xffffff, 1.8);
      sun.position.set(0.4, 1.0, 0.8);
      camera.add(sun);  // the light follows the view, so every side the user turns to is lit
      scene.add(camera);
      const content = new Group();
      scene.add(content);
      const roots = [];
      for (const layer of spec.layers) {
        const root = await loadLayer(loader, layer);
        content.add(root);
        roots.push(root);
      }
      if (spec.bounds) {
        const helper = new Box3Helper(new Box3(new Vector3(...spec.bounds[0]), new Vector3(...spec.bounds[1])),
          0x9a9a9a);
        content.add(helper);
      }
      // Orbiting turns about camera.up as it was when the controls were made: a target
      // camera looking down (its up not y) gets controls of its own, or dragging did nothing.
      // On a page of several views the wheel scrolls the page until a view is pressed (it
      // zoomed whichever tile lay under the pointer, and tiles cover the page).
      const zoomAtOnce = elements.length === 1;
      let pressed = false;  // since the pointer last entered the view
      let controls = null;
      const orbitAbout = (up) => {
        if (controls) controls.dispose();
        camera.up.set(...up);
        controls = new OrbitControls(camera, element);
        controls.enableZoom = zoomAtOnce || pressed;
        controls.addEventListener('change', redraw);
        view.controls = controls;
      };
      const view = { element, scene, camera, controls };
      if (!zoomAtOnce) {
        element.addEventListener('pointerdown', () => { pressed = true; controls.enableZoom = true; });
        element.addEventListener('pointerleave', () => { pressed = false; controls.enableZoom = false; });
      }
      orbitAbout([0, 1, 0]);
      const box = new Box3();
      roots.forEach((root, i) => { if (spec.layers[i].frame !== false) box.expandByObject(root); });
      if (box.isEmpty()) box.setFromObject(content);
      if (box.isEmpty()) box.set(new Vector3(-1, -1, -1), new Vector3(1, 1, 1));
      const direction = new Vector3(...(spec.direction || [1.0, 0.7, 1.4]));
      const home = () => { orbitAbout([0, 1, 0]); camera.fov = 35; frame(camera, controls, box, direction); redraw(); };
      home();
      element.addEventListener('dblclick', home);
      legend(element, spec.layers, roots, redraw);
      if (spec.label) {
        const caption = document.createElement('div');
        caption.className = 'procmod-view-label';
        caption.textContent = spec.label;
        element.append(caption);
      }
      const buttons = document.createElement('div');
      buttons.className = 'procmod-view-buttons';
      const reset = document.createElement('button');
      reset.type = 'button';
      reset.textContent = 'reset view';
      reset.addEventListener('click', home);
      buttons.append(reset);
      (spec.cameras || []).forEach((cameraSpec, i) => {
        const button = document.createElement('button');
        button.type = 'button';
        button.textContent = `target camera ${i + 1}`;
        button.addEventListener('click', () => {
          orbitAbout(cameraSpec.up);
          viewFromTargetCamera(camera, controls, cameraSpec);
          redraw();
        });
        buttons.append(button);
      });
      keepPointer(buttons);
      element.append(buttons);
      views.push(view);
    }
  } catch (error) {
    fail('The 3D view could not be built: ' + error);
    throw error;
  }
  window.addEventListener('resize', redraw);
  window.addEventListener('scroll', redraw, { passive: true });
  redraw();
}

if (document.readyState === 'loading') {
  document.addEventListener('DOMContentLoaded', start);
} else {
  start();
}
