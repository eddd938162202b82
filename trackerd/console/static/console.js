// trackerd console: one WebSocket brings camera images, fixes, status and warnings (docs/console.md).
"use strict";

const SVG = "http://www.w3.org/2000/svg";
const TRAIL = 90;            // hits kept in the wall map's fading trail
const STALE_MS = 2500;       // a camera image older than this is marked as such
const $ = (id) => document.getElementById(id);
const page = { info: null, cards: {}, trail: [], status: null, warnings: 0 };

function el(tag, attrs, parent) {
  const node = document.createElementNS(SVG, tag);
  for (const [k, v] of Object.entries(attrs || {})) node.setAttribute(k, v);
  if (parent) parent.appendChild(node);
  return node;
}

function fmt(v, digits = 1, unit = "") {
  return v === null || v === undefined ? "–" : `${Number(v).toFixed(digits)}${unit}`;
}

// ------------------------------------------------------------------ cameras

function cameraCard(cam) {
  const card = document.createElement("div");
  card.className = "camera";
  card.dataset.camera = cam.id;
  card.dataset.state = "";
  card.dataset.frames = "0";
  card.innerHTML = `<div class="title"><b>${cam.id}</b><span class="state">–</span><span class="rate dim"></span></div>
    <div class="view"><img alt="camera ${cam.id}"><svg viewBox="0 0 ${cam.width_px} ${cam.height_px}" preserveAspectRatio="none"></svg>
    <div class="stale">no pairs</div></div><div class="ends"></div>`;
  $("cameras").appendChild(card);
  return { card, img: card.querySelector("img"), svg: card.querySelector("svg"), ends: card.querySelector(".ends"),
           state: card.querySelector(".state"), rate: card.querySelector(".rate"), url: null, at: 0 };
}

function drawOverlay(view, h) {
  const svg = view.svg;
  svg.setAttribute("viewBox", `0 0 ${h.width_px} ${h.height_px}`);
  svg.replaceChildren();
  for (const run of h.outline_px) {
    el("polyline", { class: "outline", points: run.map((p) => p.join(",")).join(" ") }, svg);
  }
  const names = ["BL", "BR", "TR", "TL"];
  h.corners_px.forEach((c, k) => {
    if (!c) return;
    el("rect", { class: "corner", x: c[0] - 9, y: c[1] - 9, width: 18, height: 18 }, svg);
    const label = el("text", { class: "corner-label", x: c[0] + 14, y: c[1] - 12 }, svg);
    label.textContent = names[k];
  });
  const notes = [];
  for (const colour of ["red", "blue"]) {
    const end = h.ends[colour];
    if (!end.found) { notes.push(`${colour}: ${end.reason}`); continue; }
    const [x0, y0, x1, y1] = end.window_px;
    el("rect", { class: `window window-${colour}`, x: x0, y: y0, width: x1 - x0, height: y1 - y0 }, svg);
    el("circle", { class: `end end-${colour}`, cx: end.x_px, cy: end.y_px, r: end.radius_px + 8,
                   "data-colour": colour, "data-seq": h.sequence, "data-x": end.x_px, "data-y": end.y_px }, svg);
    el("path", { class: "cross", d: `M${end.x_px - 10},${end.y_px}h20M${end.x_px},${end.y_px - 10}v20` }, svg);
    notes.push(`${colour} (${end.x_px.toFixed(1)}, ${end.y_px.toFixed(1)}) px`);
  }
  notes.filter((n) => n.includes(":")).forEach((n, k) => {
    const t = el("text", { class: "reason", x: 20, y: h.height_px - 24 - 52 * k }, svg);
    t.textContent = n;
  });
  view.ends.textContent = `pair ${h.sequence} · ${h.status}${h.reason ? ` (${h.reason})` : ""} · ${h.search || "–"} search · ${notes.join(" · ")}`;
}

