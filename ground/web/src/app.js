// MMIC-I operator dashboard. Plain DOM, one state object fed by a snapshot and then by
// server-sent events; views redraw what changed once per animation frame.
import uPlot from 'uplot';
import 'uplot/dist/uPlot.min.css';
import './app.css';

const $ = (s, r = document) => r.querySelector(s);
const el = (tag, attrs = {}, ...kids) => {
  const e = document.createElement(tag);
  for (const [k, v] of Object.entries(attrs)) {
    if (k === 'class') e.className = v;
    else if (k.startsWith('on')) e.addEventListener(k.slice(2), v);
    else if (v !== undefined && v !== null) e.setAttribute(k, v);
  }
  for (const k of kids.flat()) if (k !== null && k !== undefined) e.append(k);
  return e;
};
const SEV = { info: 0, low: 1, medium: 2, high: 3 };
const fmtTime = (ms) => (ms ? new Date(ms).toISOString().slice(11, 23) : '');
const fmtDate = (ms) => (ms ? new Date(ms).toISOString().replace('T', ' ').slice(0, 19) : '');
const fmtVal = (v) => (v === null || v === undefined ? '—' : Math.abs(v) >= 1000 || Number.isInteger(v) ? String(v) : v.toFixed(3));

// ---- access token (needed when the server is bound beyond localhost) -------------
const params = new URLSearchParams(location.search);
if (params.get('token')) {
  sessionStorage.setItem('dash-token', params.get('token'));
  // Keep the token out of the address bar and the history.
  history.replaceState(null, '', location.pathname + location.hash);
}
const token = sessionStorage.getItem('dash-token');
async function api(path, opts = {}) {
  const headers = Object.assign({ 'Content-Type': 'application/json' }, opts.headers || {});
  if (token) headers.Authorization = 'Bearer ' + token;
  const r = await fetch(path, Object.assign({}, opts, { headers }));
  const body = await r.json().catch(() => ({ error: r.statusText }));
  if (!r.ok) throw new Error(body.error || r.statusText);
  return body;
}

// ---- state ------------------------------------------------------------------------
const S = {
  mib: null, params: new Map(), robots: new Map(), events: [], alarms: new Map(), commands: new Map(),
  plans: new Map(), lastId: 0, clockOffset: 0, view: 'fleet',
  // Per robot: the last on-board plan control sent from its panel ({ id, name } or { error }).
  onboardTc: new Map(),
  dirty: { robots: new Set(), hk: new Set(), events: true, alarms: true, commands: true, plans: true, fleetAll: true, modules: true, team: true },
};
// Update-latency samples (ms from HK time to drawn), read by the benchmark.
const metrics = { latency: [], frames: 0, messages: 0, plots: [] };
window.dashMetrics = metrics;
window.dashState = S;

function robotOf(n) {
  let r = S.robots.get(n);
  if (!r) {
    r = { robot: n, link: 'connecting', last_heard_ms: null, mode: null, modes: {}, config: null, hk: {}, hk_t_ms: null, modules: null, team: null, onboard: null };
    S.robots.set(n, r);
    S.dirty.fleetAll = true;
  }
  return r;
}

function applySnapshot(s) {
  S.robots.clear(); S.alarms.clear(); S.commands.clear(); S.plans.clear();
  for (const r of s.robots) S.robots.set(r.robot, r);
  S.events = s.events.slice().reverse();
  for (const a of s.alarms) S.alarms.set(a.id, a);
  for (const c of s.commands.slice().reverse()) S.commands.set(c.request_id, c);
  for (const p of s.plans) S.plans.set(p.run_id, p);
  S.lastId = s.last_id;
  // Correct ages for clock skew only when it is real (> 1 s); below that the estimate
  // is mostly the snapshot's own transfer time.
  const skew = s.server_ms - Date.now();
  S.clockOffset = Math.abs(skew) > 1000 ? skew : 0;
  Object.assign(S.dirty, { events: true, alarms: true, commands: true, plans: true, fleetAll: true, modules: true, team: true });
  refreshRobotSelects();
}

function apply(m) {
  metrics.messages++;
  switch (m.type) {
    case 'robot': {
      const r = robotOf(m.robot);
      Object.assign(r, { link: m.link, last_heard_ms: m.last_heard_ms, mode: m.mode, modes: m.modes, config: m.config });
      S.dirty.robots.add(m.robot);
      S.dirty.team = true;
      refreshRobotSelects();
      break;
    }
    case 'modules':
      robotOf(m.robot).modules = m.modules;
      S.dirty.robots.add(m.robot);
      S.dirty.modules = true;
      break;
    case 'onboard':
      robotOf(m.robot).onboard = m.onboard;
      S.dirty.robots.add(m.robot);
      break;
    case 'team':
      robotOf(m.robot).team = m.team;
      S.dirty.robots.add(m.robot);
      S.dirty.team = true;
      break;
    case 'hk': {
      const r = robotOf(m.robot);
      for (const [name, value, limit] of m.v) {
        const p = S.params.get(name);
        r.hk[name] = { value, limit, unit: p ? p.unit : '', t_ms: m.t_ms };
      }
      r.hk_t_ms = Math.max(r.hk_t_ms || 0, m.t_ms);
      r.last_heard_ms = Math.max(r.last_heard_ms || 0, m.t_ms);
      S.dirty.hk.add(m.robot);
      break;
    }
    case 'event':
      S.events.push(m.event);
      if (S.events.length > 2000) S.events.splice(0, S.events.length - 2000);
      S.dirty.events = true;
      break;
    case 'alarm':
      S.alarms.set(m.alarm.id, m.alarm);
      S.dirty.alarms = true;
      S.dirty.robots.add(m.alarm.robot);
      break;
    case 'tc':
      S.commands.delete(m.tc.request_id);
      S.commands.set(m.tc.request_id, m.tc);
      if (S.commands.size > 1000) S.commands.delete(S.commands.keys().next().value);
      S.dirty.commands = true;
      if ((S.onboardTc.get(m.tc.robot) || {}).id === m.tc.request_id) S.dirty.robots.add(m.tc.robot);
      break;
    case 'plan':
      S.plans.set(m.plan.run_id, m.plan);
      S.dirty.plans = true;
      break;
  }
}

