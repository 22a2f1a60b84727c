// The studio's 3-D viewer: the merged model (binary STL from /api/model.stl) and each view's
// points (/api/view/N/points, the view's camera frame), turned with the mouse (three.js's orbit
// controls). window.studioViewer tells tests what it shows.
import * as THREE from "three";
import { OrbitControls } from "orbit";

const token = new URLSearchParams(location.search).get("token");
const withToken = (url) => (token ? `${url}${url.includes("?") ? "&" : "?"}token=${token}` : url);
const box = document.getElementById("viewer");
const renderer = new THREE.WebGLRenderer({ antialias: true, preserveDrawingBuffer: true });
renderer.setPixelRatio(window.devicePixelRatio || 1);
box.appendChild(renderer.domElement);
const scene = new THREE.Scene();
scene.background = new THREE.Color(0x1e2328);
const camera = new THREE.PerspectiveCamera(40, 4 / 3, 1, 20000);
const controls = new OrbitControls(camera, renderer.domElement);
scene.add(new THREE.HemisphereLight(0xffffff, 0x445566, 1.2));
const sun = new THREE.DirectionalLight(0xffffff, 1.5);
scene.add(sun);

/** What the viewer shows: `model` (triangles), `view` (its number, from 1) and `points`. */
window.studioViewer = { model: 0, view: 0, points: 0, error: null };
let shown = null;

function resize() {
  const w = box.clientWidth || 480;
  const h = Math.round(w * 0.75);
  renderer.setSize(w, h);
  camera.aspect = w / h;
  camera.updateProjectionMatrix();
}

function frame(object) {
  const b = new THREE.Box3().setFromObject(object);
  const c = b.getCenter(new THREE.Vector3());
  const r = Math.max(b.getSize(new THREE.Vector3()).length() / 2, 1);
  controls.target.copy(c);
  camera.position.copy(c).add(new THREE.Vector3(0, -r * 0.6, -r * 2.4));
  camera.up.set(0, -1, 0);
  camera.near = r / 100;
  camera.far = r * 100;
  camera.updateProjectionMatrix();
  sun.position.copy(camera.position);
  controls.update();
}

function show(object) {
  if (shown) {
    scene.remove(shown);
    shown.geometry.dispose();
  }
  shown = object;
  scene.add(object);
  frame(object);
}

/** Triangles of a binary STL: 80 bytes, a u32 count, then 50 bytes each. */
function stlGeometry(buf) {
  const dv = new DataView(buf);
  const n = buf.byteLength >= 84 ? dv.getUint32(80, true) : 0;
  if (84 + n * 50 > buf.byteLength) throw new Error("the model file is cut short");
  const pos = new Float32Array(n * 9);
  for (let i = 0; i < n; i++) {
    for (let k = 0; k < 9; k++) pos[i * 9 + k] = dv.getFloat32(84 + i * 50 + 12 + k * 4, true);
  }
  const g = new THREE.BufferGeometry();
  g.setAttribute("position", new THREE.BufferAttribute(pos, 3));
  g.computeVertexNormals();
  return [g, n];
}

async function showModel() {
  const r = await fetch(withToken("/api/model.stl"));
  if (!r.ok) { window.studioViewer.error = (await r.json()).refused; return; }
  const [g, n] = stlGeometry(await r.arrayBuffer());
  show(new THREE.Mesh(g, new THREE.MeshStandardMaterial({ color: 0xc8c3b8, roughness: 0.7, side: THREE.DoubleSide })));
  Object.assign(window.studioViewer, { model: n, view: 0, points: 0, error: null });
}

async function showView(n) {
  const r = await fetch(withToken(`/api/view/${n}/points`));
  if (!r.ok) { window.studioViewer.error = (await r.json()).refused; return; }
  const v = await r.json();
  const g = new THREE.BufferGeometry();
  g.setAttribute("position", new THREE.BufferAttribute(new Float32Array(v.points), 3));
  show(new THREE.Points(g, new THREE.PointsMaterial({ color: 0x9fd3ff, size: 1.2 })));
  Object.assign(window.studioViewer, { model: 0, view: n, points: v.points.length / 3, error: null });
}

/** The viewer's buttons: the model, then one per view. */
window.studioViewerButtons = (views, merged) => {
  const bar = document.getElementById("viewer-buttons");
  const want = (merged ? ["model"] : []).concat(views.map((_, k) => String(k + 1)));
  if (bar.dataset.shown === want.join(",")) return;
  bar.dataset.shown = want.join(",");
  bar.textContent = "";
  for (const w of want) {
    const b = document.createElement("button");
    b.id = w === "model" ? "viewer-model" : `viewer-view-${w}`;
    b.textContent = w === "model" ? "The model" : `View ${w}`;
    b.onclick = () => (w === "model" ? showModel() : showView(Number(w))).catch((e) => (window.studioViewer.error = String(e)));
    bar.appendChild(b);
  }
};

resize();
window.addEventListener("resize", resize);
renderer.setAnimationLoop(() => renderer.render(scene, camera));
