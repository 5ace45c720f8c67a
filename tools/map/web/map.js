// The live map (docs/map.md): loads /api/state, then follows /events (Server-Sent Events) from the
// state's seq on, and draws the chosen frame: the reference device at the origin, each target's latest
// estimate with its 1-sigma ellipse and its trace, direction-only estimates as bearings; the health
// table and the event log beside it. Everything drawn carries data-* attributes with the numbers it
// was drawn from (tests/integration/map reads them back in headless Chromium).
'use strict';

const SVGNS = 'http://www.w3.org/2000/svg';
const $ = (id) => document.getElementById(id);
const st = { tracks: new Map(), devices: new Map(), latestFrame: null, sse: 0, es: null, dirty: false, maxLog: 100 };

function keyOf(e) { return [e.plugin, e.reference, e.frame, e.target].join('|'); }
function hasFlag(e, f) { return Array.isArray(e.flags) && e.flags.includes(f); }
function num(v) { return typeof v === 'number' && isFinite(v); }
function fmt(v, d) { return num(v) ? v.toFixed(d) : '–'; }

function addEstimate(e, node) {
  const k = keyOf(e);
  let t = st.tracks.get(k);
  if (!t) { t = { node, trace: [], count: 0 }; st.tracks.set(k, t); }
  t.estimate = e; t.node = node; t.count++;
  const p = e.position_m;
  if (!hasFlag(e, 'direction_only') && Array.isArray(p) && num(p[0]) && num(p[1])) {
    t.trace.push([p[0], p[1]]);
    if (t.trace.length > st.tracePoints) t.trace.shift();
  }
  st.latestFrame = e.frame;
}

function loadState(s) {
  st.tracks.clear();
  st.tracePoints = s.trace_points || 300;
  $('title').textContent = s.title; document.title = s.title + ' map';
  setStatus(s.status, s.finished);
  for (const t of s.tracks) {
    st.tracks.set(t.key, { node: t.node, trace: t.trace, count: t.count, estimate: t.estimate });
    st.latestFrame = t.estimate.frame;
  }
  setDevices(s.devices);
  $('events').textContent = '';
  for (const r of s.recent) logEvent(r.node, r.event);
  document.body.dataset.seq = s.seq;
  document.body.dataset.ready = '1';
}

function setStatus(text, finished) {
  $('status').textContent = text;
  document.body.dataset.finished = finished ? '1' : '0';
}

function setDevices(list) {
  st.devices = new Map(list.map((d) => [d.id, d]));
  const body = $('health').tBodies[0];
  body.textContent = '';
  for (const d of list) {
    const tr = document.createElement('tr');
    tr.dataset.device = d.id;
    tr.dataset.framesLost = d.frames_lost;
    tr.dataset.xruns = d.xruns;
    tr.dataset.link = d.link;
    if (d.frames_lost > 0 || d.xruns > 0 || d.link === 'offline') tr.className = 'bad';
    const cells = [d.id, d.node, d.link, d.frames_lost, d.xruns, d.events_dropped + d.sensor_dropped, d.detections,
                   fmt(d.last_snr_db, 1)];
    for (const c of cells) { const td = document.createElement('td'); td.textContent = c; tr.appendChild(td); }
    body.appendChild(tr);
  }
}

function logEvent(node, e) {
  const li = document.createElement('li');
  let what = '';
  if (e.type === 'estimate') {
    what = `${e.plugin} ${e.target} in ${e.frame}: ` + (hasFlag(e, 'direction_only')
      ? `bearing ${fmt(e.direction_rad * 180 / Math.PI, 1)}°`
      : `(${fmt(e.position_m && e.position_m[0], 2)}, ${fmt(e.position_m && e.position_m[1], 2)}) m ±${fmt(e.std_m, 2)}`);
    if (e.flags && e.flags.length) what += ' [' + e.flags.join(',') + ']';
  } else if (e.type === 'audio_detection') {
    what = `${e.device} ch${e.channel} ${e.detector} SNR ${fmt(e.snr_db, 1)} dB`;
  } else {
    what = e.device || e.target || '';
  }
  li.textContent = `${fmt(e.t_s, 3)} s ${node} ${e.type} ${what}`;
  const ol = $('events');
  ol.insertBefore(li, ol.firstChild);
  while (ol.childNodes.length > st.maxLog) ol.removeChild(ol.lastChild);
}