function onImage(buffer) {
  const length = new DataView(buffer).getUint32(0);
  const header = JSON.parse(new TextDecoder().decode(new Uint8Array(buffer, 4, length)));
  const view = page.cards[header.camera];
  if (!view) return;
  const url = URL.createObjectURL(new Blob([new Uint8Array(buffer, 4 + length)], { type: "image/jpeg" }));
  const old = view.url;
  view.url = url;
  view.img.onload = () => { if (old) URL.revokeObjectURL(old); };
  view.img.src = url;
  view.img.dataset.seq = header.sequence;
  view.at = performance.now();
  view.card.classList.remove("stale");
  view.card.dataset.frames = String(Number(view.card.dataset.frames) + 1);
  view.card.dataset.seq = header.sequence;
  drawOverlay(view, header);
}

setInterval(() => {
  for (const view of Object.values(page.cards)) {
    view.card.classList.toggle("stale", view.at > 0 && performance.now() - view.at > STALE_MS);
  }
}, 500);

// ------------------------------------------------------------------ wall map

function setupWall(wall) {
  const svg = $("wallmap");
  const margin = 0.05 * Math.max(wall.width_m, wall.height_m);
  svg.setAttribute("viewBox", `${-margin} ${-margin} ${wall.width_m + 2 * margin} ${wall.height_m + 2 * margin}`);
  svg.replaceChildren();
  // Wall coordinates have y up; the SVG's y goes down.
  const g = el("g", { transform: `translate(0 ${wall.height_m}) scale(1 -1)`, id: "wall-frame" }, svg);
  el("rect", { class: "display", x: 0, y: 0, width: wall.width_m, height: wall.height_m }, g);
  for (let x = 0.5; x < wall.width_m; x += 0.5) el("line", { class: "grid", x1: x, y1: 0, x2: x, y2: wall.height_m }, g);
  for (let y = 0.5; y < wall.height_m; y += 0.5) el("line", { class: "grid", x1: 0, y1: y, x2: wall.width_m, y2: y }, g);
  page.trailGroup = el("g", { id: "trail" }, g);
  page.uncertainty = el("circle", { class: "uncertainty", r: 0, cx: -10, cy: -10 }, g);
  page.hit = el("circle", { id: "hit", r: 0.025 * Math.max(wall.width_m, wall.height_m), cx: -10, cy: -10,
                            visibility: "hidden" }, g);
}

function onFixes(messages) {
  let last = null;
  for (const m of messages) {
    if (m.topic === "hit") { page.trail.push(m); last = m; }
    else if (m.topic === "pointer" && m.status !== "hit") { $("hit-text").textContent = `pointer ${m.status}`; }
  }
  while (page.trail.length > TRAIL) page.trail.shift();
  if (!last || !page.hit) return;
  page.hit.setAttribute("cx", last.wall_x_m);
  page.hit.setAttribute("cy", last.wall_y_m);
  page.hit.setAttribute("visibility", "visible");
  page.hit.dataset.seq = last.sequence;
  page.hit.dataset.x = last.wall_x_m;
  page.hit.dataset.y = last.wall_y_m;
  const sigma = (last.uncertainty_mm || 0) / 1000;
  page.uncertainty.setAttribute("cx", last.wall_x_m);
  page.uncertainty.setAttribute("cy", last.wall_y_m);
  page.uncertainty.setAttribute("r", 2 * sigma);
  const n = page.trail.length;
  page.trailGroup.replaceChildren();
  const r = 0.008 * Math.max(page.info.wall.width_m, page.info.wall.height_m);
  page.trail.forEach((h, k) => {
    el("circle", { class: "trail", cx: h.wall_x_m, cy: h.wall_y_m, r, opacity: ((k + 1) / n) * 0.8 }, page.trailGroup);
  });
  const px = last.display_x_px === null ? "" : ` · display (${last.display_x_px.toFixed(0)}, ${last.display_y_px.toFixed(0)}) px`;
  $("hit-text").textContent = `(${last.wall_x_m.toFixed(3)}, ${last.wall_y_m.toFixed(3)}) m ± ${fmt(last.uncertainty_mm, 1, " mm")}${px}${last.on_wall ? "" : " · off the display"}`;
}

