// JavaScript helpers for bench/peers/webppl/vines.wppl, the WebPPL peer of procmod's vines
// bench. Written for the bench from shared/seeds/vines.md; it shares no code with procmod.
//
// A canvas is immutable: every add* returns a new canvas (a copy of the pixels plus the new
// primitive), because WebPPL particles share JavaScript objects and SMC copies particles by
// continuation. A pixel is covered when its centre lies inside the primitive (no minimum
// stroke width), as in the original program.
'use strict';

var fs = require('fs');

// World viewport of the vines experiments: x in [-12, 12], y in [-22, 2]; row 0 is y = -22.
var XMIN = -12, XMAX = 12, YMIN = -22, YMAX = 2;
var FLAT = 1 / 1.5;          // weight of a flat (non-edge) target-filled pixel
var SIGMA = 0.02;            // likelihood: -(sim - 1)^2 / SIGMA^2
var OOB_SIGMA = 0.001;       // out-of-bounds term: -(ex^2 + ey^2) / OOB_SIGMA^2

function sobelWeights(mask, w, h) {
  // Sobel gradient magnitude with replicated borders, normalised to [0, 1].
  function at(i, j) {
    i = Math.min(Math.max(i, 0), w - 1);
    j = Math.min(Math.max(j, 0), h - 1);
    return mask[j * w + i];
  }
  var mag = new Float64Array(w * h);
  var top = 0;
  for (var j = 0; j < h; j++) {
    for (var i = 0; i < w; i++) {
      var gx = (at(i + 1, j - 1) + 2 * at(i + 1, j) + at(i + 1, j + 1)) -
               (at(i - 1, j - 1) + 2 * at(i - 1, j) + at(i - 1, j + 1));
      var gy = (at(i - 1, j + 1) + 2 * at(i, j + 1) + at(i + 1, j + 1)) -
               (at(i - 1, j - 1) + 2 * at(i, j - 1) + at(i + 1, j - 1));
      var m = Math.sqrt(gx * gx + gy * gy);
      mag[j * w + i] = m;
      if (m > top) { top = m; }
    }
  }
  if (top > 0) {
    for (var k = 0; k < w * h; k++) { mag[k] /= top; }
  }
  return mag;
}

function loadTarget(path) {
  // {"width": W, "height": H, "mask": [0/1 row-major], "start": [u, v], "direction": [dx, dy]}
  var spec = JSON.parse(fs.readFileSync(path, 'utf8'));
  var w = spec.width, h = spec.height;
  var mask = Uint8Array.from(spec.mask);
  var sobel = sobelWeights(mask, w, h);
  var gain = new Float64Array(w * h);
  var filledWeight = 0;
  for (var k = 0; k < w * h; k++) {
    if (mask[k]) {
      var wk = FLAT + (1 - FLAT) * sobel[k];
      gain[k] = wk;              // filling a target pixel: one more agreeing pixel
      filledWeight += wk;
    } else {
      gain[k] = -1;              // filling an empty pixel: one agreeing pixel less
    }
  }
  var x0 = XMIN + spec.start[0] * (XMAX - XMIN);
  var y0 = YMIN + spec.start[1] * (YMAX - YMIN);
  return {
    width: w, height: h, gain: gain, filledWeight: filledWeight,
    startX: x0, startY: y0, startAngle: Math.atan2(spec.direction[1], spec.direction[0]),
    sx: w / (XMAX - XMIN), sy: h / (YMAX - YMIN)
  };
}

function emptyCanvas(target) {
  return {pixels: new Uint8Array(target.width * target.height), gainTotal: 0,
          bbox: null, geometry: null, count: 0};
}

// Cover the pixels of the box [xlo, xhi] x [ylo, yhi] (world) whose centres pass `inside`.
function draw(target, canvas, xlo, xhi, ylo, yhi, inside, primitive) {
  var w = target.width, h = target.height;
  var pixels = canvas.pixels.slice();
  var gainTotal = canvas.gainTotal;
  var ilo = Math.max(0, Math.floor((xlo - XMIN) * target.sx));
  var ihi = Math.min(w - 1, Math.floor((xhi - XMIN) * target.sx));
  var jlo = Math.max(0, Math.floor((ylo - YMIN) * target.sy));
  var jhi = Math.min(h - 1, Math.floor((yhi - YMIN) * target.sy));
  for (var j = jlo; j <= jhi; j++) {
    var py = YMIN + (j + 0.5) / target.sy;
    for (var i = ilo; i <= ihi; i++) {
      var k = j * w + i;
      if (pixels[k]) { continue; }
      var px = XMIN + (i + 0.5) / target.sx;
      if (inside(px, py)) {
        pixels[k] = 1;
        gainTotal += target.gain[k];
      }
    }
  }
  var b = canvas.bbox;
  var bbox = b === null ? [xlo, xhi, ylo, yhi] :
      [Math.min(b[0], xlo), Math.max(b[1], xhi), Math.min(b[2], ylo), Math.max(b[3], yhi)];
  return {pixels: pixels, gainTotal: gainTotal, bbox: bbox,
          geometry: {primitive: primitive, rest: canvas.geometry}, count: canvas.count + 1};
}