function connect(after) {
  if (st.es) st.es.close();
  const es = new EventSource('/events?after=' + after);
  st.es = es;
  es.onopen = () => { $('conn').textContent = 'live'; $('conn').className = 'conn-ok'; };
  es.onerror = () => { $('conn').textContent = 'reconnecting'; $('conn').className = 'conn-wait'; };
  es.addEventListener('locus', (m) => {
    const d = JSON.parse(m.data);
    st.sse++;
    document.body.dataset.sseEvents = st.sse;
    document.body.dataset.seq = m.lastEventId;
    if (d.event.type === 'estimate') addEstimate(d.event, d.node);
    else if (d.event.type === 'audio_detection') {
      const dev = st.devices.get(d.event.device);
      if (dev) { dev.last_snr_db = d.event.snr_db; dev.detections++; }
    }
    logEvent(d.node, d.event);
    schedule();
  });
  es.addEventListener('health', (m) => { setDevices(JSON.parse(m.data).devices); });
  es.addEventListener('status', (m) => { const d = JSON.parse(m.data); setStatus(d.status, d.finished); });
  es.addEventListener('reset', () => { es.close(); start(); });
}

function schedule() {
  if (st.dirty) return;
  st.dirty = true;
  requestAnimationFrame(() => { st.dirty = false; render(); });
}

function el(name, attrs, parent) {
  const n = document.createElementNS(SVGNS, name);
  for (const [k, v] of Object.entries(attrs)) n.setAttribute(k, v);
  if (parent) parent.appendChild(n);
  return n;
}

function updateFrames() {
  const sel = $('frame');
  const frames = [...new Set([...st.tracks.values()].map((t) => t.estimate.frame))].sort();
  const have = [...sel.options].slice(1).map((o) => o.value);
  if (have.join('\n') === frames.join('\n')) return;
  const keep = sel.value;
  while (sel.options.length > 1) sel.remove(1);
  for (const f of frames) { const o = document.createElement('option'); o.value = f; o.textContent = f; sel.appendChild(o); }
  sel.value = frames.includes(keep) ? keep : '';
}

