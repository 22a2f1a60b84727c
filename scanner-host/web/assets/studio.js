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
// the camera's controls, by their number on the wire; the box shows what the job keeps
const CONTROLS = [["exposure", 0], ["gain", 1], ["focus-value", 2], ["white-balance", 3]];
const setControl = (control, value) => send("camera", { control, value: Math.round(Number(value)) });
for (const [id, n] of CONTROLS) {
  const set = id === "focus-value" ? "set-focus" : `set-${id}`;
  q(set).onclick = () => setControl(n, q(id).value);
}
q("apply-advice").onclick = () => {
  const a = window.studio.state && window.studio.state.camera_advice;
  if (a && a.value != null) setControl(a.number, a.value);
};
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

/** The coverage map: each cell the target was seen in, green; the guide's regions still
 * missing, outlined orange; each kept shot's tilt as a dot from the centre. */
function drawCover(cover, shots, guide) {
  const c = q("cover").getContext("2d");
  c.clearRect(0, 0, 160, 120);
  for (let r = 0; r < 8; r++) {
    for (let k = 0; k < 8; k++) {
      const on = cover[r * 8 + k] === "1";
      c.fillStyle = on ? "#7bc47f" : "#eee";
      c.fillRect(k * 20 + 1, r * 15 + 1, 18, 13);
    }
  }
  c.strokeStyle = "#e8590c";
  c.lineWidth = 2;
  for (const g of guide ? guide.regions : []) {
    if (g.done) continue;
    const [x0, y0, x1, y1] = g.rect;
    c.strokeRect(x0 * 160 + 1, y0 * 120 + 1, (x1 - x0) * 160 - 2, (y1 - y0) * 120 - 2);
  }
  c.fillStyle = "#2d3b45";
  for (const s of shots) {
    if (!s.kept || s.board) continue;
    c.beginPath();
    c.arc(80 + 1.5 * s.tilt_deg[1], 60 + 1.2 * s.tilt_deg[0], 2.5, 0, 6.3);
    c.fill();
  }
}

/** Where the next target shot should go, drawn over the live picture: the region the guide
 * asks for first, in orange. */
function drawGuideBox(guide) {
  const img = q("picture");
  const box = q("guide-box");
  box.width = img.clientWidth;
  box.height = img.clientHeight;
  const c = box.getContext("2d");
  c.clearRect(0, 0, box.width, box.height);
  const s = window.studio.state;
  const ask = guide && guide.asks.find((a) => a.region != null);
  // only over the whole picture (a zoom shows part of it) while the target is asked for
  if (!ask || zoom || !s.preview || s.calibration) return;
  const [x0, y0, x1, y1] = guide.regions[ask.region].rect;
  c.strokeStyle = "#e8590c";
  c.lineWidth = 3;
  c.setLineDash([8, 5]);
  c.strokeRect(x0 * box.width + 2, y0 * box.height + 2, (x1 - x0) * box.width - 4, (y1 - y0) * box.height - 4);
  c.fillStyle = "#e8590c";
  c.font = "bold 14px system-ui";
  // the label inside the box, on the side away from the picture's edge
  const right = x0 > 0.5;
  c.textAlign = right ? "right" : "left";
  c.fillText("next shot here", right ? x1 * box.width - 8 : x0 * box.width + 8, y0 * box.height + 20);
}

const GRADE = { good: "good", usable: "usable", redo: "redo" };
/** Each figure's name on the page. */
const FIGURE = {
  rms_px: "reprojection error (RMS)",
  halves_px: "two halves' calibrations apart",
  regions: "regions of the picture covered",
  board_rms_px: "sheets' dots off their layout (RMS)",
  board_angle_deg: "angle between the sheets",
  laser_lines_pct: "picture lines the laser crosses",
};

