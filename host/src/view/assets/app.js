// hvs view: the page. Everything it shows comes from the JSON API of the server it came from.
'use strict';
const token = new URLSearchParams(location.search).get('token');
const q = (path) => token ? path + (path.includes('?') ? '&' : '?') + 'token=' + encodeURIComponent(token) : path;
const $ = (id) => document.getElementById(id);
let session = null;
let pair = 0;
let frameCount = 0;
let clicked = null;

async function getJson(path) {
  const r = await fetch(q(path));
  const body = await r.json();
  if (!r.ok) throw new Error(body.error || r.statusText);
  return body;
}

async function postJson(path, value) {
  const r = await fetch(q(path), {method: 'POST', headers: {'Content-Type': 'application/json'}, body: JSON.stringify(value)});
  const body = await r.json();
  if (!r.ok) throw new Error(body.error || r.statusText);
  return body;
}

function view(side) {
  return $('show-corners').checked ? side + '-corners' : side;
}

// Frames: a still source is loaded once; a live one is polled, the next pair asked for when
// the last one has arrived. A live frame is fetched and decoded off screen, then put in place
// in one step (an image already decoded under its URL is shown at once), so the shown
// image always has its size and a click always maps to a pixel.
let liveLoop = false;
function loadFrames() {
  if (session.live) {
    if (!liveLoop) { liveLoop = true; liveFrames(); }
    return;
  }
  let loaded = 0;
  for (const side of ['left', 'right']) {
    const img = $(side);
    img.onload = () => {
      loaded += 1;
      if (loaded === 2) {
        $('frames-status').textContent = 'frames loaded';
        $('frames-status').dataset.loaded = 'yes';
      }
    };
    img.onerror = () => { $('frames-status').textContent = `no ${side} frame for this pair`; };
    img.src = q(`/api/frame/${pair}/${view(side)}?n=${frameCount}`);
  }
}

// A live frame: `after` waits on the server for a frame newer than the one shown (no busy
// polling), `seq` asks for the right image of the same pair as the left one.
async function fetchFrame(side, query) {
  const r = await fetch(q(`/api/frame/${pair}/${view(side)}?${query}`));
  if (!r.ok) throw new Error(`no ${side} frame (${r.status})`);
  const seq = Number(r.headers.get('x-frame-seq'));
  const url = URL.createObjectURL(await r.blob());
  const pre = new Image();
  pre.src = url;
  return {seq, url, decoded: pre.decode()};
}

let lastSeq = 0, shown = 0;
const shownAt = [];
async function liveFrames() {
  try {
    const left = await fetchFrame('left', `after=${lastSeq}`);
    const right = await fetchFrame('right', `seq=${left.seq}`);
    await Promise.all([left.decoded, right.decoded]);
    [left, right].forEach((f, k) => {
      const img = $(k ? 'right' : 'left'), old = img.src;
      img.src = f.url;
      if (old.startsWith('blob:')) setTimeout(() => URL.revokeObjectURL(old), 2000);
    });
    const now = performance.now();
    if (left.seq !== lastSeq) { shownAt.push(now); shown += 1; }
    while (shownAt.length > 2 && now - shownAt[0] > 2000) shownAt.shift();
    lastSeq = left.seq;
    frameCount += 1;
    const span = (now - shownAt[0]) / 1000;
    const fps = shownAt.length > 1 && span > 0 ? (shownAt.length - 1) / span : 0;
    $('frames-status').textContent = `live, frame ${left.seq}, ${fps.toFixed(1)} frames/s shown`;
    $('frames-status').dataset.loaded = 'yes';
    $('frames-status').dataset.shown = shown;
    setTimeout(liveFrames, 0);
  } catch (err) {
    $('frames-status').textContent = 'live: ' + err.message;
    setTimeout(liveFrames, 500);
  }
}