function render() {
  updateFrames();
  const frame = $('frame').value || st.latestFrame;
  const svg = $('map');
  svg.textContent = '';
  const tracks = [...st.tracks.values()].filter((t) => t.estimate.frame === frame);
  const W = svg.clientWidth || 800, H = svg.clientHeight || 600, pad = 30;
  svg.setAttribute('viewBox', `0 0 ${W} ${H}`);
  svg.dataset.frame = frame || '';
  // Extent: the origin, every position with its 1-sigma, every trace point; bearings get the radius.
  let xs = [0], ys = [0];
  for (const t of tracks) {
    const e = t.estimate, p = e.position_m, s = num(e.std_m) ? e.std_m : 0;
    if (!hasFlag(e, 'direction_only') && Array.isArray(p) && num(p[0]) && num(p[1])) {
      xs.push(p[0] - s, p[0] + s); ys.push(p[1] - s, p[1] + s);
    }
    for (const q of t.trace) { xs.push(q[0]); ys.push(q[1]); }
  }
  let x0 = Math.min(...xs), x1 = Math.max(...xs), y0 = Math.min(...ys), y1 = Math.max(...ys);
  const span = Math.max(x1 - x0, y1 - y0, 1);
  const cx = (x0 + x1) / 2, cy = (y0 + y1) / 2;
  const k = Math.min((W - 2 * pad) / span, (H - 2 * pad) / span) / 1.1;
  const X = (x) => W / 2 + (x - cx) * k, Y = (y) => H / 2 - (y - cy) * k;
  svg.dataset.scale = k;
  // Grid (1 m, or 10 cm when small) and axes through the origin.
  const step = span > 3 ? 1 : 0.1;
  const g = el('g', { class: 'grid-layer' }, svg);
  for (let x = Math.floor((cx - W / 2 / k) / step) * step; x <= cx + W / 2 / k; x += step) el('line', { class: 'grid', x1: X(x), x2: X(x), y1: 0, y2: H }, g);
  for (let y = Math.floor((cy - H / 2 / k) / step) * step; y <= cy + H / 2 / k; y += step) el('line', { class: 'grid', y1: Y(y), y2: Y(y), x1: 0, x2: W }, g);
  el('line', { class: 'axis', x1: X(0), x2: X(0), y1: 0, y2: H }, g);
  el('line', { class: 'axis', y1: Y(0), y2: Y(0), x1: 0, x2: W }, g);
  el('line', { class: 'scale', x1: 10, x2: 10 + step * k, y1: H - 10, y2: H - 10 }, g);
  el('text', { class: 'label', x: 14 + step * k, y: H - 6 }, g).textContent = step === 1 ? '1 m' : '10 cm';
  // The reference devices of this frame, at the origin.
  const refs = [...new Set(tracks.map((t) => t.estimate.reference).filter((r) => r))];
  for (const r of refs) {
    const d = el('g', { class: 'device reference', 'data-id': r, 'data-x': 0, 'data-y': 0 }, svg);
    el('rect', { x: X(0) - 6, y: Y(0) - 6, width: 12, height: 12 }, d);
    el('text', { class: 'label', x: X(0) + 9, y: Y(0) - 8 }, d).textContent = r;
  }
  const R = span * 0.6;
  let drawn = 0;
  for (const t of tracks) {
    const e = t.estimate;
    const flagged = hasFlag(e, 'inconsistent') || hasFlag(e, 'weak');
    if (hasFlag(e, 'direction_only')) {
      if (!num(e.direction_rad)) continue;
      const b = el('g', { class: 'bearing' + (flagged ? ' flagged' : ''), 'data-target': e.target, 'data-plugin': e.plugin,
                          'data-direction-rad': e.direction_rad, 'data-direction-std-rad': num(e.direction_std_rad) ? e.direction_std_rad : '' }, svg);
      const a = e.direction_rad, s = num(e.direction_std_rad) ? e.direction_std_rad : 0;
      if (s > 0) {
        const p1 = [X(R * Math.cos(a - s)), Y(R * Math.sin(a - s))], p2 = [X(R * Math.cos(a + s)), Y(R * Math.sin(a + s))];
        el('path', { d: `M${X(0)},${Y(0)} L${p1[0]},${p1[1]} L${p2[0]},${p2[1]} Z` }, b);
      }
      el('line', { x1: X(0), y1: Y(0), x2: X(R * Math.cos(a)), y2: Y(R * Math.sin(a)) }, b);
      el('text', { class: 'label', x: X(R * Math.cos(a)) + 4, y: Y(R * Math.sin(a)) }, b).textContent = e.target;
      drawn++;
      continue;
    }
    const p = e.position_m;
    if (!Array.isArray(p) || !num(p[0]) || !num(p[1])) continue;
    const grp = el('g', { class: 'estimate' + (flagged ? ' flagged' : ''), 'data-target': e.target, 'data-plugin': e.plugin,
                          'data-node': t.node, 'data-x': p[0], 'data-y': p[1], 'data-std': num(e.std_m) ? e.std_m : '',
                          'data-count': t.count }, svg);
    if (t.trace.length > 1) el('polyline', { class: 'trace', points: t.trace.map((q) => `${X(q[0])},${Y(q[1])}`).join(' ') }, grp);
    // 1-sigma ellipse: radial (distance_std_m) x tangential (distance * direction_std_rad) when the
    // localizer gives them, else a circle of std_m.
    let rx = num(e.std_m) ? e.std_m : 0, ry = rx, rot = 0;
    if (num(e.distance_std_m) && num(e.direction_std_rad) && num(e.distance_m)) {
      rx = e.distance_std_m; ry = e.distance_m * e.direction_std_rad;
      rot = -Math.atan2(p[1], p[0]) * 180 / Math.PI;
    }
    if (rx > 0 || ry > 0) {
      el('ellipse', { class: 'ellipse', cx: X(p[0]), cy: Y(p[1]), rx: Math.max(rx * k, 1), ry: Math.max(ry * k, 1),
                      transform: `rotate(${rot} ${X(p[0])} ${Y(p[1])})`, 'data-rx-m': rx, 'data-ry-m': ry }, grp);
    }
    el('circle', { class: 'dot', cx: X(p[0]), cy: Y(p[1]), r: 4 }, grp);
    el('text', { class: 'label', x: X(p[0]) + 6, y: Y(p[1]) - 6 }, grp).textContent = e.target;
    drawn++;
  }
  svg.dataset.drawn = drawn;
  $('counts').textContent = `${st.tracks.size} targets, ${st.sse} live events`;
}

async function start() {
  $('conn').textContent = 'loading'; $('conn').className = 'conn-wait';
  try {
    const r = await fetch('/api/state', { cache: 'no-store' });
    if (!r.ok) throw new Error('HTTP ' + r.status);
    const s = await r.json();
    loadState(s);
    render();
    connect(s.seq);
  } catch (err) {
    $('conn').textContent = 'cannot load the state: ' + err.message; $('conn').className = 'conn-bad';
    setTimeout(start, 2000);
  }
}

$('frame').addEventListener('change', render);
window.addEventListener('resize', schedule);
start();
