// SPDX-License-Identifier: BSD-3-Clause
// Interactive 3-D replay of an fnmpc run (docs/replay.md). tools/replay.py writes the run's
// samples into the page as JSON (element #replay-data); this script, bundled with three.js
// into one classic script (no module imports, so the page opens from file:// offline),
// draws them. Frames: world ENU with z up (three.js camera.up = +z), Euler ZYX.
import * as THREE from 'three';
import { OrbitControls } from 'three/examples/jsm/controls/OrbitControls.js';

const FIELDS = 10; // per vehicle and frame, see tools/replay.py: x y z roll pitch yaw err0 err1 formation_error thrust
const TRAIL_SECONDS = 20;
const PALETTE = [0xff8c1a, 0x3fa7ff, 0x5fd35f, 0xe05fd0, 0xf2d13a, 0x41e0c9, 0xff5c5c, 0xa98bff];
// Wake cone: the self-similar round jet of fnmpc/sim/downwash.hpp (half width at the rotor
// plane 0.3 m, spreading rate 0.094 after Pope 2000, ch. 5), drawn 2.5 m long, cut at the ground.
const WAKE_RADIUS = 0.3;
const WAKE_SPREADING = 0.094;
const WAKE_LENGTH = 2.5;

function setStatus(status) {
  document.body.dataset.status = status;
}
window.addEventListener('error', (e) => setStatus('error: ' + e.message));

function decodeFloats(b64) {
  const bin = atob(b64);
  const bytes = new Uint8Array(bin.length);
  for (let i = 0; i < bin.length; ++i) bytes[i] = bin.charCodeAt(i);
  return new Float32Array(bytes.buffer);
}

function errorColor(err, scale, out) {
  // green (0) -> yellow (scale / 2) -> red (>= scale); grey when unknown
  if (!Number.isFinite(err)) return out.setRGB(0.5, 0.5, 0.5);
  const a = Math.min(Math.max(err / scale, 0), 1);
  return a < 0.5 ? out.setRGB(2 * a, 0.85, 0.1) : out.setRGB(1, 0.85 * (2 - 2 * a), 0.1);
}

function makeLabel(text, color) {
  const c = document.createElement('canvas');
  c.width = 256;
  c.height = 64;
  const g = c.getContext('2d');
  g.font = 'bold 34px sans-serif';
  g.fillStyle = '#' + color.toString(16).padStart(6, '0');
  g.textAlign = 'center';
  g.textBaseline = 'middle';
  g.fillText(text, 128, 32);
  const sprite = new THREE.Sprite(
    new THREE.SpriteMaterial({ map: new THREE.CanvasTexture(c), depthTest: false, transparent: true }),
  );
  sprite.scale.set(1.0, 0.25, 1);
  sprite.position.set(0, 0, 0.35);
  return sprite;
}

function makeVehicle(color, arm) {
  const g = new THREE.Group();
  const frameMat = new THREE.MeshStandardMaterial({ color: 0x30343a, roughness: 0.6 });
  for (const angle of [Math.PI / 4, -Math.PI / 4]) {
    const bar = new THREE.Mesh(new THREE.BoxGeometry(2 * arm, 0.03, 0.02), frameMat);
    bar.rotation.z = angle;
    g.add(bar);
  }
  g.add(new THREE.Mesh(new THREE.BoxGeometry(0.14, 0.1, 0.06), new THREE.MeshStandardMaterial({ color })));
  const rotorMat = new THREE.MeshStandardMaterial({ color, transparent: true, opacity: 0.55 });
  for (const [sx, sy] of [[1, 1], [1, -1], [-1, 1], [-1, -1]]) {
    const disc = new THREE.Mesh(new THREE.CylinderGeometry(0.127, 0.127, 0.008, 24), rotorMat);
    disc.rotation.x = Math.PI / 2;
    disc.position.set((sx * arm) / Math.SQRT2, (sy * arm) / Math.SQRT2, 0.02);
    g.add(disc);
  }
  const nose = new THREE.Mesh(new THREE.ConeGeometry(0.035, 0.12, 12), new THREE.MeshStandardMaterial({ color: 0xffffff }));
  nose.rotation.z = -Math.PI / 2; // cone axis +y -> +x (forward)
  nose.position.set(0.13, 0, 0);
  g.add(nose);
  return g;
}