// ---- live stream -------------------------------------------------------------------
let es = null;
function connect() {
  const q = new URLSearchParams({ since: String(S.lastId) });
  if (token) q.set('token', token);
  es = new EventSource('/api/stream?' + q);
  es.onopen = () => setConn('live', 'ok');
  // On error the browser reconnects by itself and sends Last-Event-ID: nothing is lost.
  es.onerror = () => setConn('reconnecting…', 'warn');
  es.onmessage = (e) => {
    S.lastId = Number(e.lastEventId) || S.lastId;
    apply(JSON.parse(e.data));
    schedule();
  };
  es.addEventListener('reset', async () => {
    // Too far behind for the replay ring: reload the whole picture.
    es.close();
    setConn('resynchronising…', 'warn');
    applySnapshot(await api('/api/snapshot'));
    schedule();
    connect();
  });
}
function setConn(text, cls) {
  const c = $('#conn');
  c.textContent = text;
  c.className = 'conn ' + cls;
}

// ---- rendering ---------------------------------------------------------------------
// At most one redraw per FRAME_MS: at 50 robots × 10 Hz every card still shows each HK
// report's values within 100 ms, but style, layout and paint run 10 times a second
// instead of 60 (see docs/dashboard.md, Performance).
const FRAME_MS = 100;
let pending = false;
let lastRender = 0;
function schedule() {
  if (!pending) {
    pending = true;
    setTimeout(() => requestAnimationFrame(render), Math.max(0, lastRender + FRAME_MS - performance.now()));
  }
}
function render() {
  pending = false;
  lastRender = performance.now();
  metrics.frames++;
  const now = Date.now();
  if (S.view === 'fleet') renderFleet(now);
  if (S.view === 'hk') renderHk();
  if (S.view === 'alarms' && S.dirty.alarms) renderAlarms();
  if (S.view === 'events' && S.dirty.events) renderEvents();
  if (S.view === 'commands' && S.dirty.commands) renderHistory();
  if (S.view === 'plans' && S.dirty.plans) renderPlans();
  if (S.view === 'modules' && S.dirty.modules) renderModules();
  if (S.view === 'team' && S.dirty.team) renderTeam();
  if (S.dirty.alarms) renderAlarmBadge();
  if (S.view !== 'fleet') S.dirty.hk.clear();
}

// --- fleet
const cards = new Map();
const FLEET_VALUES = [
  ['V_BAT_A', 'Battery A'], ['V_BAT_B', 'Battery B'], ['I_BAT', 'I bat'], ['V_REG', 'V reg'],
  ['I_LOC_A', 'I loc A'], ['I_LOC_B', 'I loc B'], ['I_GRIP_A', 'I grip A'], ['I_GRIP_B', 'I grip B'],
  ['I_BO_A', 'I bolt A'], ['I_BO_B', 'I bolt B'],
];
function makeCard(n) {
  const vals = {};
  const grid = el('div', { class: 'vals' },
    FLEET_VALUES.map(([p, label]) => {
      const v = el('span', { class: 'v', 'data-param': p }, '—');
      vals[p] = v;
      return el('div', { class: 'kv' }, el('span', { class: 'k', title: p }, label), v);
    }));
  const card = el('div', { class: 'card robot', id: 'robot-' + n, 'data-robot': n },
    el('div', { class: 'head' }, el('h2', {}, 'Robot ' + n), el('span', { class: 'link' }), el('span', { class: 'age' }), el('span', { class: 'mode' })),
    el('div', { class: 'body' }, el('div', { class: 'pic' }), el('div', { class: 'tree' }), grid),
    el('div', { class: 'cfgline' }),
    el('div', { class: 'onboard' }),
    el('div', { class: 'ralarms' }));
  const c = { card, vals, link: $('.link', card), age: $('.age', card), mode: $('.mode', card), pic: $('.pic', card), tree: $('.tree', card), alarms: $('.ralarms', card), cfgline: $('.cfgline', card), onboard: $('.onboard', card) };
  cards.set(n, c);
  return c;
}
function renderFleet(now) {
  const box = $('#fleet');
  if (S.dirty.fleetAll) {
    S.dirty.fleetAll = false;
    box.textContent = '';
    cards.clear();
    for (const n of [...S.robots.keys()].sort((a, b) => a - b)) {
      box.append(makeCard(n).card);
      S.dirty.robots.add(n);
      S.dirty.hk.add(n);
    }
  }
  for (const n of S.dirty.robots) {
    const r = S.robots.get(n), c = cards.get(n);
    if (!r || !c) continue;
    c.link.textContent = r.link;
    c.link.className = 'link pill ' + r.link;
    c.mode.textContent = r.mode || 'mode ?';
    c.mode.className = 'mode pill m-' + (r.mode || 'unknown').toLowerCase();
    c.pic.replaceChildren(configPicture(r.config));
    c.tree.replaceChildren(modeTree(r.modes));
    c.cfgline.replaceChildren(...cfgLine(r));
    onboardPanel(c.onboard, r);
    c.alarms.replaceChildren(...robotAlarms(n));
  }
  S.dirty.robots.clear();
  for (const n of S.dirty.hk) {
    const r = S.robots.get(n), c = cards.get(n);
    if (!r || !c) continue;
    for (const [p] of FLEET_VALUES) {
      const h = r.hk[p];
      if (!h) continue;
      const span = c.vals[p];
      span.textContent = fmtVal(h.value) + ' ' + (h.unit || '');
      span.className = 'v lim-' + h.limit;
    }
    if (r.hk_t_ms) {
      // Server and page on one clock (as in the benchmark): no offset applied.
      metrics.latency.push(now - r.hk_t_ms);
      if (metrics.latency.length > 5000) metrics.latency.splice(0, 1000);
    }
  }
  S.dirty.hk.clear();
  for (const [n, c] of cards) {
    const r = S.robots.get(n);
    const age = r && r.last_heard_ms ? Math.max(0, (now + S.clockOffset - r.last_heard_ms) / 1000) : null;
    // Whole seconds: a tenth-second counter on 50 cards would redraw 500 times a second.
    const t = age === null ? 'never heard' : age < 1 ? 'heard < 1 s ago' : 'heard ' + Math.floor(age) + ' s ago';
    if (c.age.textContent !== t) c.age.textContent = t;
  }
}

function modeTree(modes) {
  const nodes = S.mib ? S.mib.nodes : [];
  const kids = (parent) => nodes.filter((n) => n.parent === parent);
  const item = (n) => {
    const m = modes[n.name];
    const sub = kids(n.name);
    return el('li', {}, el('span', { class: 'node' }, n.name), ' ', el('span', { class: 'pill m-' + (m || 'unknown').toLowerCase() }, m || '?'),
      sub.length ? el('ul', {}, sub.map(item)) : null);
  };
  return el('ul', { class: 'modetree' }, kids(null).map(item));
}