function place(mark, img, u, v) {
  const sx = img.clientWidth / img.naturalWidth, sy = img.clientHeight / img.naturalHeight;
  mark.style.left = `${(u + 0.5) * sx}px`;
  mark.style.top = `${(v + 0.5) * sy}px`;
  mark.hidden = false;
}

// The dense depth of the pair (`hvs depth --thorough --colour`), computed by the server when
// first asked.
async function loadDepth() {
  const fig = $('depth-figure');
  fig.hidden = !$('show-depth').checked;
  if (fig.hidden) return;
  const asked = pair;
  $('depth-status').textContent = 'matching every pixel…';
  delete $('depth').dataset.loaded;
  try {
    const d = await getJson(`/api/depth/${asked}`);
    if (asked !== pair) return;
    $('depth-status').textContent = `${d.summary}, depth box ${d.z_box_cm[0].toFixed(0)}-${d.z_box_cm[1].toFixed(0)} cm, ` +
      `${(d.ms / 1000).toFixed(2)} s` + (d.warnings.length ? '; ' + d.warnings.join('; ') : '');
    $('depth').onload = () => { $('depth').dataset.loaded = 'yes'; };
    $('depth').src = q(`/api/depth/${asked}/image`);
  } catch (err) {
    $('depth-status').textContent = 'no depth: ' + err.message;
  }
}

// The 3-D view: the pair's point cloud, the bytes of `hvs depth --thorough --ply` (binary
// little-endian: float x, y, z; uchar red, green, blue), drawn by hand on a canvas (no library): each point
// turned with the view, projected with a pinhole, nearest point wins a pixel.
const cloud = {points: null, grey: null, n: 0, yaw: 0, pitch: 0, zoom: 1, centre: [0, 0, 0], size: 1};

function parsePly(buf) {
  const bytes = new Uint8Array(buf);
  const text = new TextDecoder().decode(bytes.subarray(0, Math.min(bytes.length, 1024)));
  const end = text.indexOf('end_header\n');
  const count = /element vertex (\d+)/.exec(text);
  if (end < 0 || !count || !text.startsWith('ply\nformat binary_little_endian 1.0\n')) throw new Error('not a PLY of hvs depth');
  const n = Number(count[1]);
  const start = end + 'end_header\n'.length;
  if (bytes.length !== start + 15 * n) throw new Error(`the PLY says ${n} points but holds ${bytes.length - start} bytes`);
  const dv = new DataView(buf, start);
  const points = new Float32Array(3 * n);
  const grey = new Uint8Array(n);
  for (let i = 0; i < n; i++) {
    for (let k = 0; k < 3; k++) points[3 * i + k] = dv.getFloat32(15 * i + 4 * k, true);
    grey[i] = dv.getUint8(15 * i + 12);
  }
  return {points, grey, n};
}

function resetCloud() {
  const p = cloud.points;
  const lo = [Infinity, Infinity, Infinity], hi = [-Infinity, -Infinity, -Infinity];
  for (let i = 0; i < cloud.n; i++) for (let k = 0; k < 3; k++) {
    lo[k] = Math.min(lo[k], p[3 * i + k]); hi[k] = Math.max(hi[k], p[3 * i + k]);
  }
  cloud.centre = lo.map((l, k) => cloud.n ? (l + hi[k]) / 2 : 0);
  cloud.size = cloud.n ? Math.max(hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2], 1) : 1;
  cloud.yaw = 0; cloud.pitch = 0; cloud.zoom = 1;
}

