// The live view: points streamed by scanner-host over a WebSocket, drawn with three.js; the
// finished mesh in their place when the scan ends. Formats: scanner-host/src/live/.
import * as THREE from 'three';
import { OrbitControls } from 'orbit';

const params = new URLSearchParams(location.search);
const token = params.get('t');
const Q = token ? '?t=' + encodeURIComponent(token) : '';
// Points drawn at most (the page's memory is bounded: past it the drawn points are thinned by
// half). `?cap=N` lowers or raises it (1 000 … 5 000 000).
const CAP = Math.max(1000, Math.min(5000000, Number(params.get('cap')) || 1000000));
const HIGHLIGHT = 65536;

const $ = (id) => document.getElementById(id);
const fmt = (n) => Math.round(n).toLocaleString('en');

const canvas = $('view');
const renderer = new THREE.WebGLRenderer({ canvas, antialias: true, preserveDrawingBuffer: true });
renderer.setPixelRatio(window.devicePixelRatio || 1);
const scene = new THREE.Scene();
scene.background = new THREE.Color(0x1d2128);
const camera = new THREE.PerspectiveCamera(45, 1, 1, 50000);
camera.position.set(0, 150, 900);
const controls = new OrbitControls(camera, canvas);
controls.enableDamping = true;
controls.addEventListener('start', () => { userMoved = true; });

const vertexShader = `
  attribute vec3 rgb;
  uniform float mode, zmin, zmax, size, bright;
  varying vec3 vColour;
  vec3 turbo(float x) {
    x = clamp(x, 0.0, 1.0);
    vec4 v4 = vec4(1.0, x, x * x, x * x * x);
    vec2 v2 = v4.zw * v4.z;
    return vec3(
      dot(v4, vec4(0.13572138, 4.61539260, -42.66032258, 132.13108234)) + dot(v2, vec2(-152.94239396, 59.28637943)),
      dot(v4, vec4(0.09140261, 2.19418839, 4.84296658, -14.18503333)) + dot(v2, vec2(4.27729857, 2.82956604)),
      dot(v4, vec4(0.10667330, 12.64194608, -60.58204836, 110.36276771)) + dot(v2, vec2(-89.90310912, 27.34824973)));
  }
  void main() {
    float t = (position.z - zmin) / max(zmax - zmin, 1e-3);
    vColour = mix(turbo(t), rgb, mode);
    vColour = mix(vColour, vec3(1.0), bright);
    vec4 mv = modelViewMatrix * vec4(position, 1.0);
    gl_Position = projectionMatrix * mv;
    gl_PointSize = size;
  }`;
const fragmentShader = `
  varying vec3 vColour;
  void main() { gl_FragColor = vec4(vColour, 1.0); }`;

function pointLayer(capacity, size, bright) {
  const geometry = new THREE.BufferGeometry();
  const xyz = new Float32Array(capacity * 3);
  const rgb = new Uint8Array(capacity * 3);
  geometry.setAttribute('position', new THREE.BufferAttribute(xyz, 3).setUsage(THREE.DynamicDrawUsage));
  geometry.setAttribute('rgb', new THREE.BufferAttribute(rgb, 3, true).setUsage(THREE.DynamicDrawUsage));
  geometry.setDrawRange(0, 0);
  const material = new THREE.ShaderMaterial({
    vertexShader, fragmentShader,
    uniforms: {
      mode: { value: 0 }, zmin: { value: -100 }, zmax: { value: 100 },
      size: { value: size * (window.devicePixelRatio || 1) }, bright: { value: bright },
    },
  });
  const points = new THREE.Points(geometry, material);
  points.frustumCulled = false;
  scene.add(points);
  return { geometry, xyz, rgb, material, points, n: 0 };
}

const cloud = pointLayer(CAP, 2, 0);
const last = pointLayer(HIGHLIGHT, 4, 0.6);
let received = 0;
let colourMode = 0;
let hasColour = false;
// A reservoir sample of the points: the depth colours' range and the framing come from its
// percentiles, so that a few stray points neither wash out the colours nor shrink the object.
const SAMPLE = 4096;
const sample = [];
let seen = 0;
let fitted = 0;
let userMoved = false;
let meshShown = false;

// Keeps every second drawn point.
function thin(layer) {
  let k = 0;
  for (let i = 0; i < layer.n; i += 2, k++) {
    layer.xyz.copyWithin(3 * k, 3 * i, 3 * i + 3);
    layer.rgb.copyWithin(3 * k, 3 * i, 3 * i + 3);
  }
  layer.n = k;
}