// The robot in its reference voxel: the four faces of the X–Y plane (gravity −Y), the
// two sides gripped to their faces, arms to the hip.
const SVGNS = 'http://www.w3.org/2000/svg';
const svg = (tag, attrs, ...kids) => {
  const e = document.createElementNS(SVGNS, tag);
  for (const [k, v] of Object.entries(attrs)) e.setAttribute(k, v);
  for (const k of kids) e.append(k);
  return e;
};
function facePoint(face, offset) {
  // Centre of the face of a 100×100 voxel at (50,50), y down on screen.
  const c = { Xpos: [100, 50], Xneg: [0, 50], Ypos: [50, 0], Yneg: [50, 100] }[face];
  if (!c) return null;
  const along = face === 'Xpos' || face === 'Xneg' ? [0, 1] : [1, 0];
  return [c[0] + along[0] * offset, c[1] + along[1] * offset];
}
function inward(face) {
  return { Xpos: [-1, 0], Xneg: [1, 0], Ypos: [0, 1], Yneg: [0, -1] }[face];
}
function configPicture(cfg) {
  const g = svg('svg', { viewBox: '-30 -30 160 185', class: 'voxel', role: 'img' });
  for (let i = -1; i <= 2; i++) {
    g.append(svg('line', { x1: i * 100, y1: -30, x2: i * 100, y2: 130, class: 'lattice' }));
    g.append(svg('line', { x1: -30, y1: i * 100, x2: 130, y2: i * 100, class: 'lattice' }));
  }
  g.append(svg('rect', { x: 0, y: 0, width: 100, height: 100, class: 'cell' }));
  for (const f of ['Xpos', 'Xneg', 'Ypos', 'Yneg']) {
    const p = facePoint(f, 0), n = inward(f);
    g.append(svg('text', { x: p[0] - n[0] * 18, y: p[1] - n[1] * 14 + 3, class: 'facelabel' }, f));
  }
  g.append(svg('text', { x: 112, y: 120, class: 'facelabel' }, 'g ↓'));
  if (!cfg || !cfg.face_a || !cfg.face_b) {
    g.append(svg('text', { x: 50, y: 55, class: 'unknown' }, cfg ? cfg.name : 'no state'));
    g.setAttribute('aria-label', 'configuration state unknown');
    return g;
  }
  g.setAttribute('aria-label', `state ${cfg.name}: side A on ${cfg.face_a}, side B on ${cfg.face_b}`);
  const same = cfg.face_a === cfg.face_b;
  const pa = facePoint(cfg.face_a, same ? -18 : 0), pb = facePoint(cfg.face_b, same ? 18 : 0);
  let hip;
  if (same) {
    const n = inward(cfg.face_a);
    const mid = facePoint(cfg.face_a, 0);
    hip = [mid[0] + n[0] * 22, mid[1] + n[1] * 22];
  } else if (cfg.kind === 'stretch') {
    hip = [50, 50];
  } else {
    // Turn: the hip sits at the corner between the two faces, pulled inwards.
    const na = inward(cfg.face_a), nb = inward(cfg.face_b);
    hip = [50 - (na[0] + nb[0]) * 22, 50 - (na[1] + nb[1]) * 22];
  }
  g.append(svg('polyline', { points: `${pa} ${hip} ${pb}`, class: 'arm' }));
  g.append(svg('circle', { cx: hip[0], cy: hip[1], r: 6, class: 'hip' }));
  for (const [p, side, face] of [[pa, 'A', cfg.face_a], [pb, 'B', cfg.face_b]]) {
    const n = inward(face);
    const horiz = n[0] === 0;
    g.append(svg('rect', { x: p[0] - (horiz ? 9 : 3) + n[0] * 3, y: p[1] - (horiz ? 3 : 9) + n[1] * 3, width: horiz ? 18 : 6, height: horiz ? 6 : 18, class: 'grip side' + side }));
    g.append(svg('text', { x: p[0] + n[0] * 16, y: p[1] + n[1] * 16 + 4, class: 'sidelabel' }, side));
  }
  g.append(svg('text', { x: 50, y: 148, class: 'statename' }, `${cfg.name} (${cfg.kind})`));
  return g;
}

// --- module set and team (issues 24 and 25)
const STATUS_CLASS = { ACCEPTED: 'up', NOT_ACCEPTED: 'm-hold', INVALID: 'lost', NOT_DISCOVERED: 'connecting' };
const ROLE_CLASS = { LEADER: 'm-operational', CANDIDATE: 'm-hold', FOLLOWER: 'connecting' };
// One line under a fleet card: the configuration (name, state, hash) and the team role.
function cfgLine(r) {
  const out = [];
  const m = r.modules;
  if (m) {
    const absent = m.slots.filter((s) => !s.present).length;
    out.push(el('span', { class: 'modules', 'data-config': m.config, 'data-status': m.status, 'data-hash': m.hash },
      el('span', { class: 'k' }, 'modules '), el('b', {}, m.config), ' ',
      el('span', { class: 'pill ' + (STATUS_CLASS[m.status] || '') }, m.status), ' ',
      el('code', {}, m.hash), absent ? el('span', { class: 'hint' }, ` ${absent} slot(s) absent`) : null,
      m.previous_hash ? el('span', { class: 'bad' }, ` changed from ${m.previous_hash}`) : null));
  }
  const t = r.team;
  if (t && t.roster.length) {
    out.push(el('span', { class: 'team', 'data-role': t.role },
      el('span', { class: 'k' }, ' team '), el('span', { class: 'pill ' + (ROLE_CLASS[t.role] || '') }, t.role),
      ` term ${t.term}, leader ${t.leader ?? 'none'}, ground ${t.ground_seen ? 'seen' : 'LOST'}`));
  }
  return out;
}

