// hvs view: the page. Everything it shows comes from the JSON API of the server it came from.
'use strict';
const token = new URLSearchParams(location.search).get('token');
const q = (path) => token ? path + (path.includes('?') ? '&' : '?') + 'token=' + encodeURIComponent(token) : path;
const $ = (id) => document.getElementById(id);
let session = null;
let pair = 0;
let frameCount = 0;
let frameStart = performance.now();
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

async function fetchFrame(side) {
  const r = await fetch(q(`/api/frame/${pair}/${view(side)}?n=${frameCount}`));
  if (!r.ok) throw new Error(`no ${side} frame (${r.status})`);
  const url = URL.createObjectURL(await r.blob());
  const pre = new Image();
  pre.src = url;
  await pre.decode();
  return url;
}

async function liveFrames() {
  try {
    const urls = await Promise.all(['left', 'right'].map(fetchFrame));
    ['left', 'right'].forEach((side, k) => {
      const img = $(side), old = img.src;
      img.src = urls[k];
      if (old.startsWith('blob:')) setTimeout(() => URL.revokeObjectURL(old), 2000);
    });
    frameCount += 1;
    const fps = frameCount / ((performance.now() - frameStart) / 1000);
    $('frames-status').textContent = `live, ${fps.toFixed(1)} pairs fetched/s`;
    $('frames-status').dataset.loaded = 'yes';
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

// The dense depth of the pair (`hvs depth --colour`), computed by the server when first asked.
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
    const pct = 100 * d.returned / d.pixels;
    $('depth-status').textContent = `${d.returned} of ${d.pixels} pixels with a depth (${pct.toFixed(1)} %), ` +
      `${d.z_box_cm[0].toFixed(0)}-${d.z_box_cm[1].toFixed(0)} cm, disparities ${d.disparity_px[0]}..${d.disparity_px[1]} px, ` +
      `${(d.ms / 1000).toFixed(2)} s` + (d.warnings.length ? '; ' + d.warnings.join('; ') : '');
    $('depth').onload = () => { $('depth').dataset.loaded = 'yes'; };
    $('depth').src = q(`/api/depth/${asked}/image`);
  } catch (err) {
    $('depth-status').textContent = 'no depth: ' + err.message;
  }
}

async function click(e) {
  const img = e.currentTarget;
  const left = $('left');
  const u = Math.floor(e.offsetX * img.naturalWidth / img.clientWidth);
  const v = Math.floor(e.offsetY * img.naturalWidth / img.clientWidth);
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
  $('board').textContent = `(${c.board}; one fundamental matrix: Sampson rms ${fmt(c.sampson_rms_px, 3)} px)`;
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
    $('head-loop').textContent = h.status + (h.moving ? ', moving' : '') + (h.error ? '; ' + h.error : '');
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
  $('pair').addEventListener('change', choosePair);
  $('show-corners').addEventListener('change', loadFrames);
  $('retrain').addEventListener('click', retrain);
  if (session.captures) await loadCaptures();
  if (session.head) {
    $('head').hidden = false;
    $('look').addEventListener('click', () => clicked && look({target: 'pixel', u: clicked.u, v: clicked.v}));
    $('look-nearest').addEventListener('click', () => look({target: 'nearest'}));
    $('home').addEventListener('click', () => look({target: 'home'}));
    pollHead();
  }
  loadFrames();
}

start().catch((err) => { $('frames-status').textContent = 'error: ' + err.message; });