function upload(layer) {
  const g = layer.geometry;
  g.attributes.position.needsUpdate = true;
  g.attributes.rgb.needsUpdate = true;
  g.setDrawRange(0, layer.n);
}

function addPoints(buf) {
  const view = new DataView(buf);
  if (buf.byteLength < 8 || view.getUint8(0) !== 1) return;
  const colour = (view.getUint8(1) & 1) === 1;
  const count = view.getUint32(4, true);
  if (buf.byteLength !== 8 + count * 15) return;
  const xyz = new Float32Array(buf, 8, count * 3);
  const rgb = new Uint8Array(buf, 8 + count * 12, count * 3);
  received += count;
  hasColour = hasColour || colour;
  // Every point goes in (thinning what is drawn when full); a batch larger than the whole
  // capacity is taken with a stride.
  const stride = Math.ceil(count / CAP);
  for (let i = 0; i < count; i += stride) {
    if (cloud.n >= CAP) thin(cloud);
    const k = cloud.n++;
    cloud.xyz[3 * k] = xyz[3 * i];
    cloud.xyz[3 * k + 1] = xyz[3 * i + 1];
    cloud.xyz[3 * k + 2] = xyz[3 * i + 2];
    cloud.rgb[3 * k] = rgb[3 * i];
    cloud.rgb[3 * k + 1] = rgb[3 * i + 1];
    cloud.rgb[3 * k + 2] = rgb[3 * i + 2];
    seen++;
    const j = sample.length < SAMPLE ? sample.length : Math.floor(Math.random() * seen);
    if (j < SAMPLE) sample[j] = [xyz[3 * i], xyz[3 * i + 1], xyz[3 * i + 2]];
  }
  const box = robustBox(sample);
  upload(cloud);
  // The latest batch, highlighted.
  const m = Math.min(count, HIGHLIGHT);
  last.xyz.set(xyz.subarray(3 * (count - m)));
  last.rgb.set(rgb.subarray(3 * (count - m)));
  last.n = m;
  upload(last);
  for (const layer of [cloud, last]) {
    layer.material.uniforms.zmin.value = box.min.z;
    layer.material.uniforms.zmax.value = box.max.z;
  }
  // Frame the object as it grows, until the user takes the view in hand.
  const size = box.getSize(new THREE.Vector3()).length();
  if (!userMoved && received > 500 && Math.abs(size - fitted) > 0.15 * fitted) {
    fit(box);
    fitted = size;
  }
  $('points').textContent = fmt(received);
  $('stored').textContent = fmt(cloud.n);
  document.body.dataset.points = String(received);
  document.body.dataset.stored = String(cloud.n);
}

// The box of the sample's 2nd to 98th percentiles on each axis.
function robustBox(points) {
  const b = new THREE.Box3();
  if (points.length === 0) return b;
  const lo = [], hi = [];
  for (let a = 0; a < 3; a++) {
    const v = points.map((p) => p[a]).sort((x, y) => x - y);
    lo.push(v[Math.floor(0.02 * (v.length - 1))]);
    hi.push(v[Math.ceil(0.98 * (v.length - 1))]);
  }
  b.min.set(lo[0], lo[1], lo[2]);
  b.max.set(hi[0], hi[1], hi[2]);
  return b;
}

function fit(b) {
  if (b.isEmpty()) return;
  const centre = b.getCenter(new THREE.Vector3());
  const size = b.getSize(new THREE.Vector3()).length();
  controls.target.copy(centre);
  camera.position.copy(centre).add(new THREE.Vector3(0, 0.4 * size, 1.9 * size));
  camera.near = Math.max(0.1, size / 1000);
  camera.far = size * 100;
  camera.updateProjectionMatrix();
  controls.update();
}