function renderModules() {
  S.dirty.modules = false;
  const ns = [...S.robots.keys()].sort((a, b) => a - b);
  $('#modules').replaceChildren(...ns.map((n) => {
    const r = S.robots.get(n), m = r.modules;
    if (!m) return el('div', { class: 'card', 'data-modules': n }, el('h2', {}, 'Robot ' + n), el('span', { class: 'hint' }, 'no module report or MODULES housekeeping yet'));
    const rows = m.slots.map((s) => el('tr', { class: 'slot-' + s.state, 'data-slot': s.name, 'data-state': s.state },
      el('td', {}, String(s.slot)), el('td', {}, s.name), el('td', {}, s.kind),
      el('td', { class: 'num' }, s.variant ?? ''), el('td', { class: 'num' }, s.revision ?? ''), el('td', { class: 'num' }, s.serial ?? ''),
      el('td', {}, s.present ? 'present' : 'absent'),
      el('td', { class: 'state' }, s.state)));
    const accept = m.status === 'NOT_ACCEPTED'
      ? el('button', { class: 'accept danger', 'data-robot': n, onclick: () => acceptConfig(n, m.hash) }, `Accept ${m.hash}`) : null;
    return el('div', { class: 'card', 'data-modules': n, 'data-hash': m.hash, 'data-config': m.config, 'data-status': m.status },
      el('h2', {}, `Robot ${n}: ${m.config} `, el('span', { class: 'pill ' + (STATUS_CLASS[m.status] || '') }, m.status), ' ', accept,
        el('span', { class: 'accept-result', 'data-robot': n })),
      el('div', { class: 'hint' },
        `hash ${m.hash}`, m.previous_hash ? el('span', { class: 'bad' }, ` (was ${m.previous_hash})`) : null,
        ` — against the accepted configuration: ${m.replacement}`,
        m.reason && m.reason !== 'NONE' && m.reason !== '?' ? el('span', { class: 'bad' }, ` — invalid: ${m.reason}${m.reason_slot ? ' (' + m.reason_slot + ')' : ''}`) : null,
        m.report_t_ms ? ` — report ${fmtDate(m.report_t_ms)}` : ' — no module report yet'),
      el('table', { class: 'grid slots' },
        el('thead', {}, el('tr', {}, ['Slot', 'Name', 'Type', 'Variant', 'Revision', 'Serial', 'Present', 'State'].map((h) => el('th', {}, h)))),
        el('tbody', {}, rows)));
  }));
}

// ACCEPT_CONFIG with the hash shown (hazardous in the MIB: the page asks first). The
// robot refuses a stale hash (CONFIG_HASH_STALE), shown beside the button.
async function acceptConfig(robot, hash) {
  const t = S.mib.tcs.find((x) => x.name === 'ACCEPT_CONFIG');
  const out = () => document.querySelector(`.accept-result[data-robot="${robot}"]`);
  if (!t || !(await confirmHazard(t, robot))) return;
  try {
    const r = await api('/api/tc', { method: 'POST', body: JSON.stringify({ robot, name: 'ACCEPT_CONFIG', args: { hash: parseInt(hash, 16) }, confirm: true }) });
    if (out()) { out().textContent = ` sent: request ${r.request_id}`; out().className = 'accept-result ok'; }
  } catch (e) {
    if (out()) { out().textContent = ' ' + e.message; out().className = 'accept-result bad'; }
  }
}

function renderTeam() {
  S.dirty.team = false;
  const ns = [...S.robots.keys()].sort((a, b) => a - b);
  const withTeam = ns.filter((n) => S.robots.get(n).team);
  // The newest term among the robots whose link is up (a lost robot's last report is
  // old), the robots acting as leader in it and the leaders the others name.
  const up = withTeam.filter((n) => S.robots.get(n).link === 'up').map((n) => S.robots.get(n).team);
  const term = up.reduce((m, t) => Math.max(m, t.term), -1);
  const acting = new Set(up.filter((t) => t.term === term && t.role === 'LEADER').map((t) => t.leader));
  const named = new Set(up.filter((t) => t.term === term && t.leader).map((t) => t.leader));
  const lost = up.filter((t) => !t.ground_seen).length;
  const ground = !up.length ? '' : lost ? ` — ground lost by ${lost} of ${up.length}` : ' — ground seen by all';
  const leader = acting.size === 1 && named.size === 1 && [...named][0] === [...acting][0] ? [...acting][0] : null;
  const summary = !withTeam.length ? 'No team status received (robots without a team roster report none).'
    : leader ? `Leader: robot ${leader} (term ${term})${ground}`
      : acting.size > 1 || named.size > 1 ? `Robots disagree on the leader of term ${term}: ${[...new Set([...acting, ...named])].join(', ')}${ground}`
        : named.size === 1 ? `No acting leader (term ${term} was led by robot ${[...named][0]})${ground}`
          : `No leader (term ${Math.max(term, 0)})${ground}`;
  $('#team-summary').textContent = summary;
  $('#team-summary').dataset.leader = leader ? String(leader) : '';
  $('#team tbody').replaceChildren(...withTeam.map((n) => {
    const r = S.robots.get(n), t = r.team, stale = r.link !== 'up';
    return el('tr', { 'data-robot': n, 'data-role': t.role, class: (t.role === 'LEADER' ? 'leader' : '') + (stale ? ' stale' : '') },
      el('td', {}, String(n), stale ? el('span', { class: 'bad', title: 'the last report before the link was lost' }, ` (link ${r.link})`) : null),
      el('td', { class: 'num' }, String(t.term)),
      el('td', {}, el('span', { class: 'pill ' + (ROLE_CLASS[t.role] || '') }, t.role)),
      el('td', { class: 'leader' }, t.leader ? 'robot ' + t.leader : 'none'),
      el('td', {}, t.roster.length ? t.roster.join(', ') : 'no roster'),
      el('td', { class: t.ground_seen ? 'ok' : 'bad' }, t.ground_seen ? 'seen' : 'lost'),
      el('td', {}, t.lease ? 'yes' : ''), el('td', {}, t.voted_for ?? ''),
      el('td', {}, t.auth_steps ? `${t.auth_steps} steps` : 'HOLD only'),
      el('td', {}, fmtTime(t.t_ms)));
  }));
}