function addSegment(target, canvas, x0, y0, x1, y1, width) {
  var r = width / 2, dx = x1 - x0, dy = y1 - y0, len2 = dx * dx + dy * dy;
  return draw(target, canvas, Math.min(x0, x1) - r, Math.max(x0, x1) + r,
              Math.min(y0, y1) - r, Math.max(y0, y1) + r,
              function(px, py) {
                var t = len2 > 0 ? ((px - x0) * dx + (py - y0) * dy) / len2 : 0;
                t = Math.min(1, Math.max(0, t));
                var ex = px - (x0 + t * dx), ey = py - (y0 + t * dy);
                return ex * ex + ey * ey <= r * r;
              },
              {type: 'segment', x0: x0, y0: y0, x1: x1, y1: y1, width: width});
}

function addEllipse(target, canvas, cx, cy, angle, length, width) {
  var a = length / 2, b = width / 2, ca = Math.cos(angle), sa = Math.sin(angle);
  var hx = Math.sqrt(a * a * ca * ca + b * b * sa * sa);
  var hy = Math.sqrt(a * a * sa * sa + b * b * ca * ca);
  return draw(target, canvas, cx - hx, cx + hx, cy - hy, cy + hy,
              function(px, py) {
                var u = (px - cx) * ca + (py - cy) * sa, v = -(px - cx) * sa + (py - cy) * ca;
                return (u * u) / (a * a) + (v * v) / (b * b) <= 1;
              },
              {type: 'ellipse', x: cx, y: cy, angle: angle, length: length, width: width});
}

function addLeaf(target, canvas, x, y, angle, length, width) {
  // An elliptical leaf whose base is at (x, y), pointing along `angle`.
  return addEllipse(target, canvas, x + 0.5 * length * Math.cos(angle),
                    y + 0.5 * length * Math.sin(angle), angle, length, width);
}

function addDisc(target, canvas, x, y, radius) {
  return draw(target, canvas, x - radius, x + radius, y - radius, y + radius,
              function(px, py) { return (px - x) * (px - x) + (py - y) * (py - y) <= radius * radius; },
              {type: 'disc', x: x, y: y, radius: radius});
}

function similarity(target, canvas) {
  return canvas.gainTotal / target.filledWeight;
}

function logLikelihood(target, canvas) {
  best.factors += 1;  // one per emit: the factor count, comparable with procmod's particle-steps
  var d = similarity(target, canvas) - 1;
  var ll = -(d * d) / (SIGMA * SIGMA);
  var b = canvas.bbox;
  if (b !== null) {
    var ex = (Math.max(0, XMIN - b[0]) + Math.max(0, b[1] - XMAX)) / (XMAX - XMIN);
    var ey = (Math.max(0, YMIN - b[2]) + Math.max(0, b[3] - YMAX)) / (YMAX - YMIN);
    ll -= (ex * ex + ey * ey) / (OOB_SIGMA * OOB_SIGMA);
  }
  return ll;
}

// The best complete output seen (by the program's own similarity), kept outside the
// particles: every particle that finishes reports here, as procmod's engines offer every
// complete derivation to their tracker.
var best = {similarity: -Infinity, canvas: null, finished: 0, factors: 0};

function finished(target, canvas) {
  best.finished += 1;
  var s = similarity(target, canvas);
  if (s > best.similarity) {
    best.similarity = s;
    best.canvas = canvas;
  }
  return s;
}

function geometryList(canvas) {
  var out = [];
  for (var g = canvas === null ? null : canvas.geometry; g !== null; g = g.rest) {
    out.push(g.primitive);
  }
  return out.reverse();
}

// Seconds on a monotonic clock with sub-microsecond resolution: lodash's _.now() is
// Date.now(), whole milliseconds, as long as a short run's whole Infer call.
function clock() {
  return Number(process.hrtime.bigint()) / 1e9;
}

function writeResult(path, extra) {
  var result = {similarity: best.similarity, finished: best.finished, factors: best.factors,
                geometry: geometryList(best.canvas)};
  for (var key in extra) { result[key] = extra[key]; }
  var tmp = path + '.tmp';
  fs.writeFileSync(tmp, JSON.stringify(result));
  fs.renameSync(tmp, path);
  return result.similarity;
}

module.exports = {
  loadTarget: loadTarget, emptyCanvas: emptyCanvas, addSegment: addSegment, addLeaf: addLeaf,
  addDisc: addDisc, similarity: similarity, logLikelihood: logLikelihood, finished: finished,
  writeResult: writeResult, clock: clock
};
