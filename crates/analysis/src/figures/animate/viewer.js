// The jointplay animation viewer: draws the mechanism of a run in 3D on a 2D canvas and, for
// each clearance joint, the journal centre's orbit in its magnified clearance.
//
// Written for this page rather than taken from a 3D library: the page must open from a file
// with no network and stay small, and a WebGL library's software fallback is missing from many
// headless and remote browsers. The parts (triangle meshes in each body's axes, written by
// jointplay) are flat-shaded and drawn far to near (the painter's algorithm), which is exact for
// the convex, separate parts a mechanism is drawn with.
//
// Data (the JSON in #jointplay-data): every array is little-endian base64. Frames k = 0..n-1 at
// `time` (float64, s); `poses` (float32) per frame and drawn body the centre-of-mass position
// relative to `origin` (m) and the Euler parameters (w, x, y, z); `orbits` (float32) per frame
// and clearance joint u, w (m, housing axes) and the sum of its normal forces (N); `contact`
// (uint8) per frame and joint 1 while any of its contacts is closed.
(function () {
  'use strict';
  const errors = [];
  window.addEventListener('error', (e) => errors.push(String(e.message)));

  const D = JSON.parse(document.getElementById('jointplay-data').textContent);

  function decode(text, Type) {
    const bin = atob(text);
    const bytes = new Uint8Array(bin.length);
    for (let i = 0; i < bin.length; i++) bytes[i] = bin.charCodeAt(i);
    return new Type(bytes.buffer);
  }

  const time = decode(D.time, Float64Array);
  const poses = decode(D.poses, Float32Array);
  const orbits = decode(D.orbits, Float32Array);
  const contact = decode(D.contact, Uint8Array);
  const nFrames = time.length;
  const nBodies = D.bodies.length;
  const nJoints = D.joints.length;
  const t0 = time[0];
  const t1 = time[nFrames - 1];

  function meshes(list) {
    return list.map((m) => ({
      color: m.color,
      opacity: m.opacity,
      v: decode(m.vertices, Float32Array),
      t: decode(m.triangles, Uint32Array),
    }));
  }
  const bodies = D.bodies.map((b) => ({ name: b.name, meshes: meshes(b.meshes) }));
  const ground = meshes(D.ground);

  // ---- vectors -------------------------------------------------------------------------------
  const sub = (a, b) => [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
  const add = (a, b) => [a[0] + b[0], a[1] + b[1], a[2] + b[2]];
  const scale = (a, s) => [a[0] * s, a[1] * s, a[2] * s];
  const dot = (a, b) => a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
  const cross = (a, b) => [
    a[1] * b[2] - a[2] * b[1],
    a[2] * b[0] - a[0] * b[2],
    a[0] * b[1] - a[1] * b[0],
  ];
  const unit = (a) => scale(a, 1 / Math.hypot(a[0], a[1], a[2]));

  // The rotation matrix (rows) of the Euler parameters (w, x, y, z).
  function rotation(w, x, y, z) {
    const n = Math.hypot(w, x, y, z) || 1;
    w /= n; x /= n; y /= n; z /= n;
    return [
      1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y),
      2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x),
      2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y),
    ];
  }

  // ---- time ----------------------------------------------------------------------------------
  // The frame k with time[k] <= t < time[k + 1] (the last but one at the end), by bisection.
  function frameAt(t) {
    let lo = 0;
    let hi = nFrames - 1;
    if (t <= time[0]) return 0;
    if (t >= time[hi]) return Math.max(hi - 1, 0);
    while (hi - lo > 1) {
      const mid = (lo + hi) >> 1;
      if (time[mid] <= t) lo = mid; else hi = mid;
    }
    return lo;
  }

  // The frame nearest t (the last one at the end): what the insets show, without interpolation.
  function frameNear(t) {
    const k = frameAt(t);
    if (k + 1 < nFrames && time[k + 1] - t < t - time[k]) return k + 1;
    return k;
  }

  // Body b's position and rotation at time t: positions interpolated linearly, Euler
  // parameters normalised linearly (the frames are close enough for the difference from a
  // spherical interpolation to be far below a pixel).
  function pose(b, t) {
    const k = frameAt(t);
    const k1 = Math.min(k + 1, nFrames - 1);
    const span = time[k1] - time[k];
    const f = span > 0 ? Math.min(Math.max((t - time[k]) / span, 0), 1) : 0;
    const a = (k * nBodies + b) * 7;
    const c = (k1 * nBodies + b) * 7;
    const p = [0, 1, 2].map((i) => poses[a + i] + f * (poses[c + i] - poses[a + i]));
    let sign = 0;
    for (let i = 3; i < 7; i++) sign += poses[a + i] * poses[c + i];
    const s = sign < 0 ? -1 : 1;
    const q = [3, 4, 5, 6].map((i) => poses[a + i] + f * (s * poses[c + i] - poses[a + i]));
    return { p, r: rotation(q[0], q[1], q[2], q[3]) };
  }

  // ---- layout --------------------------------------------------------------------------------
  const view = document.getElementById('view');
  const ctx = view.getContext('2d');
  const insets = document.getElementById('insets');
  const slider = document.getElementById('scrub');
  const playButton = document.getElementById('play');
  const speedSelect = document.getElementById('speed');
  const clock = document.getElementById('clock');

  document.getElementById('title').textContent = D.title;
  document.getElementById('note').textContent = D.note;

  for (const f of [0.01, 0.1, 0.25, 0.5, 1, 2, 4, 10]) {
    const o = document.createElement('option');
    const s = D.speed * f;
    o.value = String(s);
    o.textContent = s >= 1 ? Number(s.toPrecision(3)) + ' x real time'
      : '1/' + Number((1 / s).toPrecision(3)) + ' of real time';
    if (f === 1) o.selected = true;
    speedSelect.appendChild(o);
  }

  const joints = D.joints.map((j, i) => {
    const box = document.createElement('div');
    box.className = 'inset';
    const head = document.createElement('div');
    head.className = 'inset-title';
    head.textContent = j.title;
    const canvas = document.createElement('canvas');
    canvas.width = 240;
    canvas.height = 240;
    const foot = document.createElement('div');
    foot.className = 'inset-foot';
    box.appendChild(head);
    box.appendChild(canvas);
    box.appendChild(foot);
    insets.appendChild(box);
    return { spec: j, index: i, canvas, foot };
  });
  if (nJoints === 0) insets.style.display = 'none';

  // ---- camera --------------------------------------------------------------------------------
  const up = unit(D.view.up);
  const h1 = unit(D.view.across);
  const h2 = cross(up, h1);
  const camera = {
    az: 0,
    el: D.view.elevation,
    dist: D.view.distance,
    target: D.view.target,
  };
  function resetCamera() {
    camera.az = 0;
    camera.el = D.view.elevation;
    camera.dist = D.view.distance;
  }

  // The camera's axes and position.
  function cameraFrame() {
    const ce = Math.cos(camera.el);
    const eye = add(
      add(scale(h1, ce * Math.cos(camera.az)), scale(h2, ce * Math.sin(camera.az))),
      scale(up, Math.sin(camera.el)),
    );
    const forward = scale(eye, -1);
    let right = cross(forward, up);
    if (Math.hypot(right[0], right[1], right[2]) < 1e-9) right = h2;
    right = unit(right);
    const camUp = cross(right, forward);
    return { pos: add(camera.target, scale(eye, camera.dist)), forward, right, camUp };
  }

  // ---- drawing the mechanism ----------------------------------------------------------------
  const light = unit([0.4, 0.7, 1.0]);

  function shade(color, opacity, intensity) {
    const c = color.map((x) => Math.round(Math.min(255, x * intensity)));
    return opacity < 1 ? `rgba(${c[0]},${c[1]},${c[2]},${opacity})` : `rgb(${c[0]},${c[1]},${c[2]})`;
  }

  // Appends the screen triangles of `mesh` placed at (p, r) to `out`.
  function project(mesh, p, r, cam, focal, cx, cy, out) {
    const v = mesh.v;
    const n = v.length / 3;
    const sx = new Float32Array(n);
    const sy = new Float32Array(n);
    const vz = new Float32Array(n);
    const world = new Float32Array(3 * n);
    for (let i = 0; i < n; i++) {
      const x = v[3 * i];
      const y = v[3 * i + 1];
      const z = v[3 * i + 2];
      const g = [
        p[0] + r[0] * x + r[1] * y + r[2] * z,
        p[1] + r[3] * x + r[4] * y + r[5] * z,
        p[2] + r[6] * x + r[7] * y + r[8] * z,
      ];
      world[3 * i] = g[0];
      world[3 * i + 1] = g[1];
      world[3 * i + 2] = g[2];
      const d = sub(g, cam.pos);
      const depth = Math.max(dot(d, cam.forward), 1e-6);
      sx[i] = cx + focal * dot(d, cam.right) / depth;
      sy[i] = cy - focal * dot(d, cam.camUp) / depth;
      vz[i] = depth;
    }
    const t = mesh.t;
    for (let k = 0; k < t.length; k += 3) {
      const a = t[k];
      const b = t[k + 1];
      const c = t[k + 2];
      const area = (sx[b] - sx[a]) * (sy[c] - sy[a]) - (sx[c] - sx[a]) * (sy[b] - sy[a]);
      // Counter-clockwise from outside is clockwise on a y-down screen: area < 0 faces us.
      if (mesh.opacity >= 1 && area >= 0) continue;
      const ga = [world[3 * a], world[3 * a + 1], world[3 * a + 2]];
      const gb = [world[3 * b], world[3 * b + 1], world[3 * b + 2]];
      const gc = [world[3 * c], world[3 * c + 1], world[3 * c + 2]];
      let normal = cross(sub(gb, ga), sub(gc, ga));
      const len = Math.hypot(normal[0], normal[1], normal[2]);
      if (len === 0) continue;
      normal = scale(normal, 1 / len);
      // The light comes from over the viewer's shoulder, fixed to the camera.
      const l = add(add(scale(cam.right, light[0]), scale(cam.camUp, light[1])), scale(cam.forward, -light[2]));
      const intensity = 0.45 + 0.65 * Math.abs(dot(normal, l));
      out.push({
        depth: (vz[a] + vz[b] + vz[c]) / 3,
        x: [sx[a], sx[b], sx[c]],
        y: [sy[a], sy[b], sy[c]],
        fill: shade(mesh.color, mesh.opacity, intensity),
      });
    }
  }

  const identity = [1, 0, 0, 0, 1, 0, 0, 0, 1];
  let current = t0;

  function drawView() {
    const w = view.width;
    const h = view.height;
    ctx.fillStyle = '#ffffff';
    ctx.fillRect(0, 0, w, h);
    const cam = cameraFrame();
    const focal = 0.5 * Math.min(w, h) / Math.tan(D.view.half_angle);
    const tris = [];
    const origin = [0, 0, 0];
    for (const m of ground) project(m, origin, identity, cam, focal, w / 2, h / 2, tris);
    for (let b = 0; b < nBodies; b++) {
      const { p, r } = pose(b, current);
      for (const m of bodies[b].meshes) project(m, p, r, cam, focal, w / 2, h / 2, tris);
    }
    tris.sort((a, b) => b.depth - a.depth);
    ctx.lineJoin = 'round';
    ctx.lineWidth = 0.6;
    for (const t of tris) {
      ctx.beginPath();
      ctx.moveTo(t.x[0], t.y[0]);
      ctx.lineTo(t.x[1], t.y[1]);
      ctx.lineTo(t.x[2], t.y[2]);
      ctx.closePath();
      ctx.fillStyle = t.fill;
      ctx.strokeStyle = t.fill;
      ctx.fill();
      ctx.stroke();
    }
  }

  // ---- the insets: orbits in the clearance ---------------------------------------------------
  // Colour of a normal force f: grey while free, then yellow to dark red with f / fMax.
  function forceColor(f, fMax) {
    if (!(f > 0)) return 'rgb(150,150,150)';
    const s = Math.min(1, Math.sqrt(f / (fMax || 1)));
    const r = Math.round(250 - 110 * s);
    const g = Math.round(200 * (1 - s));
    return `rgb(${r},${g},20)`;
  }

  function drawInset(j) {
    const c = j.canvas.getContext('2d');
    const W = j.canvas.width;
    const H = j.canvas.height;
    const spec = j.spec;
    c.fillStyle = '#ffffff';
    c.fillRect(0, 0, W, H);
    const half = 0.42 * Math.min(W, H);
    const k = half / spec.clearance; // px per m
    const cx = W / 2;
    const cy = H / 2;
    c.strokeStyle = '#333333';
    c.lineWidth = 1.5;
    c.beginPath();
    if (spec.outline === 'band') {
      c.moveTo(cx - half * 1.1, cy - half);
      c.lineTo(cx + half * 1.1, cy - half);
      c.moveTo(cx - half * 1.1, cy + half);
      c.lineTo(cx + half * 1.1, cy + half);
    } else if (spec.outline === 'square') {
      c.rect(cx - half, cy - half, 2 * half, 2 * half);
    } else {
      c.arc(cx, cy, half, 0, 2 * Math.PI);
    }
    c.stroke();
    c.strokeStyle = '#dddddd';
    c.lineWidth = 1;
    c.beginPath();
    c.moveTo(cx - half, cy);
    c.lineTo(cx + half, cy);
    c.moveTo(cx, cy - half);
    c.lineTo(cx, cy + half);
    c.stroke();
    c.fillStyle = '#555555';
    c.font = '11px sans-serif';
    c.fillText(spec.axes[0], cx + half + 2, cy - 3);
    c.fillText(spec.axes[1], cx + 3, cy - half - 3);
    const kNow = frameNear(current);
    const from = frameAt(current - D.trail);
    // The screen point of frame f: u to the right, w up (for a slider, w right and u up).
    const at = (f) => {
      const o = (f * nJoints + j.index) * 3;
      const a = orbits[o];
      const b = orbits[o + 1];
      return spec.outline === 'band' ? [cx + k * b, cy - k * a] : [cx + k * a, cy - k * b];
    };
    c.lineWidth = 1.2;
    for (let f = from; f < kNow; f++) {
      const [x0, y0] = at(f);
      const [x1, y1] = at(f + 1);
      c.strokeStyle = forceColor(orbits[(f * nJoints + j.index) * 3 + 2], spec.force_max);
      c.beginPath();
      c.moveTo(x0, y0);
      c.lineTo(x1, y1);
      c.stroke();
    }
    const o = (kNow * nJoints + j.index) * 3;
    const force = orbits[o + 2];
    const [x, y] = at(kNow);
    c.fillStyle = forceColor(force, spec.force_max);
    c.strokeStyle = '#000000';
    c.beginPath();
    c.arc(x, y, 4 + 4 * Math.min(1, Math.sqrt(force / (spec.force_max || 1)) || 0), 0, 2 * Math.PI);
    c.fill();
    c.stroke();
    const state = contact[kNow * nJoints + j.index] ? 'in contact' : 'free';
    j.foot.textContent = `${state}, normal force ${force > 0 ? force.toPrecision(4) : 0} N`;
  }

  function draw() {
    drawView();
    for (const j of joints) drawInset(j);
    clock.textContent = `t = ${current.toFixed(D.digits)} s`;
    slider.value = String(Math.round(1000 * (current - t0) / ((t1 - t0) || 1)));
  }

  // ---- sizing, play, scrub, camera ----------------------------------------------------------
  function resize() {
    const ratio = window.devicePixelRatio || 1;
    const box = view.parentElement.getBoundingClientRect();
    view.width = Math.max(1, Math.floor(box.width * ratio));
    view.height = Math.max(1, Math.floor(box.height * ratio));
    draw();
  }
  window.addEventListener('resize', resize);

  let playing = false;
  let last = null;
  function tick(stamp) {
    if (!playing) return;
    if (last !== null) {
      current += ((stamp - last) / 1000) * Number(speedSelect.value);
      if (current >= t1) current = t0 + (current - t1) % ((t1 - t0) || 1);
    }
    last = stamp;
    draw();
    requestAnimationFrame(tick);
  }
  function setPlaying(on) {
    playing = on;
    playButton.textContent = on ? 'Pause' : 'Play';
    last = null;
    if (on) requestAnimationFrame(tick);
  }
  playButton.addEventListener('click', () => setPlaying(!playing));
  slider.addEventListener('input', () => {
    current = t0 + (Number(slider.value) / 1000) * (t1 - t0);
    draw();
  });
  document.addEventListener('keydown', (e) => {
    if (e.key === ' ') {
      setPlaying(!playing);
      e.preventDefault();
    }
  });

  let drag = null;
  view.addEventListener('pointerdown', (e) => {
    drag = { x: e.clientX, y: e.clientY };
    view.setPointerCapture(e.pointerId);
  });
  view.addEventListener('pointermove', (e) => {
    if (!drag) return;
    camera.az -= (e.clientX - drag.x) * 0.01;
    camera.el = Math.max(-1.55, Math.min(1.55, camera.el + (e.clientY - drag.y) * 0.01));
    drag = { x: e.clientX, y: e.clientY };
    if (!playing) draw();
  });
  view.addEventListener('pointerup', () => { drag = null; });
  view.addEventListener('wheel', (e) => {
    camera.dist *= Math.exp(e.deltaY * 0.001);
    e.preventDefault();
    if (!playing) draw();
  }, { passive: false });
  view.addEventListener('dblclick', () => {
    resetCamera();
    if (!playing) draw();
  });

  // For tests and scripts: the page's clock and its errors.
  window.jointplay = {
    start: t0,
    end: t1,
    frames: nFrames,
    errors,
    time: () => current,
    setTime(t) {
      current = Math.min(Math.max(t, t0), t1);
      draw();
    },
    play: () => setPlaying(true),
    pause: () => setPlaying(false),
  };
  resize();
  window.jointplay.ready = true;
})();