// --- on-board plan (PUS 18): state from the robot's PLAN housekeeping and plan events,
// decoded by the collector with the MIB; a button per control TC, enabled only in the
// states the robot accepts it in (the collector's `controls`, which the server checks too).
const PLAN_CLASS = { RUNNING: 'm-operational', SUSPENDED: 'm-hold', ABORTED: 'lost', COMPLETED: 'up', LOADED: 'connecting', EMPTY: 'connecting' };
function onboardPanel(box, r) {
  const ob = r.onboard;
  box.dataset.state = ob ? ob.state : '';
  if (!ob) {
    box.replaceChildren(el('span', { class: 'k' }, 'on-board plan '), el('span', { class: 'hint' }, 'no plan status yet (PLAN housekeeping every 2 s)'));
    return;
  }
  const live = r.link === 'up';
  // The controls and their TCs come from the MIB view (`/api/mib` plan_controls).
  const buttons = (S.mib ? S.mib.plan_controls : []).map(({ control: c, tc, states }) => {
    const label = c === 'skip' ? 'Skip step' : c[0].toUpperCase() + c.slice(1);
    const ok = live && ob.controls.includes(c);
    const t = S.mib && S.mib.tcs.find((x) => x.name === tc);
    const why = !live ? `robot ${r.robot}'s link is ${r.link}` : ok ? `${tc}${t && t.hazard ? ' (hazardous: asks first)' : ''}` : `${tc} is accepted only with the plan ${states.join(' or ')}`;
    return el('button', { class: 'ob-ctl' + (t && t.hazard ? ' hazard' : ''), 'data-control': c, disabled: ok ? null : '', title: why, onclick: () => onboardControl(r.robot, c, tc) },
      c === 'skip' ? `${label} ${ob.done}` : label);
  });
  const sent = S.onboardTc.get(r.robot);
  let result = null;
  if (sent && sent.error) result = el('span', { class: 'ob-result bad' }, sent.error);
  else if (sent) {
    const cmd = S.commands.get(sent.id);
    const stages = cmd ? cmd.stages.map((s) => el('span', { class: s.success ? 'ok' : 'bad', 'data-stage': s.stage },
      ` ${s.success ? '✓' : '✗'} ${s.stage}${s.failure ? ' ' + s.failure.name : ''}`)) : [];
    const failed = cmd && cmd.stages.some((s) => !s.success);
    const done = cmd && cmd.stages.some((s) => s.stage === 'completion');
    result = el('span', { class: 'ob-result', 'data-request': sent.id, 'data-outcome': failed ? 'failed' : done ? 'completed' : 'pending' },
      `${sent.name} ${sent.id}:`, stages.length ? stages : el('span', { class: 'hint' }, ' sent'));
  }
  box.replaceChildren(
    el('div', { class: 'ob-line' },
      el('span', { class: 'k' }, 'on-board plan '),
      el('span', { class: 'pill ob-state ' + (PLAN_CLASS[ob.state] || ''), title: `plan state ${ob.state_code}` }, ob.state),
      ob.cause && ob.cause !== 'COMMAND' ? el('span', { class: ob.cause === 'DONE' ? 'hint' : 'bad ob-cause' }, ` ${ob.cause}`) : null,
      ob.state_code === 0 ? null : [
        el('span', { class: 'ob-steps' }, ` at step ${ob.next_step} of ${ob.steps} (${ob.done} done)`),
        el('progress', { max: Math.max(ob.steps, 1), value: ob.done }),
        el('code', { title: ob.crc ? 'plan ID, CRC-32 of the image' : 'plan ID' }, ob.plan_id + (ob.crc ? ' crc ' + ob.crc : '')),
        ob.waiting_for ? el('span', { class: 'hint ob-wait' }, ` waiting for robot ${ob.waiting_for[0]}'s step ${ob.waiting_for[1]}`) : null,
      ]),
    el('div', { class: 'ob-ctls' }, buttons, result));
}
async function onboardControl(robot, control, tc) {
  const t = S.mib.tcs.find((x) => x.name === tc);
  let confirm = false;
  if (t && t.hazard) {
    confirm = await confirmHazard(t, robot);
    if (!confirm) { S.onboardTc.set(robot, { error: `${tc} not sent` }); S.dirty.robots.add(robot); schedule(); return; }
  }
  try {
    const r = await api(`/api/robots/${robot}/onboard/${control}`, { method: 'POST', body: JSON.stringify({ confirm }) });
    S.onboardTc.set(robot, { id: r.request_id, name: tc });
  } catch (e) {
    S.onboardTc.set(robot, { error: e.message });
  }
  S.dirty.robots.add(robot);
  schedule();
}

function robotAlarms(n) {
  const open = [...S.alarms.values()].filter((a) => a.robot === n && (a.state === 'active' || a.state === 'acknowledged'));
  return open.map((a) => el('div', { class: 'alarm sev-' + a.severity + ' st-' + a.state },
    el('b', {}, a.source), ' ', a.message, ' ',
    a.state === 'active' ? el('button', { class: 'ack', onclick: () => ackAlarm(a.id) }, 'Acknowledge') : el('span', { class: 'hint' }, 'acknowledged')));
}

// Names, not numbers, for HK parameters whose values the MIB names.
const MODES = ['STANDBY', 'OPERATIONAL', 'SAFED'];
function hkText(name, v) {
  if (v === null || v === undefined || !S.mib) return fmtVal(v);
  switch (name) {
    case 'MODE': return MODES[v] ?? String(v);
    case 'PENDING_MODE': return v === 255 ? 'none' : MODES[v] ?? String(v);
    case 'CONFIG_STATE': case 'TARGET_STATE': { const s = S.mib.states.find((x) => x.id === v); return s ? s.name : v === 255 ? (name === 'CONFIG_STATE' ? 'unknown' : 'none') : String(v); }
    case 'BOLT_SIDE': return v === 0 ? 'A' : v === 1 ? 'B' : String(v);
    case 'LAST_FAULT_EVENT': { const e = S.mib.events.find((x) => x.id === v); return e ? e.name : v === 0 ? 'none' : String(v); }
    case 'CONFIG_HASH': return '0x' + (v >>> 0).toString(16).padStart(8, '0');
    case 'MODULES_PRESENT': return '0x' + (v >>> 0).toString(16).padStart(4, '0');
    default: {
      const p = S.params.get(name);
      const n = p && p.names && p.names.find(([x]) => x === v);
      return n ? n[1] : fmtVal(v);
    }
  }
}

// --- telemetry table
let hkRows = { robot: null, rows: new Map() };
function renderHk() {
  const n = Number($('#hk-robot').value);
  const r = S.robots.get(n);
  const filter = $('#hk-filter').value.trim().toUpperCase();
  const tbody = $('#hk-table tbody');
  const key = n + '|' + filter + '|' + (r ? Object.keys(r.hk).length : 0);
  if (hkRows.robot !== key) {
    hkRows = { robot: key, rows: new Map() };
    tbody.textContent = '';
    if (r) {
      for (const name of Object.keys(r.hk).sort()) {
        if (filter && !name.includes(filter)) continue;
        const p = S.params.get(name) || {};
        const l = p.limits;
        const v = el('td', { class: 'num' });
        const row = el('tr', { 'data-param': name },
          el('td', {}, el('a', { href: '#', onclick: (e) => { e.preventDefault(); plotParam(n, name); } }, name)),
          v, el('td', {}, p.unit || ''),
          el('td', { class: 'hint' }, l ? `${l.soft_lo} … ${l.soft_hi} / ${l.hard_lo} … ${l.hard_hi}${l.applies ? ' (' + l.applies + ')' : ''}` : ''),
          el('td', { class: 'hint' }, p.desc || ''));
        hkRows.rows.set(name, { row, v });
        tbody.append(row);
      }
    }
  }
  if (!r) return;
  for (const [name, { row, v }] of hkRows.rows) {
    const h = r.hk[name];
    if (!h) continue;
    v.textContent = hkText(name, h.value);
    row.className = 'lim-' + h.limit;
  }
}