// ------------------------------------------------------------------ status

function row(name, value) { return `<tr><td>${name}</td><td>${value}</td></tr>`; }
function esc(text) { return String(text).replace(/[&<>"]/g, (c) => ({ "&": "&amp;", "<": "&lt;", ">": "&gt;", '"': "&quot;" })[c]); }
function lat(part) { return part && part.samples ? `${fmt(part.p50_ms, 2)} / ${fmt(part.p99_ms, 2)} / ${fmt(part.max_ms, 1)} ms (${part.samples})` : "–"; }
function counts(obj) { const e = Object.entries(obj || {}); return e.length ? e.map(([k, v]) => `${esc(k)} ${v}`).join(", ") : "none"; }

function onStatus(msg) {
  const s = msg.status;
  page.status = s;
  if (s) {
    $("state").textContent = s.state;
    $("state").dataset.state = s.state;
    $("detail").textContent = s.detail || "";
    for (const cam of s.cameras) {
      const view = page.cards[cam.id];
      if (!view) continue;
      view.card.dataset.state = cam.state;
      view.state.textContent = cam.state;
      view.rate.textContent = `${cam.frame_rate_hz.toFixed(1)} fps · ${cam.frames} frames${cam.losses ? ` · lost ${cam.losses}×` : ""}`;
    }
    const p = s.pairing;
    let rows = row("uptime", `${s.uptime_s.toFixed(0)} s · ${esc(s.version)}`);
    rows += s.cameras.map((c) => row(`camera ${esc(c.id)}`, `${esc(c.state)}, ${c.frame_rate_hz.toFixed(1)} fps, drops: ${counts(c.dropped)}${c.last_error ? `<br><span class="dim">${esc(c.last_error)}</span>` : ""}`)).join("");
    rows += row("pairs", `${p.pair_rate_hz.toFixed(1)} /s · ${p.pairs} in all · ${esc(p.mode || "")}`);
    rows += row("skew p50 / p99", `${fmt(p.skew_p50_us, 0)} / ${fmt(p.skew_p99_us, 0)} µs`);
    rows += row("dropped", `frames: ${counts(p.dropped_frames)}; pairs ${p.dropped_pairs}; messages ${s.dropped_messages}`);
    rows += row("latency p50 / p99 / max", `${lat(s.processing)}<br><span class="dim">capture to publish ${lat(s.latency)}</span>`);
    for (const [name, part] of Object.entries(s.stages || {})) rows += row(`&nbsp;&nbsp;${esc(name)}`, lat(part));
    rows += row("fixes", counts(s.fixes));
    const c = s.calibration;
    rows += row("calibration", c ? `${c.suspect ? "<b style='color:var(--bad)'>SUSPECT</b>" : "ok"}: ray gap ${fmt(c.ray_gap_mm.p50, 2)} mm, reprojection ${fmt(c.reprojection_px.p50, 2)} px (${c.fixes} fixes)${c.reason ? `<br><span class="dim">${esc(c.reason)}</span>` : ""}` : "no fixes measured yet");
    if (s.colours && s.colours.warning) rows += row("colours", `<span style="color:var(--warn)">${esc(s.colours.warning)}</span>`);
    const r = msg.recording;
    rows += row("recording", r ? `${esc(r.state)}${r.path ? ` · ${esc(r.path)}` : ""}${r.pairs ? ` · ${r.pairs} pairs, ${fmt(r.written_mb, 0)} MB` : ""}${r.detail ? `<br><span class="dim">${esc(r.detail)}</span>` : ""}` : "not available (no [recording] directory)");
    const k = msg.check;
    if (k && k.state !== "none") rows += row("calibration check", k.text ? `<pre>${esc(k.text)}</pre>` : `${esc(k.state)}: ${k.fixes} / ${k.wanted} fixes`);
    $("status").innerHTML = rows;
    document.body.dataset.recording = r ? r.state : "unavailable";
    const recording = r && (r.state === "recording" || r.state === "finishing");
    // From the status, not the page's info: a reload may make recording available or take it away.
    $("record-start").disabled = !r || recording;
    $("record-stop").disabled = !r || !recording;
  }
  const list = $("warnings");
  for (const w of msg.warnings || []) {
    const item = document.createElement("li");
    item.className = w.level;
    item.textContent = `${w.time_utc.slice(11, 19)} ${w.message}`;
    list.prepend(item);
    page.warnings += 1;
  }
  while (list.children.length > 100) list.lastChild.remove();
  if (!page.warnings && !list.children.length) list.innerHTML = `<li class="none">none since the console started</li>`;
  if (page.warnings && list.querySelector(".none")) list.querySelector(".none").remove();
}

// ------------------------------------------------------------------ actions

async function post(path) {
  // The header tells the console the request comes from its own page (docs/console.md).
  const response = await fetch(path, { method: "POST", headers: { "X-Trackerd-Console": "1" } });
  let body = {};
  try { body = await response.json(); } catch (e) { body = { error: response.statusText }; }
  return { ok: response.ok, body };
}

function say(html) { $("action").innerHTML = html; }

$("snapshot").onclick = async () => {
  say("snapshot: waiting for the next pair…");
  const { ok, body } = await post("api/snapshot");
  if (!ok) { say(`snapshot failed: ${esc(body.error)}`); return; }
  say(`snapshot ${esc(body.name)} saved in ${esc(body.folder)}: ` +
      body.files.map((f) => `<a class="snapfile" href="${f.url}" download>${esc(f.name)}</a>`).join(""));
};
$("record-start").onclick = async () => { const { body } = await post("api/recording/start"); say(esc(body.message || body.error)); };
$("record-stop").onclick = async () => { const { body } = await post("api/recording/stop"); say(esc(body.message || body.error)); };
$("check").onclick = async () => {
  const { body } = await post("api/check?fixes=200");
  say(esc(body.message || body.error));
  if (!body.ok) return;
  const poll = setInterval(async () => {
    const progress = await (await fetch("api/check")).json();
    if (progress.state === "done") { clearInterval(poll); say(`<pre>${esc(progress.text)}</pre>`); }
    else if (progress.state === "running") say(`calibration check: ${progress.fixes} / ${progress.wanted} fixes; wave the pointer around in view of both cameras`);
  }, 500);
};

// ------------------------------------------------------------------ connection

function onInfo(info) {
  page.info = info;
  $("rig").textContent = info.rig;
  document.title = `trackerd ${info.rig}`;
  if (!Object.keys(page.cards).length) for (const cam of info.cameras) page.cards[cam.id] = cameraCard(cam);
  setupWall(info.wall);
}

function connect() {
  const ws = new WebSocket(`${location.protocol === "https:" ? "wss" : "ws"}://${location.host}${location.pathname.replace(/[^/]*$/, "")}ws`);
  ws.binaryType = "arraybuffer";
  ws.onmessage = (event) => {
    if (typeof event.data !== "string") { onImage(event.data); return; }
    const msg = JSON.parse(event.data);
    if (msg.type === "info") onInfo(msg);
    else if (msg.type === "status") onStatus(msg);
    else if (msg.type === "fixes") onFixes(msg.messages);
  };
  ws.onopen = () => { document.body.dataset.connected = "yes"; };
  ws.onclose = () => {
    document.body.dataset.connected = "no";
    $("state").textContent = "disconnected";
    $("state").dataset.state = "disconnected";
    setTimeout(connect, 1000);
  };
}
connect();
