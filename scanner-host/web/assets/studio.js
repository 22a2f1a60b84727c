// The studio's page: reads the job (/api/state) a few times a second and draws it; each button
// sends the head a command (/api/command) and shows the answer in words.
"use strict";

const token = new URLSearchParams(location.search).get("token");
const headers = { "Content-Type": "application/json" };
if (token) headers["x-scanner-token"] = token;
const q = (id) => document.getElementById(id);
const withToken = (url) => (token ? `${url}${url.includes("?") ? "&" : "?"}token=${token}` : url);

/** Why the merge left a view out, in the page's words. */
const LEFT_OUT = { left_out: "you unticked it", no_points: "it has no points", not_ended: "its sweep has not ended" };

/** Shots of the target the calibration asks for. */
const TARGET_SHOTS = 6;

/** What the page last read, for tests and the console. */
window.studio = { state: null, lastAnswer: null };

async function post(path, body) {
  const r = await fetch(withToken(path), { method: "POST", headers, body: JSON.stringify(body) });
  let v;
  try { v = await r.json(); } catch { v = { outcome: "error", words: await r.text() }; }
  window.studio.lastAnswer = v;
  q("answer").textContent = v.words || "";
  q("answer").className = v.outcome === "accepted" ? "good" : "bad";
  return v;
}

const send = (command, extra) => post("/api/command", Object.assign({ command }, extra || {}));

/** The part of the camera's picture shown: null for the whole. */
let zoom = null;
const previewOn = () => send("preview", { on: true, every: 2, picture: true, zoom: zoom || [0, 0, 0, 0] });
q("preview-on").onclick = previewOn;
q("preview-off").onclick = () => send("preview", { on: false });
q("laser-on").onclick = () => send("laser", { on: true });
q("laser-off").onclick = () => send("laser", { on: false });
q("shot-target").onclick = () => send("shot", { board: false });
q("shot-board").onclick = () => send("shot", { board: true });
q("calibrate").onclick = () => send("calibrate");
q("sweep").onclick = () => send("sweep", { disc: Number(q("disc").value) });
q("stop").onclick = () => send("stop");
q("turn").onclick = () => send("turn", { steps: 1 });
q("merge").onclick = () => post("/api/merge", { min_overlap: Number(q("min-overlap").value) });
// a click zooms to the camera's full resolution around the point clicked; another, back out
q("picture").onclick = (ev) => {
  const s = window.studio.state && window.studio.state.sharpness;
  if (!s) return;
  if (zoom) {
    zoom = null;
  } else {
    const img = q("picture");
    const [x0, y0, w, h] = s.region;
    const cx = x0 + (ev.offsetX / img.clientWidth) * w;
    const cy = y0 + (ev.offsetY / img.clientHeight) * h;
    const zw = Math.min(w, 320), zh = Math.min(h, 240);
    zoom = [Math.max(0, Math.round(cx - zw / 2)), Math.max(0, Math.round(cy - zh / 2)), zw, zh].map((v) => Math.max(0, v));
  }
  previewOn();
};

const ADVICE = {
  good: "The board, the laser and the exposure are right.",
  too_bright: "Too many pixels are clipped: lower the exposure or the light.",
  board_not_seen: "The board's dots are not seen: aim the camera at both sheets, lit and in focus.",
  laser_in_reference: "The laser was on while the head took its reference: switch it off, then on when told.",
  laser_not_across_board: "The laser line does not cross both sheets: aim it across the crease.",
  laser_not_seen: "No laser line is seen: switch the laser on and aim it at the board.",
  out_of_focus: "The picture is blurred: turn the focus until the edges' width is smallest.",
};

function drawCover(cover, shots) {
  const c = q("cover").getContext("2d");
  c.clearRect(0, 0, 160, 120);
  for (let r = 0; r < 8; r++) {
    for (let k = 0; k < 8; k++) {
      const on = (BigInt(cover) >> BigInt(r * 8 + k)) & 1n;
      c.fillStyle = on ? "#7bc47f" : "#eee";
      c.fillRect(k * 20 + 1, r * 15 + 1, 18, 13);
    }
  }
  // each kept shot's tilt as a dot from the centre
  c.fillStyle = "#2d3b45";
  for (const s of shots) {
    if (!s.kept || s.board) continue;
    c.beginPath();
    c.arc(80 + 1.5 * s.tilt_deg[1], 60 + 1.2 * s.tilt_deg[0], 2.5, 0, 6.3);
    c.fill();
  }
}