// --- plots: the server decimates to min/max per pixel column; a zoom fetches finer data
let plot = null;
const plotState = { robot: null, param: null, t0: 0, t1: 0, live: true, span: 300, timer: null };
function plotParam(robot, param) {
  $('#plot-robot').value = String(robot);
  $('#plot-param').value = param;
  plotState.robot = robot;
  plotState.param = param;
  plotState.live = $('#plot-live').checked;
  fetchPlot();
}
async function fetchPlot() {
  const st = plotState;
  if (!st.param) return;
  const started = performance.now();
  if (st.live) {
    st.t1 = Date.now() + S.clockOffset;
    st.t0 = st.t1 - st.span * 1000;
  }
  const box = $('#plot');
  const width = Math.max(300, box.clientWidth || 700);
  const q = new URLSearchParams({ robot: st.robot, param: st.param, t0: Math.floor(st.t0), t1: Math.ceil(st.t1), columns: width });
  let d;
  try {
    d = await api('/api/series?' + q);
  } catch (e) {
    $('#plot-info').textContent = e.message;
    return;
  }
  const xs = d.points.map((p) => p[0] / 1000), lo = d.points.map((p) => p[1]), hi = d.points.map((p) => p[2]);
  const data = [xs, lo, hi];
  $('#plot-info').textContent = `${d.points.length} columns (min/max) for ${d.columns} px` + (d.skipped_non_finite ? `, ${d.skipped_non_finite} non-finite samples skipped` : '');
  // Fetch + draw time, read by the benchmark (after the draw below).
  requestAnimationFrame(() => metrics.plots.push({ ms: performance.now() - started, span_s: (st.t1 - st.t0) / 1000, points: d.points.length }));
  if (plot && plot.__key === st.robot + st.param) {
    plot.__fetching = true;
    plot.setData(data, false);
    plot.setScale('x', { min: st.t0 / 1000, max: st.t1 / 1000 });
    plot.__fetching = false;
    return;
  }
  if (plot) plot.destroy();
  const unit = d.unit ? ` [${d.unit}]` : '';
  plot = new uPlot({
    width, height: 320,
    scales: { x: { time: true } },
    axes: [{}, { size: 70 }],
    series: [{}, { label: st.param + ' min' + unit, stroke: '#2b6cb0', width: 1 }, { label: st.param + ' max' + unit, stroke: '#c05621', width: 1 }],
    bands: [{ series: [2, 1], fill: 'rgba(43,108,176,0.15)' }],
    cursor: { drag: { x: true, y: false } },
    hooks: {
      setSelect: [(u) => {
        if (u.select.width < 3) return;
        const min = u.posToVal(u.select.left, 'x'), max = u.posToVal(u.select.left + u.select.width, 'x');
        $('#plot-live').checked = false;
        st.live = false;
        st.t0 = min * 1000;
        st.t1 = max * 1000;
        u.setSelect({ width: 0, height: 0 }, false);
        fetchPlot();
      }],
    },
  }, data, box);
  plot.__key = st.robot + st.param;
  plot.setScale('x', { min: st.t0 / 1000, max: st.t1 / 1000 });
}
setInterval(() => { if (S.view === 'hk' && plotState.live && plotState.param) fetchPlot(); }, 2000);

// --- alarms
function renderAlarmBadge() {
  const n = [...S.alarms.values()].filter((a) => a.state === 'active').length;
  $('#alarm-count').textContent = n ? String(n) : '';
}
function renderAlarms() {
  S.dirty.alarms = false;
  const st = $('#al-state').value, rb = $('#al-robot').value, sev = SEV[$('#al-sev').value];
  const rows = [...S.alarms.values()]
    .filter((a) => (st === 'open' ? a.state === 'active' || a.state === 'acknowledged' : !st || a.state === st))
    .filter((a) => !rb || a.robot === Number(rb))
    .filter((a) => (SEV[a.severity] ?? 3) >= sev)
    .sort((a, b) => b.last_ms - a.last_ms)
    .map((a) => el('tr', { class: 'sev-' + a.severity + ' st-' + a.state, 'data-alarm': a.id },
      el('td', {}, String(a.id)), el('td', {}, String(a.robot)), el('td', {}, a.source),
      el('td', {}, el('span', { class: 'pill sev-' + a.severity }, a.severity)), el('td', {}, a.state),
      el('td', {}, fmtDate(a.first_ms)), el('td', {}, fmtDate(a.last_ms)), el('td', {}, a.message),
      el('td', {},
        a.state === 'active' || a.state === 'shelved' ? el('button', { class: 'ack', onclick: () => ackAlarm(a.id) }, 'Acknowledge') : null,
        a.state !== 'cleared' && a.state !== 'shelved' ? el('button', { class: 'shelve', onclick: () => shelveAlarm(a.id) }, 'Shelve 1 h') : null)));
  $('#alarms tbody').replaceChildren(...rows);
}
async function ackAlarm(id) {
  try { await api(`/api/alarms/${id}/ack`, { method: 'POST' }); } catch (e) { alert(e.message); }
}
async function shelveAlarm(id) {
  try { await api(`/api/alarms/${id}/shelve`, { method: 'POST', body: JSON.stringify({ minutes: 60 }) }); } catch (e) { alert(e.message); }
}