function makeWake(clip) {
  const geo = new THREE.CylinderGeometry(WAKE_RADIUS, WAKE_RADIUS + WAKE_SPREADING * WAKE_LENGTH, WAKE_LENGTH, 32, 1, true);
  geo.rotateX(Math.PI / 2); // axis along z
  geo.translate(0, 0, -WAKE_LENGTH / 2); // from the rotor plane downwards (-b_z)
  const mat = new THREE.MeshBasicMaterial({
    color: 0x7fc8ff, transparent: true, opacity: 0.16, side: THREE.DoubleSide, depthWrite: false,
    clippingPlanes: [clip],
  });
  return new THREE.Mesh(geo, mat);
}

function main() {
  const data = JSON.parse(document.getElementById('replay-data').textContent);
  const t = decodeFloats(data.t);
  const state = decodeFloats(data.state);
  const nv = data.vehicles.length;
  const nf = t.length;
  const at = (f, i, k) => state[(f * nv + i) * FIELDS + k];
  document.getElementById('title').textContent = data.title;

  // Scene.
  const canvas = document.getElementById('view');
  const renderer = new THREE.WebGLRenderer({ canvas, antialias: true, preserveDrawingBuffer: true });
  renderer.setPixelRatio(window.devicePixelRatio || 1);
  renderer.localClippingEnabled = true;
  const scene = new THREE.Scene();
  scene.background = new THREE.Color(0x1d2127);
  scene.add(new THREE.HemisphereLight(0xffffff, 0x404040, 2.0));
  const sun = new THREE.DirectionalLight(0xffffff, 1.5);
  sun.position.set(3, -4, 8);
  scene.add(sun);

  // Extent of the view: every vehicle's start and the leaders' whole flight, so that a
  // vehicle lost far away (a crash, a fall) does not shrink the formation to a dot.
  const lo = new THREE.Vector3(Infinity, Infinity, 0);
  const hi = new THREE.Vector3(-Infinity, -Infinity, 1);
  const include = (f, i) => {
    const p = new THREE.Vector3(at(f, i, 0), at(f, i, 1), at(f, i, 2));
    if (Number.isFinite(p.x + p.y + p.z)) {
      lo.min(p);
      hi.max(p);
    }
  };
  data.vehicles.forEach((v, i) => {
    include(0, i);
    if (v.role === 'leader') for (let f = 0; f < nf; ++f) include(f, i);
  });
  if (!Number.isFinite(lo.x + hi.x)) lo.set(-1, -1, 0), hi.set(1, 1, 1);
  const center = lo.clone().add(hi).multiplyScalar(0.5);
  const extent = Math.max(hi.x - lo.x, hi.y - lo.y, 2) + 4;
  const grid = new THREE.GridHelper(Math.ceil(extent), Math.ceil(extent), 0x8a929c, 0x3a4049);
  grid.rotation.x = Math.PI / 2; // xy plane
  grid.position.set(Math.round(center.x), Math.round(center.y), 0);
  scene.add(grid);
  scene.add(new THREE.AxesHelper(0.5));

  const camera = new THREE.PerspectiveCamera(45, 1, 0.05, 1000);
  camera.up.set(0, 0, 1);
  const target0 = new THREE.Vector3(center.x, center.y, Math.max(center.z, 0.8));
  camera.position.copy(target0).add(new THREE.Vector3(-0.45 * extent, -0.75 * extent, 0.5 * extent));
  const controls = new OrbitControls(camera, canvas);
  controls.target.copy(target0);
  controls.update();

  // Vehicles, trails, wakes, ties.
  const ground = new THREE.Plane(new THREE.Vector3(0, 0, 1), 0);
  const vehicles = data.vehicles.map((v, i) => {
    const color = v.role === 'leader' ? PALETTE[0] : PALETTE[1 + ((i - 1 + PALETTE.length - 1) % (PALETTE.length - 1))];
    const body = makeVehicle(color, data.arm_length || 0.225);
    body.rotation.order = 'ZYX';
    body.add(makeLabel(v.name, color));
    let wake = null;
    if (data.downwash) {
      wake = makeWake(ground);
      body.add(wake);
    }
    scene.add(body);
    const positions = new Float32Array(nf * 3);
    for (let f = 0; f < nf; ++f) {
      positions[3 * f] = at(f, i, 0);
      positions[3 * f + 1] = at(f, i, 1);
      positions[3 * f + 2] = at(f, i, 2);
    }
    const trailGeo = new THREE.BufferGeometry();
    trailGeo.setAttribute('position', new THREE.BufferAttribute(positions, 3));
    const trail = new THREE.Line(trailGeo, new THREE.LineBasicMaterial({ color, transparent: true, opacity: 0.7 }));
    trail.frustumCulled = false;
    scene.add(trail);
    return { ...v, color, body, wake, trail };
  });
  const ties = [];
  data.vehicles.forEach((v, i) => (v.neighbours || []).forEach((j, slot) => ties.push({ i, j, slot })));
  const tieGeo = new THREE.BufferGeometry();
  tieGeo.setAttribute('position', new THREE.BufferAttribute(new Float32Array(ties.length * 6), 3));
  tieGeo.setAttribute('color', new THREE.BufferAttribute(new Float32Array(ties.length * 6), 3));
  const tieLines = new THREE.LineSegments(tieGeo, new THREE.LineBasicMaterial({ vertexColors: true }));
  tieLines.frustumCulled = false;
  scene.add(tieLines);

  // Controls.
  const slider = document.getElementById('slider');
  const playButton = document.getElementById('play');
  const speedSelect = document.getElementById('speed');
  const followSelect = document.getElementById('follow');
  const timeLabel = document.getElementById('time');
  slider.min = t[0];
  slider.max = t[nf - 1];
  slider.step = 'any';
  vehicles.forEach((v, i) => followSelect.add(new Option(v.name, String(i))));
  let time = t[0];
  let playing = false;
  let followed = -1;
  const lastFollow = new THREE.Vector3();
  const trailFrames = Math.max(2, Math.round(TRAIL_SECONDS / Math.max(data.dt, 1e-3)));

  const frameAt = (s) => {
    // largest f with t[f] <= s (binary search), and the blend towards f + 1
    let a = 0;
    let b = nf - 1;
    if (s <= t[0]) return [0, 0];
    if (s >= t[b]) return [b, 0];
    while (b - a > 1) {
      const m = (a + b) >> 1;
      if (t[m] <= s) a = m;
      else b = m;
    }
    return [a, (s - t[a]) / (t[b] - t[a])];
  };
  const sample = (f, w, i, k) => {
    const x0 = at(f, i, k);
    if (w === 0 || f + 1 >= nf) return x0;
    const x1 = at(f + 1, i, k);
    if (k >= 3 && k <= 5) {
      let d = x1 - x0; // angles: shortest way
      d -= 2 * Math.PI * Math.round(d / (2 * Math.PI));
      return x0 + w * d;
    }
    return x0 + w * (x1 - x0);
  };

  const color = new THREE.Color();
  function apply() {
    const [f, w] = frameAt(time);
    vehicles.forEach((v, i) => {
      const x = sample(f, w, i, 0);
      const y = sample(f, w, i, 1);
      const z = sample(f, w, i, 2);
      const ok = Number.isFinite(x + y + z);
      v.body.visible = ok;
      if (ok) {
        v.body.position.set(x, y, z);
        v.body.rotation.set(sample(f, w, i, 3), sample(f, w, i, 4), sample(f, w, i, 5), 'ZYX');
      }
      if (v.wake) v.wake.visible = ok && at(f, i, 9) > 1.0; // rotors producing thrust [N]
      const start = Math.max(0, f - trailFrames);
      v.trail.geometry.setDrawRange(start, f - start + 1);
    });
    const pos = tieGeo.attributes.position.array;
    const col = tieGeo.attributes.color.array;
    ties.forEach((tie, n) => {
      const a = vehicles[tie.i].body.position;
      const b = vehicles[tie.j].body.position;
      pos.set([a.x, a.y, a.z, b.x, b.y, b.z], 6 * n);
      errorColor(at(f, tie.i, 6 + tie.slot), data.error_scale, color);
      col.set([color.r, color.g, color.b, color.r, color.g, color.b], 6 * n);
    });
    tieGeo.attributes.position.needsUpdate = true;
    tieGeo.attributes.color.needsUpdate = true;
    if (followed >= 0) {
      const p = vehicles[followed].body.position;
      const d = p.clone().sub(lastFollow);
      camera.position.add(d);
      controls.target.add(d);
      lastFollow.copy(p);
    }
    slider.value = time;
    timeLabel.textContent = time.toFixed(2) + ' s';
    plot.draw(time);
  }

  // Formation-error plot linked to the slider.
  const plot = makePlot(document.getElementById('plot'), t, nv, vehicles, at, (s) => {
    time = s;
    apply();
  });

  slider.addEventListener('input', () => {
    time = Number(slider.value);
    apply();
  });
  playButton.addEventListener('click', () => {
    if (!playing && time >= t[nf - 1]) time = t[0];
    playing = !playing;
    playButton.textContent = playing ? 'Pause' : 'Play';
  });
  followSelect.addEventListener('change', () => {
    followed = Number(followSelect.value);
    if (followed >= 0) {
      lastFollow.copy(vehicles[followed].body.position);
      const d = lastFollow.clone().sub(controls.target);
      camera.position.add(d);
      controls.target.add(d);
    }
  });

  function resize() {
    const w = canvas.clientWidth;
    const h = canvas.clientHeight;
    renderer.setSize(w, h, false);
    camera.aspect = w / Math.max(h, 1);
    camera.updateProjectionMatrix();
    plot.resize();
  }
  window.addEventListener('resize', resize);
  resize();

  // Start state from the address, e.g. replay.html#t=40&follow=leader&speed=2&play.
  const hash = new URLSearchParams(window.location.hash.slice(1));
  if (hash.has('t')) time = Math.min(Math.max(Number(hash.get('t')) || 0, t[0]), t[nf - 1]);
  if (hash.has('speed')) speedSelect.value = hash.get('speed');
  if (hash.has('follow')) {
    const i = vehicles.findIndex((v) => v.name === hash.get('follow'));
    if (i >= 0) {
      followSelect.value = String(i);
      followSelect.dispatchEvent(new Event('change'));
    }
  }
  if (hash.has('play')) playButton.click();

  let last = performance.now();
  function loop(now) {
    const dt = Math.min((now - last) / 1000, 0.1);
    last = now;
    if (playing) {
      time = Math.min(time + dt * Number(speedSelect.value), t[nf - 1]);
      if (time >= t[nf - 1]) {
        playing = false;
        playButton.textContent = 'Play';
      }
      apply();
    }
    controls.update();
    renderer.render(scene, camera);
    requestAnimationFrame(loop);
  }
  apply();
  renderer.render(scene, camera);

  // For tests and scripts: the present time, seeking, and where each vehicle is drawn.
  window.fnmpcReplay = {
    frames: nf,
    vehicles: nv,
    time: () => time,
    setTime: (s) => {
      time = Math.min(Math.max(s, t[0]), t[nf - 1]);
      apply();
      renderer.render(scene, camera);
    },
    screenPositions: () =>
      vehicles.map((v) => {
        const p = v.body.position.clone().project(camera);
        return [((p.x + 1) / 2) * canvas.clientWidth, ((1 - p.y) / 2) * canvas.clientHeight];
      }),
  };
  requestAnimationFrame(loop);
  window.fnmpcReplay.readyMs = performance.now(); // since navigation start (studies/replay-load-time/replay_load_time.py)
  setStatus('ready');
}