function cellsFree(cover) {
  let n = 0;
  for (let i = 0; i < 64; i++) if (!((BigInt(cover) >> BigInt(i)) & 1n)) n++;
  return n;
}

function render(s) {
  window.studio.state = s;
  q("head").textContent = s.link_closed ? "head: the link closed" : s.head.heard ? `head: ${s.head.state}` : "head: not heard yet";
  if (s.head.laser_off_unheard_s != null) q("head").textContent += ` · the head switched the laser off after ${s.head.laser_off_unheard_s} s without the studio: press Laser on to go on`;
  if (s.preview) {
    const p = s.preview;
    const sh = s.sharpness;
    if (!sh) q("picture").src = withToken(`/api/preview.png?frame=${p.frame}`);
    q("focus").textContent = sh
      ? `${sh.region[2]}×${sh.region[3]} at (${sh.region[0]}, ${sh.region[1]}), 1:${sh.scale}${zoom ? " (zoomed: click to go back)" : " (click to zoom)"} · edges ${sh.edge_px == null ? "–" : sh.edge_px.toFixed(1)} px wide (sharp: about 2.5; 8 or more: out of focus)`
      : "";
    q("facts").textContent = `${p.width}×${p.height} (1:${p.scale}) · clipped ${(p.clipped_permille / 10).toFixed(1)} % · dots ${p.markers} · laser on ${p.laser_lines_pct.toFixed(0)} % of the lines, +${p.laser_dn} DN`;
    q("verdict").textContent = p.verdict;
    q("verdict").className = p.verdict === "good" ? "good" : "bad";
    q("advice").textContent = ADVICE[p.verdict] || "";
  }
  const targets = s.shots.filter((x) => x.kept && !x.board).length;
  const boards = s.shots.filter((x) => x.kept && x.board).length;
  drawCover(s.cover, s.shots);
  const more = Math.max(0, TARGET_SHOTS - targets);
  q("asked").dataset.more = String(more + (boards ? 0 : 1));
  q("asked").textContent = more > 0
    ? `Take ${more} more shot(s) of the target: tilt it, and fill the grey cells (${cellsFree(s.cover)} of 64 still empty).`
    : boards === 0 ? "Enough target shots. Now one shot of the board, laser off." : "Enough shots: calibrate.";
  if (s.calibration) {
    const c = s.calibration;
    const f = (v, d) => (v == null ? "–" : v.toFixed(d));
    const img = q("overlay");
    if (c.result === "calibrated" && !img.dataset.shown) {
      img.dataset.shown = "1";
      img.onload = () => { img.style.display = "block"; };
      img.src = withToken(`/api/overlay.png?t=${Date.now()}`);
    }
    q("calibration-result").innerHTML = `<b class="${c.result === "calibrated" ? "good" : "bad"}">${c.result}</b>: ${c.shots} shots, ${f(c.rms_px, 3)} px RMS, halves differ by ${f(c.halves_px, 3)} px; board ${f(c.board_rms_px, 2)} px, sheets at ${f(c.board_angle_deg, 1)}°`;
  }
  const body = q("views").tBodies[0];
  body.innerHTML = "";
  s.views.forEach((v, i) => {
    const tr = body.insertRow();
    for (const t of [i + 1, v.points, v.disc || "not looked for", v.done ? v.ended : "sweeping…"]) tr.insertCell().textContent = t;
    // a view the merge refuses can be left out, and taken back
    const box = document.createElement("input");
    box.type = "checkbox";
    box.id = `merge-view-${i + 1}`;
    box.checked = !v.left_out;
    box.onchange = () => post("/api/view", { view: i + 1, left_out: !box.checked });
    tr.insertCell().appendChild(box);
  });
  const last = s.views[s.views.length - 1];
  q("next").textContent = !last ? "Calibrated? Start the first sweep." : !last.done ? "Sweeping…" : "Turn the disc (or lay the object on its side), then start the next sweep; merge when every side is seen.";
  if (s.merge) {
    const m = s.merge;
    let t = `<b class="${m.state === "merged" ? "good" : "bad"}">${m.state}</b>`;
    if (m.error) t += `: ${m.error}`;
    for (const p of m.problems || []) t += `<br><span class="bad" data-kind="${p.kind}">${p.words}</span>`;
    for (const l of m.left_out || []) t += `<br>View ${l.view} left out: ${LEFT_OUT[l.why] || l.why}`;
    if (m.error && /overlap/.test(m.error)) t += "<br>Take a view between, or lower the least overlap (a side view shares little with the others) and merge again.";
    q("merge-result").innerHTML = t;
    q("downloads").innerHTML = m.files.map((f) => `<a href="${withToken(`/files/${f}`)}" download>${f}</a>`).join(" · ");
    if (m.files.includes("model.png")) q("model").src = withToken("/files/model.png");
  }
  for (const v of s.views) if (v.rebuilt) q("next").textContent = "A view cut when the studio stopped was rebuilt from its journal (see the log).";
  if (window.studioViewerButtons) window.studioViewerButtons(s.views, !!(s.merge && s.merge.files.includes("model.stl")));
  q("log").textContent = s.log.join("\n");
}