// --- events
function renderEvents() {
  S.dirty.events = false;
  const rb = $('#ev-robot').value, sev = SEV[$('#ev-sev').value], f = $('#ev-filter').value.trim().toUpperCase();
  const out = [];
  for (let i = S.events.length - 1; i >= 0 && out.length < 500; i--) {
    const e = S.events[i];
    if (rb && e.robot !== Number(rb)) continue;
    if ((SEV[e.severity] ?? 0) < sev) continue;
    if (f && !e.name.includes(f)) continue;
    out.push(el('tr', { class: 'sev-' + e.severity },
      el('td', {}, fmtTime(e.t_ms)), el('td', {}, String(e.robot)), el('td', {}, e.name),
      el('td', {}, el('span', { class: 'pill sev-' + e.severity }, e.severity)),
      el('td', {}, eventParams(e)),
      el('td', { class: 'hint' }, e.description)));
  }
  $('#events tbody').replaceChildren(...out);
}
// Event parameters by name; raw `value`/`limit` of a named parameter in engineering units.
function eventParams(e) {
  const pidEntry = e.params.find(([k]) => k === 'param_id');
  const p = pidEntry && S.mib ? S.mib.params.find((x) => x.id === pidEntry[1]) : null;
  return e.params.map(([k, v]) => {
    if (p && (k === 'value' || k === 'limit')) return `${k}=${fmtVal(v * p.scale + p.offset)} ${p.unit}`;
    return `${k}=${paramText(e.name, k, v)}`;
  }).join(' ');
}
// Names, not numbers, for TC arguments with a MIB enumeration.
function argText(tc, arg, v) {
  const t = S.mib && S.mib.tcs.find((x) => x.name === tc);
  const a = t && t.args.find((x) => x.name === arg);
  const e = a && a.enum && a.enum.find(([n]) => n === v);
  return e ? e[1] : String(v);
}
// Names, not numbers, for event parameters the MIB can name.
function paramText(event, key, v) {
  if (!S.mib) return String(v);
  if (key === 'state' || key === 'believed' || key === 'computed') { const s = S.mib.states.find((x) => x.id === v); return s ? s.name : String(v); }
  if (key === 'node') { const n = S.mib.nodes.find((x) => x.id === v); return n ? n.name : String(v); }
  if (key === 'param_id') { const p = S.mib.params.find((x) => x.id === v); return p ? p.name : String(v); }
  if (key === 'side') return v === 0 ? 'A' : v === 1 ? 'B' : String(v);
  if (key === 'cause') { const e = S.mib.events.find((x) => x.id === v); return v === 0 ? 'command' : e ? e.name : String(v); }
  if (key === 'event_id') { const e = S.mib.events.find((x) => x.id === v); return e ? e.name : String(v); }
  if (key === 'code') { const f = S.mib.failures.find((x) => x.code === v); return f ? f.name : String(v); }
  if (key === 'hash' || key.endsWith('_hash')) return '0x' + (v >>> 0).toString(16).padStart(8, '0');
  if ((event === 'MODE_CHANGED' && (key === 'from' || key === 'to')) || key === 'mode') return ['STANDBY', 'OPERATIONAL', 'SAFED'][v] ?? String(v);
  return String(v);
}

// --- commanding
function fillTcForm() {
  const sel = $('#tc-name');
  sel.textContent = '';
  const groups = new Map();
  for (const t of S.mib.tcs) {
    if (t.variable) continue;
    const g = 'service ' + t.service;
    if (!groups.has(g)) groups.set(g, el('optgroup', { label: g }));
    groups.get(g).append(el('option', { value: t.name }, t.name + (t.hazard ? ' ⚠' : '')));
  }
  sel.append(...groups.values());
  sel.value = 'PING';
  sel.onchange = buildArgs;
  buildArgs();
}
function buildArgs() {
  const t = S.mib.tcs.find((x) => x.name === $('#tc-name').value);
  $('#tc-desc').textContent = `${t.desc} — TC[${t.service},${t.subservice}]${t.function ? ' function ' + t.function : ''}; accepted in ${t.modes}` + (t.hazard ? `; HAZARDOUS: ${t.hazard}` : '');
  $('#tc-args').replaceChildren(...t.args.map((a) => {
    let input;
    if (a.enum) {
      input = el('select', { name: a.name }, a.enum.map(([v, n]) => el('option', { value: n }, `${n} (${v})`)));
    } else {
      input = el('input', { name: a.name, type: 'number', min: a.min, max: a.max, step: 1, required: '', value: Math.max(a.min, Math.min(a.max, 0)) });
    }
    return el('label', { class: 'arg' }, el('span', {}, a.name), input,
      el('span', { class: 'hint' }, `${a.enum ? '' : a.min + ' … ' + a.max + ' '}${a.unit || ''} — ${a.desc}`));
  }));
}
function readArgs(t) {
  const args = {};
  for (const a of t.args) {
    const input = $(`#tc-args [name="${a.name}"]`);
    if (a.enum) { args[a.name] = input.value; continue; }
    const v = Number(input.value);
    if (input.value === '' || !Number.isInteger(v)) throw new Error(`${a.name}: an integer is needed`);
    if (v < a.min || v > a.max) throw new Error(`${a.name}: ${v} is outside ${a.min} … ${a.max}`);
    args[a.name] = v;
  }
  return args;
}
function confirmHazard(t, robot) {
  return new Promise((resolve) => {
    $('#modal-title').textContent = `Send hazardous ${t.name} to robot ${robot}?`;
    $('#modal-text').textContent = t.hazard;
    const m = $('#modal');
    m.hidden = false;
    const done = (v) => { m.hidden = true; resolve(v); };
    $('#modal-yes').onclick = () => done(true);
    $('#modal-no').onclick = () => done(false);
  });
}
async function sendTc(e) {
  e.preventDefault();
  const t = S.mib.tcs.find((x) => x.name === $('#tc-name').value);
  const robot = Number($('#tc-robot').value);
  const out = $('#tc-result');
  let args;
  try { args = readArgs(t); } catch (err) { out.textContent = err.message; out.className = 'bad'; return; }
  let confirm = false;
  if (t.hazard) {
    confirm = await confirmHazard(t, robot);
    if (!confirm) { out.textContent = 'not sent'; out.className = 'hint'; return; }
  }
  try {
    const r = await api('/api/tc', { method: 'POST', body: JSON.stringify({ robot, name: t.name, args, confirm }) });
    out.textContent = `sent: request ${r.request_id}`;
    out.className = 'ok';
    out.dataset.request = r.request_id;
  } catch (err) {
    out.textContent = err.message;
    out.className = 'bad';
  }
}
function stageCell(c, stage) {
  const reps = c.stages.filter((s) => s.stage === stage);
  if (!reps.length) return el('td', { class: 'stage none', 'data-stage': stage }, '');
  return el('td', { class: 'stage', 'data-stage': stage }, reps.map((s) => el('div', { class: s.success ? 'ok' : 'bad' },
    (s.success ? '✓ ' : '✗ ') + (s.step !== null && s.step !== undefined ? `#${s.step} ` : '') + fmtTime(s.t_ms),
    s.failure ? el('div', { class: 'failure' }, s.failure.name, s.failure.fields.length ? ' ' + s.failure.fields.map(([k, v]) => `${k}=${paramText('', k, v)}`).join(' ') : '', el('span', { class: 'hint' }, ' ' + s.failure.data_hex)) : null)));
}
function renderHistory() {
  S.dirty.commands = false;
  const rows = [...S.commands.values()].reverse().slice(0, 300).map((c) => el('tr', { 'data-request': c.request_id },
    el('td', {}, c.request_id), el('td', {}, fmtTime(c.sent_ms)), el('td', {}, String(c.robot)), el('td', {}, c.name),
    el('td', {}, c.args.map(([k, v]) => `${k}=${argText(c.name, k, v)}`).join(' ')),
    stageCell(c, 'acceptance'), stageCell(c, 'start'), stageCell(c, 'progress'), stageCell(c, 'completion'),
    el('td', { class: 'hint' }, c.origin)));
  $('#history tbody').replaceChildren(...rows);
}