let colourChosen = false;
function showStatus(s) {
  if (s.failed) {
    $('state').textContent = 'stopped: ' + s.ended;
    $('state').className = 'figure state-lost';
    $('done-title').textContent = 'No model';
  } else {
    $('state').textContent = s.state === 'done' ? 'done (' + s.ended + ')' : s.state;
    $('state').className = 'figure' + (s.state === 'done' ? ' state-done' : '');
  }
  if (s.colouring === 'points' && !colourChosen) setColouring(1);
  if (s.kind === 'merge') {
    // merge: the views in their colours, then the model; no scan figures.
    $('title').textContent = 'Merging views';
    if (!s.failed) $('done-title').textContent = 'Model done';
    $('scan-figures').hidden = true;
    last.points.visible = false;
    return;
  }
  $('fps').textContent = s.fps > 0 ? s.fps.toFixed(1) : '–';
  $('pps').textContent = fmt(s.points_per_s);
  $('frames').textContent = fmt(s.frames);
  $('rms').textContent = s.plane_rms_mm == null ? '–' : s.plane_rms_mm.toFixed(3) + ' mm';
  $('link').textContent = fmt(s.link_rejected);
  const list = $('skipped');
  list.replaceChildren(...s.skipped.map((r) => {
    const li = document.createElement('li');
    li.textContent = r.reason + ': ' + fmt(r.frames);
    return li;
  }));
  $('skipped-total').textContent = fmt(s.skipped.reduce((a, r) => a + r.frames, 0));
  $('hint').textContent = s.hint || '';
  $('notice').textContent = s.notice || '';
  document.body.dataset.notice = s.notice_kind || '';
  document.body.dataset.fps = String(s.fps);
}

// A preview picture: the thumbnail, the dots as rings, the laser line in red.
let previews = 0;
function showPreview(p) {
  $('preview-box').hidden = false;
  $('scan-figures').hidden = true;
  $('title').textContent = 'Preview';
  const c = $('preview');
  const zoom = 3;
  c.width = p.width * zoom;
  c.height = p.height * zoom;
  const g = c.getContext('2d');
  const img = g.createImageData(p.width, p.height);
  const luma = atob(p.pixels);
  for (let i = 0; i < p.width * p.height; i++) {
    const v = luma.charCodeAt(i);
    img.data[4 * i] = v;
    img.data[4 * i + 1] = v;
    img.data[4 * i + 2] = v;
    img.data[4 * i + 3] = 255;
  }
  // Drawn at the thumbnail's size, then scaled up: the marks stay sharp on top.
  const small = document.createElement('canvas');
  small.width = p.width;
  small.height = p.height;
  small.getContext('2d').putImageData(img, 0, 0);
  g.imageSmoothingEnabled = false;
  g.drawImage(small, 0, 0, c.width, c.height);
  g.strokeStyle = '#4cc9f0';
  g.lineWidth = 1.5;
  for (const [x, y] of p.markers) {
    g.beginPath();
    g.arc((x + 0.5) * zoom, (y + 0.5) * zoom, 2.5 * zoom, 0, 2 * Math.PI);
    g.stroke();
  }
  g.fillStyle = '#ff3b3b';
  let lit = 0;
  p.stripe.forEach((at, i) => {
    if (at === 255) return;
    lit++;
    const [x, y] = p.rows ? [at, i] : [i, at];
    g.fillRect(x * zoom, y * zoom, zoom, zoom);
  });
  $('preview-dots').textContent = fmt(p.markers.length);
  $('preview-laser').textContent = lit > 0 ? '+' + p.laser_dn + ' DN' : 'no line found';
  $('preview-clipped').textContent = p.clipped_percent.toFixed(1) + ' %';
  const states = {
    points: 'takes ' + p.points + ' points',
    skipped: 'skips it',
    no_calibration: 'needs --calibration to tell',
    laser_in_reference: 'waits for a laser-off reference',
  };
  $('preview-state').textContent = states[p.state] || p.state;
  $('preview-why').textContent = [p.skip, p.hint].filter(Boolean).join(': ');
  previews++;
  Object.assign(document.body.dataset, {
    previews: String(previews),
    previewDots: String(p.markers.length),
    previewLit: String(lit),
    previewState: p.state,
    previewSkip: p.skip || '',
  });
}

async function showFinished(s) {
  showStatus(s);
  const links = $('links');
  const pictures = $('pictures');
  links.replaceChildren();
  pictures.replaceChildren();
  for (const f of s.files) {
    if (!f.held) continue;
    const a = document.createElement('a');
    a.href = '/files/' + f.name + Q;
    a.download = f.name;
    a.textContent = f.name + ' (' + (f.bytes / 1e6).toFixed(1) + ' MB)';
    links.append(a);
    if (f.name.endsWith('.png')) {
      const img = document.createElement('img');
      img.src = a.href;
      img.alt = f.name;
      pictures.append(img);
    }
  }
  $('meshinfo').textContent = s.failed ? '' : fmt(s.vertices) + ' vertices, ' + fmt(s.faces) + ' triangles';
  if (previews > 0 && !(s.faces > 0)) {
    $('done-title').textContent = 'Preview ended';
    $('meshinfo').textContent = '';
  }
  $('finished').hidden = false;
  document.body.dataset.downloads = String(links.children.length);
  if (s.faces > 0) {
    const res = await fetch('/mesh.bin' + Q);
    if (res.ok) showMesh(await res.arrayBuffer());
  }
}