/** The calibration's figures, each with its value, unit, verdict and what to do. */
function drawVerdicts(verdicts) {
  q("verdicts").style.display = verdicts && verdicts.length ? "" : "none";
  const body = q("verdicts").tBodies[0];
  body.innerHTML = "";
  for (const v of verdicts || []) {
    const tr = body.insertRow();
    tr.dataset.part = v.part;
    tr.dataset.figure = v.figure;
    tr.dataset.grade = v.grade;
    const digits = v.unit === "px" ? 3 : v.unit === "of 9" ? 0 : 1;
    const value = v.value == null ? "–" : `${v.value.toFixed(digits)} ${v.unit}`;
    for (const t of [v.part, FIGURE[v.figure] || v.figure, value]) tr.insertCell().textContent = t;
    const g = tr.insertCell();
    g.textContent = GRADE[v.grade] || v.grade;
    g.className = v.grade === "good" ? "good" : v.grade === "usable" ? "usable" : "bad";
    tr.insertCell().textContent = v.words;
  }
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
  // what the job keeps of the camera's controls, unless the maker is typing
  const kept = { exposure: s.camera.exposure, gain: s.camera.gain, "focus-value": s.camera.focus, "white-balance": s.camera.white_balance };
  for (const [id] of CONTROLS) if (document.activeElement !== q(id)) q(id).value = kept[id] == null ? "" : kept[id];
  const a = s.camera_advice;
  q("camera-advice").textContent = a ? a.words : "";
  q("camera-advice").dataset.why = a ? a.why : "";
  q("apply-advice").style.display = a && a.value != null ? "" : "none";
  const g = s.guide;
  // a head started with its calibration sweeps without the guide's shots
  const given = !s.calibration && s.views.length > 0 && s.shots.length === 0;
  drawCover(s.cover, s.shots, given ? null : g);
  drawGuideBox(given ? null : g);
  q("asked").dataset.more = String(given ? 0 : g.asks.length);
  q("asked").dataset.next = given ? "given" : g.asks.length ? g.asks[0].kind : "calibrate";
  q("asked").textContent = given
    ? "The head scans with the calibration it was started with (its --calibration): no shots needed."
    : g.asks.length
    ? `${g.asks[0].words}${g.asks.length > 1 ? ` (then ${g.asks.length - 1} more thing(s) below)` : ""}`
    : `Every region covered by ${g.target_shots} target shots, tilted ${g.tilt_spread_deg[0]}° and ${g.tilt_spread_deg[1]}°, and the board's shot taken: press Calibrate.`;
  q("asks").innerHTML = "";
  for (const a of given ? [] : g.asks.slice(1)) {
    const li = document.createElement("li");
    li.dataset.kind = a.kind;
    li.textContent = a.words;
    q("asks").appendChild(li);
  }
  q("calibrate").className = g.ready ? "" : "waiting";
  q("calibrate").title = g.ready ? "calibrate from the shots taken" : "not yet: the guide still asks for shots";
  if (s.calibration) {
    const c = s.calibration;
    const f = (v, d) => (v == null ? "–" : v.toFixed(d));
    const img = q("overlay");
    if (c.result === "calibrated" && !img.dataset.shown) {
      img.dataset.shown = "1";
      img.onload = () => { img.style.display = "block"; };
      img.src = withToken(`/api/overlay.png?t=${Date.now()}`);
    }
    q("calibration-result").innerHTML = `<b class="${c.result === "calibrated" ? "good" : "bad"}">${c.result}</b> from ${c.shots} target shots`;
    drawVerdicts(s.verdicts);
  }
  const body = q("views").tBodies[0];
  body.innerHTML = "";
  s.views.forEach((v, i) => {
    const tr = body.insertRow();
    tr.dataset.frames = v.frames;
    for (const t of [i + 1, v.frames, v.points, v.disc || "not looked for", v.done ? v.ended : "sweeping…"]) tr.insertCell().textContent = t;
    // a view the merge refuses can be left out, and taken back
    const box = document.createElement("input");
    box.type = "checkbox";
    box.id = `merge-view-${i + 1}`;
    box.checked = !v.left_out;
    box.onchange = () => post("/api/view", { view: i + 1, left_out: !box.checked });
    tr.insertCell().appendChild(box);
    // the view's own model (a fixed-laser turntable's whole model, one view's surface)
    const own = tr.insertCell();
    const m = v.model;
    own.dataset.state = m ? m.state : "";
    if (m && m.state === "made") {
      const fixed = m.summary && m.summary.fixed;
      own.innerHTML = m.files
        .filter((f) => /\.(stl|obj|ply)$/.test(f))
        .map((f) => `<a id="view-${i + 1}-${f.replace(".", "-")}" href="${withToken(`/files/view/${i + 1}/${f}`)}" download>${f}</a>`)
        .join(" ") + (fixed ? ` <span class="${fixed.watertight ? "good" : "bad"}">${fixed.watertight ? "closed" : "not closed"}</span>` : "");
    } else if (m && m.state === "running") {
      own.textContent = "making…";
    } else if (v.done && v.points > 0) {
      const b = document.createElement("button");
      b.id = `view-model-${i + 1}`;
      b.textContent = m && m.state === "failed" ? "again" : "model";
      b.title = m && m.error ? m.error : "the model of this view alone (a turntable's whole model)";
      b.onclick = () => post("/api/view-model", { view: i + 1 });
      own.appendChild(b);
    }
  });
  const last = s.views[s.views.length - 1];
  // what to do next, by kind (for tests and the console) and in words
  const model = last && last.model && last.model.state === "made";
  const [kind, words] = s.sweep_starting ? ["starting", "Starting the sweep: the head takes its reference (the scene as it is, before the laser or the shadow moves)…"]
    : s.sweep_failed ? ["failed", `The last sweep failed before its first frame: ${s.sweep_failed}`]
    : !last ? ["first", "Calibrated? Start the first sweep."]
    : !last.done ? ["sweeping", "Sweeping…"]
    : model ? ["model_ready", `View ${s.views.length}'s model is ready: download it from the table's last column, or take another view.`]
    : ["next_view", "Turn the disc (or lay the object on its side), then start the next sweep; merge when every side is seen."];
  q("next").dataset.kind = kind;
  q("next").textContent = words;
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
  // the log follows its newest line unless the maker scrolled up to read
  const log = q("log");
  const atEnd = log.scrollTop + log.clientHeight >= log.scrollHeight - 4;
  log.textContent = s.log.join("\n");
  if (atEnd) log.scrollTop = log.scrollHeight;
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