// --- plans
let planList = [];
async function loadPlans() {
  try { planList = await api('/api/plans'); } catch (e) { $('#plan-list').textContent = e.message; return; }
  $('#plan-list').replaceChildren(...(planList.length ? planList.map((p) => el('div', { class: 'card plan', 'data-plan-card': p.name },
    el('b', {}, p.name), ' ', el('span', { class: 'hint' }, `${p.description} — robots ${p.robots.join(', ')}, ${p.steps} steps`), ' ',
    p.hazards.length ? el('span', { class: 'bad', title: p.hazards.join('\n') }, `⚠ ${p.hazards.length} hazardous`) : null, ' ',
    el('button', { 'data-plan': p.name, onclick: () => startPlan(p) }, 'Start'))) : [el('span', { class: 'hint' },
      'No plans: list plan files in the collector configuration (plans = ["…"], docs/collector.md).')]),
  el('span', { id: 'plan-result' }));
}
function confirmPlan(p) {
  return new Promise((resolve) => {
    $('#modal-title').textContent = `Start plan ${p.name}? It sends hazardous TCs:`;
    $('#modal-text').textContent = p.hazards.join('\n');
    const m = $('#modal');
    m.hidden = false;
    const done = (v) => { m.hidden = true; resolve(v); };
    $('#modal-yes').onclick = () => done(true);
    $('#modal-no').onclick = () => done(false);
  });
}
async function startPlan(p) {
  const out = $('#plan-result');
  let confirm = false;
  if (p.hazards.length) {
    confirm = await confirmPlan(p);
    if (!confirm) { out.textContent = 'not started'; out.className = 'hint'; return; }
  }
  try {
    const r = await api('/api/plans', { method: 'POST', body: JSON.stringify({ name: p.name, confirm }) });
    out.textContent = `started: run ${r.run_id}`;
    out.className = 'ok';
    out.dataset.run = r.run_id;
  } catch (e) {
    out.textContent = e.message;
    out.className = 'bad';
  }
}
function renderPlans() {
  S.dirty.plans = false;
  const runs = [...S.plans.values()].sort((a, b) => b.started_ms - a.started_ms);
  $('#plan-runs').replaceChildren(...runs.map((r) => {
    const done = r.steps.filter((s) => s.state === 'done').length;
    return el('div', { class: 'card run st-' + r.state, 'data-run': r.run_id, 'data-state': r.state },
      el('h2', {}, `${r.plan} — ${r.state} (${done}/${r.steps.length} steps)`),
      r.detail ? el('div', { class: r.state === 'done' ? 'hint' : 'bad run-detail' }, r.detail) : null,
      el('progress', { max: r.steps.length, value: done }),
      el('table', { class: 'grid' }, el('tbody', {}, r.steps.map((s) => el('tr', { class: 'step-' + s.state, 'data-step': s.id },
        el('td', {}, s.id), el('td', {}, 'robot ' + s.robot), el('td', {}, s.label), el('td', { class: 'state' }, s.state),
        el('td', {}, s.request_id || ''), el('td', { class: 'hint' }, s.detail))))));
  }));
}

// ---- selects, tabs ------------------------------------------------------------------
let robotKey = '';
function refreshRobotSelects() {
  const ns = [...S.robots.keys()].sort((a, b) => a - b);
  const key = ns.join(',');
  if (key === robotKey) return;
  robotKey = key;
  for (const id of ['#hk-robot', '#plot-robot', '#tc-robot']) {
    const s = $(id), keep = s.value;
    s.replaceChildren(...ns.map((n) => el('option', { value: n }, 'robot ' + n)));
    if (ns.includes(Number(keep))) s.value = keep;
  }
  for (const id of ['#al-robot', '#ev-robot']) {
    const s = $(id), keep = s.value;
    s.replaceChildren(el('option', { value: '' }, 'all'), ...ns.map((n) => el('option', { value: n }, 'robot ' + n)));
    s.value = keep;
  }
}
function show(view) {
  S.view = view;
  for (const b of document.querySelectorAll('#tabs button')) b.classList.toggle('on', b.dataset.view === view);
  for (const s of document.querySelectorAll('.view')) s.classList.toggle('on', s.id === 'view-' + view);
  Object.assign(S.dirty, { events: true, alarms: true, commands: true, plans: true, modules: true, team: true });
  if (view === 'fleet') for (const n of S.robots.keys()) { S.dirty.robots.add(n); S.dirty.hk.add(n); }
  if (view === 'hk') { hkRows.robot = null; if (!plotState.param) plotParam(Number($('#hk-robot').value), 'V_BAT_A'); }
  if (view === 'plans') loadPlans();
  location.hash = view;
  schedule();
}

async function main() {
  for (const b of document.querySelectorAll('#tabs button')) b.onclick = () => show(b.dataset.view);
  for (const id of ['#al-state', '#al-robot', '#al-sev']) $(id).onchange = () => { S.dirty.alarms = true; schedule(); };
  for (const id of ['#ev-robot', '#ev-sev']) $(id).onchange = () => { S.dirty.events = true; schedule(); };
  $('#ev-filter').oninput = () => { S.dirty.events = true; schedule(); };
  $('#hk-robot').onchange = () => { hkRows.robot = null; schedule(); };
  $('#hk-filter').oninput = () => { hkRows.robot = null; schedule(); };
  $('#plot-robot').onchange = () => plotParam(Number($('#plot-robot').value), $('#plot-param').value);
  $('#plot-param').onchange = () => plotParam(Number($('#plot-robot').value), $('#plot-param').value);
  $('#plot-live').onchange = () => { plotState.live = $('#plot-live').checked; fetchPlot(); };
  for (const b of document.querySelectorAll('[data-range]')) b.onclick = () => {
    plotState.span = Number(b.dataset.range);
    plotState.live = true;
    $('#plot-live').checked = true;
    fetchPlot();
  };
  $('#tc-form').onsubmit = sendTc;
  S.mib = await api('/api/mib');
  S.mib.params.forEach((p) => S.params.set(p.name, p));
  $('#plot-param').replaceChildren(...S.mib.params.map((p) => el('option', { value: p.name }, p.name)));
  fillTcForm();
  applySnapshot(await api('/api/snapshot'));
  connect();
  // Ages tick even when nothing arrives.
  setInterval(schedule, 500);
  const v = location.hash.slice(1);
  show(['fleet', 'modules', 'team', 'hk', 'alarms', 'events', 'commands', 'plans'].includes(v) ? v : 'fleet');
}
main().catch((e) => setConn('error: ' + e.message, 'bad'));