function showMesh(buf) {
  const v = new DataView(buf);
  const nv = v.getUint32(0, true);
  const nf = v.getUint32(4, true);
  const colour = v.getUint8(8) === 1;
  const need = 12 + nv * 12 + nf * 12 + (colour ? nv * 3 : 0);
  if (buf.byteLength !== need) return;
  const geometry = new THREE.BufferGeometry();
  geometry.setAttribute('position', new THREE.BufferAttribute(new Float32Array(buf, 12, nv * 3), 3));
  geometry.setIndex(new THREE.BufferAttribute(new Uint32Array(buf, 12 + nv * 12, nf * 3), 1));
  if (colour) {
    geometry.setAttribute('color', new THREE.BufferAttribute(new Uint8Array(buf, 12 + nv * 12 + nf * 12, nv * 3), 3, true));
  }
  geometry.computeVertexNormals();
  const material = new THREE.MeshStandardMaterial({
    color: colour ? 0xffffff : 0xd9c7a7, vertexColors: colour, side: THREE.DoubleSide,
    roughness: 0.8, metalness: 0.0,
  });
  scene.add(new THREE.Mesh(geometry, material));
  scene.add(new THREE.HemisphereLight(0xffffff, 0x404050, 1.2));
  const sun = new THREE.DirectionalLight(0xffffff, 1.5);
  sun.position.set(1, 2, 3);
  scene.add(sun);
  cloud.points.visible = false;
  last.points.visible = false;
  const pos = geometry.attributes.position.array;
  const some = [];
  const step = Math.max(1, Math.floor(nv / SAMPLE));
  for (let i = 0; i < nv; i += step) some.push([pos[3 * i], pos[3 * i + 1], pos[3 * i + 2]]);
  if (!userMoved) fit(robustBox(some));
  meshShown = true;
  document.body.dataset.mesh = 'shown';
}

function setColouring(mode) {
  colourMode = mode;
  $('colouring').value = String(mode);
  for (const layer of [cloud, last]) layer.material.uniforms.mode.value = colourMode;
}
$('colouring').addEventListener('change', (e) => {
  colourChosen = true;
  setColouring(Number(e.target.value));
});

let done = false;
function connect() {
  const ws = new WebSocket((location.protocol === 'https:' ? 'wss://' : 'ws://') + location.host + '/live' + Q);
  ws.binaryType = 'arraybuffer';
  ws.onopen = () => { if (!done) $('state').textContent = 'waiting for the head…'; };
  ws.onmessage = (e) => {
    if (typeof e.data !== 'string') {
      addPoints(e.data);
      return;
    }
    const s = JSON.parse(e.data);
    if (s.type === 'status') showStatus(s);
    if (s.type === 'preview') showPreview(s);
    if (s.type === 'done') {
      done = true;
      showFinished(s);
    }
  };
  ws.onclose = () => {
    if (done) return;
    $('state').textContent = 'connection lost: retrying…';
    $('state').className = 'figure state-lost';
    setTimeout(connect, 1000);
  };
}

function resize() {
  const w = window.innerWidth;
  const h = window.innerHeight;
  renderer.setSize(w, h, false);
  camera.aspect = w / Math.max(h, 1);
  // On a wide screen the object is centred in the space right of the panel.
  const panel = w > 700 ? $('panel').offsetWidth + 8 : 0;
  if (panel > 0) camera.setViewOffset(w, h, -panel / 2, 0, w, h);
  else camera.clearViewOffset();
  camera.updateProjectionMatrix();
}
window.addEventListener('resize', resize);
resize();

function frame() {
  controls.update();
  renderer.render(scene, camera);
  requestAnimationFrame(frame);
}
requestAnimationFrame(frame);
window.scanView = { get received() { return received; }, get stored() { return cloud.n; }, CAP,
  get mesh() { return meshShown; }, get colour() { return hasColour; } };
connect();