function makePlot(canvas, t, nv, vehicles, at, seek) {
  const g = canvas.getContext('2d');
  const nf = t.length;
  // y range: the largest error, but at most 5 times the 95th percentile, so that one vehicle
  // lost far away does not flatten everybody else's curve (larger values are clipped).
  const errors = [];
  for (let f = 0; f < nf; ++f) {
    for (let i = 0; i < nv; ++i) {
      const e = at(f, i, 8);
      if (Number.isFinite(e)) errors.push(e);
    }
  }
  const sorted = Float64Array.from(errors).sort();
  const p95 = sorted.length ? sorted[Math.floor(0.95 * (sorted.length - 1))] : 0;
  const ymax = Math.max(0.05, Math.min(sorted.length ? sorted[sorted.length - 1] : 0, 5 * p95));
  const pad = { l: 44, r: 8, t: 8, b: 18 };
  let w = 0;
  let h = 0;
  let background = null;
  const xOf = (s) => pad.l + ((s - t[0]) / Math.max(t[nf - 1] - t[0], 1e-9)) * (w - pad.l - pad.r);
  const yOf = (e) => h - pad.b - (Math.min(e, ymax) / ymax) * (h - pad.t - pad.b);
  function drawBackground() {
    g.clearRect(0, 0, w, h);
    g.fillStyle = 'rgba(20,23,28,0.85)';
    g.fillRect(0, 0, w, h);
    g.strokeStyle = '#555';
    g.strokeRect(pad.l, pad.t, w - pad.l - pad.r, h - pad.t - pad.b);
    g.fillStyle = '#bbb';
    g.font = '11px sans-serif';
    g.fillText(ymax.toFixed(2) + ' m', 2, pad.t + 9);
    g.fillText('0', pad.l - 12, h - pad.b);
    g.fillText('formation error of each follower', pad.l + 70, pad.t + 12);
    g.fillText(t[nf - 1].toFixed(0) + ' s', w - pad.r - 30, h - 4);
    vehicles.forEach((v, i) => {
      if (v.role === 'leader') return;
      g.strokeStyle = '#' + v.color.toString(16).padStart(6, '0');
      g.beginPath();
      let pen = false;
      const step = Math.max(1, Math.floor(nf / (2 * w)));
      for (let f = 0; f < nf; f += step) {
        const e = at(f, i, 8);
        if (!Number.isFinite(e)) {
          pen = false;
          continue;
        }
        if (pen) g.lineTo(xOf(t[f]), yOf(e));
        else g.moveTo(xOf(t[f]), yOf(e));
        pen = true;
      }
      g.stroke();
    });
    background = g.getImageData(0, 0, w, h);
  }
  let cursor = t[0];
  function draw(s) {
    cursor = s;
    if (!background) return;
    g.putImageData(background, 0, 0);
    g.strokeStyle = '#fff';
    g.lineWidth = 2;
    g.beginPath();
    g.moveTo(xOf(s), pad.t);
    g.lineTo(xOf(s), h - pad.b);
    g.stroke();
    g.lineWidth = 1;
  }
  function resize() {
    w = canvas.width = canvas.clientWidth;
    h = canvas.height = canvas.clientHeight;
    if (w > 0 && h > 0) {
      drawBackground();
      draw(cursor);
    }
  }
  let dragging = false;
  const seekAt = (ev) => {
    const r = canvas.getBoundingClientRect();
    const a = (ev.clientX - r.left - pad.l) / Math.max(w - pad.l - pad.r, 1);
    seek(t[0] + Math.min(Math.max(a, 0), 1) * (t[nf - 1] - t[0]));
  };
  canvas.addEventListener('pointerdown', (ev) => {
    dragging = true;
    seekAt(ev);
  });
  canvas.addEventListener('pointermove', (ev) => dragging && seekAt(ev));
  window.addEventListener('pointerup', () => (dragging = false));
  return { draw, resize };
}

try {
  main();
} catch (e) {
  setStatus('error: ' + e.message);
  throw e;
}