function drawCloud() {
  const canvas = $('cloud');
  const ctx = canvas.getContext('2d');
  const w = canvas.width, h = canvas.height;
  const img = ctx.createImageData(w, h);
  const px = img.data;
  for (let i = 3; i < px.length; i += 4) { px[i] = 255; px[i - 3] = 17; px[i - 2] = 17; px[i - 1] = 17; }
  const zbuf = new Float32Array(w * h).fill(Infinity);
  const [cx, cy, cz] = cloud.centre;
  const cyw = Math.cos(cloud.yaw), syw = Math.sin(cloud.yaw), cp = Math.cos(cloud.pitch), sp = Math.sin(cloud.pitch);
  // The camera looks along +Z at the cloud's centre from 1.5 sizes away (the head's view at
  // the start: X right, Y down as in the images).
  const dist = 1.5 * cloud.size / cloud.zoom, f = 0.9 * w;
  const p = cloud.points;
  let drawn = 0;
  for (let i = 0; i < cloud.n; i++) {
    const x0 = p[3 * i] - cx, y0 = p[3 * i + 1] - cy, z0 = p[3 * i + 2] - cz;
    const x1 = cyw * x0 + syw * z0, z1 = -syw * x0 + cyw * z0;
    const y2 = cp * y0 - sp * z1, z2 = sp * y0 + cp * z1 + dist;
    if (!(z2 > 1e-3)) continue;
    const u = Math.round(w / 2 + f * x1 / z2), v = Math.round(h / 2 + f * y2 / z2);
    if (u < 0 || v < 0 || u >= w || v >= h) continue;
    const k = v * w + u;
    if (z2 >= zbuf[k]) continue;
    zbuf[k] = z2;
    const g = cloud.grey[i];
    px[4 * k] = g; px[4 * k + 1] = g; px[4 * k + 2] = g;
    drawn++;
  }
  ctx.putImageData(img, 0, 0);
  canvas.dataset.drawn = String(drawn);
}

async function loadCloud() {
  const fig = $('cloud-figure');
  fig.hidden = !$('show-cloud').checked;
  if (fig.hidden) return;
  const asked = pair;
  $('cloud-status').textContent = 'matching every pixel…';
  delete $('cloud').dataset.points;
  try {
    const r = await fetch(q(`/api/depth/${asked}/cloud.ply`));
    if (!r.ok) throw new Error((await r.json()).error || r.statusText);
    const parsed = parsePly(await r.arrayBuffer());
    if (asked !== pair) return;
    Object.assign(cloud, parsed);
    resetCloud();
    drawCloud();
    $('cloud').dataset.points = String(cloud.n);
    $('cloud-status').textContent = `${cloud.n} points, ${cloud.size.toFixed(0)} cm across; grey levels of the left image`;
  } catch (err) {
    $('cloud-status').textContent = 'no point cloud: ' + err.message;
  }
}

function cloudControls() {
  const canvas = $('cloud');
  let drag = null;
  canvas.addEventListener('mousedown', (e) => { drag = {x: e.clientX, y: e.clientY}; });
  window.addEventListener('mouseup', () => { drag = null; });
  window.addEventListener('mousemove', (e) => {
    if (!drag || !cloud.points) return;
    cloud.yaw += (e.clientX - drag.x) * 0.01;
    cloud.pitch = Math.max(-1.5, Math.min(1.5, cloud.pitch - (e.clientY - drag.y) * 0.01));
    drag = {x: e.clientX, y: e.clientY};
    drawCloud();
  });
  canvas.addEventListener('wheel', (e) => {
    if (!cloud.points) return;
    e.preventDefault();
    cloud.zoom = Math.max(0.2, Math.min(20, cloud.zoom * Math.exp(-e.deltaY * 0.001)));
    drawCloud();
  }, {passive: false});
  canvas.addEventListener('dblclick', () => { if (cloud.points) { resetCloud(); drawCloud(); } });
}