/** The picture, fetched again as soon as the last one is shown: as fast as the head sends them. */
window.studio.pictures = 0;
let shownFrame = -1;
let lastUrl = null;
async function pictureLoop() {
  let wait = 20;
  try {
    const s = window.studio.state;
    if (s && s.sharpness && s.head.state === "previewing") {
      const r = await fetch(withToken("/api/picture.jpg"), { headers });
      const frame = Number(r.headers.get("X-Frame"));
      if (r.ok && frame !== shownFrame) {
        const url = URL.createObjectURL(await r.blob());
        q("picture").src = url;
        if (lastUrl) URL.revokeObjectURL(lastUrl);
        lastUrl = url;
        shownFrame = frame;
        window.studio.pictures += 1;
      }
    } else {
      wait = 300;
    }
  } catch (e) {
    wait = 500;
  }
  setTimeout(pictureLoop, wait);
}
pictureLoop();

/** The open view's points, as the studio has them (thinned), and where the page is in them. */
const live = { view: 0, generation: -1, xyz: [] };
window.studio.livePoints = 0;

function drawPoints() {
  const c = q("points").getContext("2d");
  c.clearRect(0, 0, 320, 240);
  const p = live.xyz;
  if (p.length < 3) return;
  let [x0, x1, y0, y1, z0, z1] = [Infinity, -Infinity, Infinity, -Infinity, Infinity, -Infinity];
  for (let i = 0; i < p.length; i += 3) {
    x0 = Math.min(x0, p[i]); x1 = Math.max(x1, p[i]);
    y0 = Math.min(y0, p[i + 1]); y1 = Math.max(y1, p[i + 1]);
    z0 = Math.min(z0, p[i + 2]); z1 = Math.max(z1, p[i + 2]);
  }
  const k = Math.min(300 / Math.max(x1 - x0, 1), 220 / Math.max(y1 - y0, 1));
  for (let i = 0; i < p.length; i += 3) {
    const near = 1 - (p[i + 2] - z0) / Math.max(z1 - z0, 1);
    const v = Math.round(90 + 165 * near);
    c.fillStyle = `rgb(${v},${v},${Math.round(v * 0.8)})`;
    c.fillRect(10 + (p[i] - x0) * k, 10 + (p[i + 1] - y0) * k, 1.5, 1.5);
  }
}

async function pollPoints() {
  try {
    const from = live.xyz.length / 3;
    const r = await fetch(withToken(`/api/points?from=${from}&gen=${live.generation}`), { headers });
    if (r.ok) {
      const v = await r.json();
      if (v.generation !== live.generation || v.from === 0 && from !== 0) live.xyz = [];
      live.generation = v.generation;
      live.view = v.view;
      if (v.points.length) live.xyz.push(...v.points);
      window.studio.livePoints = live.xyz.length / 3;
      drawPoints();
    }
  } catch (e) { /* the next poll tries again */ }
  setTimeout(pollPoints, 400);
}
pollPoints();

async function poll() {
  try {
    const r = await fetch(withToken("/api/state"), { headers });
    if (r.ok) render(await r.json());
  } catch (e) {
    q("head").textContent = "the studio does not answer";
  }
  setTimeout(poll, 300);
}
poll();