async function click(e) {
  const img = e.currentTarget;
  const left = $('left');
  // From the image's box, not offsetX/Y: at a fractional page offset the browser paints the
  // image from the next whole pixel, and offsetX then counts one pixel too many.
  const box = img.getBoundingClientRect();
  const scale = img.naturalWidth / box.width;
  const u = Math.min(img.naturalWidth - 1, Math.max(0, Math.floor((e.clientX - box.left) * scale)));
  const v = Math.max(0, Math.floor((e.clientY - box.top) * scale));
  if (v >= left.naturalHeight) return; // the depth image's legend
  $('at').textContent = `${u},${v}`;
  clicked = {u, v};
  $('look').disabled = false;
  place($('mark-left'), left, u, v);
  $('mark-right').hidden = true;
  $('locate-note').textContent = '';
  for (const id of ['status', 'score', 'u_r', 'v_r', 'x', 'y', 'z', 'ms']) $(id).textContent = '…';
  const t0 = performance.now();
  try {
    const r = await postJson('/api/locate', {pair, u, v});
    for (const id of ['status', 'score', 'u_r', 'v_r', 'x', 'y', 'z']) $(id).textContent = r[id] ?? '—';
    $('line').textContent = r.line;
    $('ms').textContent = `${(performance.now() - t0).toFixed(1)} ms (server ${r.ms.toFixed(1)} ms)`;
    $('mark-left').classList.toggle('bad', r.status !== 'ok');
    if (r.right) place($('mark-right'), $('right'), r.right[0], r.right[1]);
    $('point').dataset.answered = String(Number($('point').dataset.answered || 0) + 1);
  } catch (err) {
    $('locate-note').textContent = err.message;
    $('status').textContent = 'refused';
  }
}

function fmt(v, d) { return v === null || v === undefined ? '—' : Number(v).toFixed(d); }

async function loadCaptures() {
  const c = await getJson('/api/captures');
  $('captures').hidden = false;
  $('corners-toggle').hidden = false;
  $('board').textContent = `(${c.board}; ${c.fundamental})`;
  const body = $('pairs').querySelector('tbody');
  body.textContent = '';
  for (const p of c.pairs) {
    const tr = document.createElement('tr');
    if (!p.found) tr.className = 'skipped';
    const cells = p.found
      ? [p.corners, fmt(p.square_px, 1), `${fmt(p.homography_rms_px[0], 3)} / ${fmt(p.homography_rms_px[1], 3)}`,
         p.epipolar ? `${fmt(p.epipolar.median_px, 3)} / ${fmt(p.epipolar.max_px, 3)}` : '—']
      : ['skipped: ' + p.skipped, '', '', ''];
    const use = document.createElement('input');
    use.type = 'checkbox'; use.className = 'use'; use.dataset.k = p.index;
    use.checked = p.found; use.disabled = !p.found;
    const td0 = document.createElement('td'); td0.appendChild(use); tr.appendChild(td0);
    for (const text of [p.name, p.z ?? '—', ...cells]) {
      const td = document.createElement('td'); td.textContent = text; tr.appendChild(td);
    }
    const tdi = document.createElement('td');
    if (p.found) {
      for (const side of ['left', 'right']) {
        const im = document.createElement('img');
        im.loading = 'lazy'; im.alt = `${side} corners`;
        im.src = q(`/api/frame/${p.index}/${side}-corners`);
        tdi.appendChild(im);
      }
    }
    tr.appendChild(tdi);
    tr.addEventListener('click', (e) => { if (e.target !== use) { $('pair').value = p.index; choosePair(); } });
    body.appendChild(tr);
  }
}

async function retrain() {
  const ticks = [...document.querySelectorAll('input.use')].map((c) => c.checked);
  $('retrain').disabled = true;
  $('retrain-status').textContent = `training on ${ticks.filter((t) => t).length} pairs…`;
  try {
    const r = await postJson('/api/retrain', {use: ticks});
    const latest = $('summary').textContent;
    if (latest !== '—') $('summary-before').textContent = latest;
    $('summary').textContent = `${r.pairs} pairs, ${r.points} points, training e_ma ${r.train_error_pct.toFixed(4)} %\n${r.summary}`;
    $('retrain-status').textContent = `done in ${(r.ms / 1000).toFixed(2)} s`;
    $('summary').dataset.runs = String(Number($('summary').dataset.runs || 0) + 1);
  } catch (err) {
    $('retrain-status').textContent = 'refused: ' + err.message;
  } finally {
    $('retrain').disabled = false;
  }
}

// The live head: its state polled, the look buttons.
async function pollHead() {
  try {
    const h = await getJson('/api/head');
    const j = h.joints;
    $('head-status').textContent = `(${h.frames} frames, ${h.fps.toFixed(1)} frames/s, t = ${h.t_s.toFixed(1)} s)`;
    $('head-goal').textContent = h.goal.target === 'pixel' ? `the object under ${h.goal.u},${h.goal.v}` : h.goal.target;
    const scale = h.right_scale != null && h.right_scale !== 1 ? `, the right camera at ${h.right_scale.toFixed(3)} times the left one's scale` : '';
    $('head-loop').textContent = h.status + (h.moving ? ', moving' : '') + scale + (h.error ? '; ' + h.error : '');
    $('head-joints').textContent = ['neck_pan', 'neck_tilt', 'eye_tilt', 'left_eye_pan', 'right_eye_pan'].map((k) => `${k} ${j[k]}`).join(', ');
    $('head-target').textContent = h.target_px ? `${fmt(h.target_px[0], 1)},${fmt(h.target_px[1], 1)} | ${fmt(h.target_px[2], 1)},${fmt(h.target_px[3], 1)}` : '—';
    $('head-xyz').textContent = h.xyz ? h.xyz.join(', ') : '—';
    $('head-err').textContent = h.err_px ? `${fmt(h.err_px[0], 1)} | ${fmt(h.err_px[1], 1)}` : '—';
    const sec = $('head');
    sec.dataset.updates = String(Number(sec.dataset.updates || 0) + 1);
    sec.dataset.status = h.status;
    if (Object.values(j).some((v) => v !== 0)) sec.dataset.moved = 'yes';
  } catch (err) {
    $('head-status').textContent = 'error: ' + err.message;
  }
  setTimeout(pollHead, 200);
}

async function look(goal) {
  $('look-note').textContent = '';
  try {
    await postJson('/api/look', goal);
    $('head').dataset.asked = String(Number($('head').dataset.asked || 0) + 1);
  } catch (err) {
    $('look-note').textContent = err.message;
  }
}

function choosePair() {
  pair = Number($('pair').value);
  $('mark-left').hidden = true;
  $('mark-right').hidden = true;
  loadFrames();
  loadDepth();
  loadCloud();
}

async function start() {
  session = await getJson('/api/session');
  $('model-info').textContent = session.model.info;
  $('model-shape').textContent = `(${session.model.topology}, ${session.model.family}, ${session.model.train_points} training points, training e_ma ${fmt(session.model.train_error_pct, 4)} %)`;
  $('summary-before').textContent = `the model as given: ${session.model.train_points} points, training e_ma ${fmt(session.model.train_error_pct, 4)} %`;
  for (const p of session.pairs) {
    const o = document.createElement('option');
    o.value = p.index; o.textContent = p.name;
    $('pair').appendChild(o);
  }
  if (session.locate_refused) $('locate-note').textContent = session.locate_refused;
  $('left').addEventListener('click', click);
  $('depth').addEventListener('click', click);
  $('show-depth').addEventListener('change', loadDepth);
  $('show-cloud').addEventListener('change', loadCloud);
  cloudControls();
  $('pair').addEventListener('change', choosePair);
  $('show-corners').addEventListener('change', loadFrames);
  $('retrain').addEventListener('click', retrain);
  if (session.captures) await loadCaptures();
  if (session.head) {
    $('head').hidden = false;
    if (!session.head_moves) {
      $('head-kind').textContent = 'Cameras (on no head)';
      $('head-buttons').hidden = true;
    }
    $('look').addEventListener('click', () => clicked && look({target: 'pixel', u: clicked.u, v: clicked.v}));
    $('look-nearest').addEventListener('click', () => look({target: 'nearest'}));
    $('home').addEventListener('click', () => look({target: 'home'}));
    pollHead();
  }
  loadFrames();
}

start().catch((err) => { $('frames-status').textContent = 'error: ' + err.message; });
