// Drives the real dashboard page in headless Chromium (Debian's package) against the
// real collector: `ground collect --http` following two real obsw processes (the page is
// fed by the collector's own robot threads, its alarms and its archive).
// Usage: node e2e.mjs GROUND_BINARY OBSW_BINARY [SCREENSHOT_DIR]
// Checks: both robots shown with modes and live values; a PING sent from the page
// completes with its stages; a battery sag injected through the simulator control
// port raises the collector's alarm, acknowledged from the page and seen acknowledged
// by `ground alarms list`; a plan from the collector's configuration, started from the
// page (its hazardous TC confirmed), runs with live step progress to completion; the
// event stream resumes after a reconnect; the page is still live after the 30 s
// downlink lease (the collector renews it); bound beyond localhost, TCs and plan starts
// need the token. Modules and team (issues 24, 25): three more obsw with a team, one
// built without bolters, each behind a UDP relay that can silence the ground, under a
// second collector: the Modules tab shows every slot and the configuration state, the
// Team tab the roster uploaded from the page and the leader the robots elect once the
// ground is silent; a robot rebuilt with another module set raises CONFIG_CHANGED on the
// page and in `ground alarms list`. On-board plans: robots 6 and 7 run a plan uploaded and
// started by `ground run --on-board --detach` before a third collector follows them: the
// fleet card's plan panel shows it running, Suspend/Resume (hazardous: confirmed) from the
// panel take robot 6's plan through SUSPENDED back to RUNNING and to COMPLETED, Abort takes
// robot 7's to ABORTED, each control's PUS 1 stages shown beside the buttons.
// DASH_E2E_ONLY=WORDS runs only the checks whose name contains WORDS.
// verifies: GND-ONBOARD-01, GND-ONBOARD-02
import { spawn, execFileSync } from 'node:child_process';
import { createInterface } from 'node:readline';
import { createSocket } from 'node:dgram';
import { createServer } from 'node:net';
import { mkdtempSync, rmSync, openSync, writeFileSync } from 'node:fs';
import { tmpdir } from 'node:os';
import { join } from 'node:path';
import { chromium } from 'playwright-core';

const [groundBin, obswBin, shotDir] = process.argv.slice(2);
if (!groundBin || !obswBin) {
  console.error('usage: node e2e.mjs GROUND_BINARY OBSW_BINARY [SCREENSHOT_DIR]');
  process.exit(2);
}
const T = 60_000; // generous: the machine is shared
let failures = 0;
const only = process.env.DASH_E2E_ONLY;
const step = async (name, fn) => {
  if (only && !name.includes(only)) return;
  const t0 = Date.now();
  try {
    await fn();
    console.log(`ok   ${name} (${Date.now() - t0} ms)`);
  } catch (e) {
    failures++;
    console.log(`FAIL ${name}: ${e.message.split('\n')[0]}`);
  }
};
const assert = (c, msg) => { if (!c) throw new Error(msg); };
const sleep = (ms) => new Promise((r) => setTimeout(r, ms));

// A port free for TCP now (the obsw and the dashboard bind it next).
const freePort = () => new Promise((resolve, reject) => {
  const srv = createServer();
  srv.once('error', reject);
  srv.listen(0, '127.0.0.1', () => { const p = srv.address().port; srv.close(() => resolve(p)); });
});

const work = mkdtempSync(join(tmpdir(), 'dash-e2e-'));
const children = [];
async function startObsw(robot, extra = [], fixedUdp = null) {
  const udp = fixedUdp || `127.0.0.1:${await freePort()}`;
  const ctl = `127.0.0.1:${await freePort()}`;
  // The bare-packet lab link (loopback): the page's own checks, not the space link's
  // (ground/tests/frames.rs runs the collector over frames).
  const p = spawn(obswBin, ['--robot', String(robot), '--udp', udp, '--sim-ctl', ctl, '--speed', '1', '--seed', String(robot), '--lab-bare-packets', ...extra],
    { stdio: ['ignore', 'pipe', 'ignore'] });
  children.push(p);
  await new Promise((resolve, reject) => {
    const rl = createInterface({ input: p.stdout });
    rl.once('line', (l) => (l.startsWith('READY') ? resolve() : reject(new Error('obsw: ' + l))));
    p.once('exit', (c) => reject(new Error(`obsw ${robot} exited with ${c}`)));
    setTimeout(() => reject(new Error(`obsw ${robot} did not start`)), T);
  });
  p.stdout.resume();
  return { robot, udp, sim_ctl: ctl, proc: p };
}

// A UDP relay between a collector and one obsw: TCs forwarded unless `silent` (the
// ground goes quiet), TM always forwarded back.
async function groundRelay(obswUdp) {
  const [host, port] = obswUdp.split(':');
  const front = createSocket('udp4'), back = createSocket('udp4');
  const r = { silent: false, ground: null, close: () => { front.close(); back.close(); } };
  front.on('message', (m, from) => { r.ground = from; if (!r.silent) back.send(m, Number(port), host); });
  back.on('message', (m) => { if (r.ground) front.send(m, r.ground.port, r.ground.address); });
  await new Promise((res) => front.bind(0, '127.0.0.1', res));
  await new Promise((res) => back.bind(0, '127.0.0.1', res));
  r.udp = `127.0.0.1:${front.address().port}`;
  return r;
}

// `ground collect --http ADDR` with its own archive in `dir`; resolves once the API answers.
async function startCollector(dir, robots, http, extra = []) {
  const args = ['--archive', join(dir, 'a.db'), 'collect', '--plain', '--http', http, '--lab-udp', ...extra];
  for (const r of robots) args.push('--robot', `${r.robot}=${r.udp}`);
  const log = openSync(join(dir, 'collect.log'), 'a');
  const p = spawn(groundBin, args, { stdio: ['ignore', 'ignore', log] });
  children.push(p);
  const url = `http://${http.replace('0.0.0.0', '127.0.0.1')}/`;
  const end = Date.now() + T;
  for (;;) {
    if (p.exitCode !== null) throw new Error('ground collect exited with ' + p.exitCode);
    try { const r = await fetch(url + 'api/mib'); if (r.status < 500) break; } catch { /* not yet */ }
    if (Date.now() > end) throw new Error('ground collect --http did not start');
    await sleep(200);
  }
  return { proc: p, url };
}

const robots = [await startObsw(1), await startObsw(2)];
const started = Date.now();
// The plans the collector offers: its configuration lists them (robots come from --robot).
writeFileSync(join(work, 'r2-mode.toml'), `name = "r2-mode"
description = "robot 2: ping, operational, pause, standby"
[[robot]]
number = 2
[[step]]
id = "ping"
robot = 2
action = "command"
tc = "PING"
[[step]]
id = "operational"
robot = 2
action = "mode"
mode = "operational"
[[step]]
id = "pause"
robot = 2
action = "wait"
seconds = 1
[[step]]
id = "standby"
robot = 2
action = "mode"
mode = "standby"
`);
writeFileSync(join(work, 'collect.toml'), 'plans = ["r2-mode.toml"]\n');
const collector = await startCollector(work, robots, `127.0.0.1:${await freePort()}`, ['--config', join(work, 'collect.toml')]);
const info = { url: collector.url, robots };
console.log('dashboard at', info.url);

const profile = mkdtempSync(join(tmpdir(), 'dash-chromium-'));
const browser = await chromium.launchPersistentContext(profile, {
  executablePath: process.env.CHROMIUM || '/usr/bin/chromium',
  headless: true,
  viewport: { width: 1400, height: 900 },
  args: ['--no-sandbox', '--disable-gpu', '--disable-background-networking', '--disable-component-update',
    '--disable-sync', '--no-first-run'],
});
const page = browser.pages()[0] || await browser.newPage();
page.setDefaultTimeout(T);
page.on('pageerror', (e) => { failures++; console.log('FAIL page error:', e.message); });
page.on('dialog', (d) => { console.log('dialog:', d.message()); d.dismiss(); });
const shot = async (name) => { if (shotDir) await page.screenshot({ path: join(shotDir, name), fullPage: false }); };
const tab = (v) => page.click(`#tabs button[data-view="${v}"]`);

async function sendTc(robot, name, args = {}, hazardous = false) {
  await tab('commands');
  await page.selectOption('#tc-robot', String(robot));
  await page.selectOption('#tc-name', name);
  for (const [k, v] of Object.entries(args)) {
    const sel = `#tc-args [name="${k}"]`;
    if (await page.$eval(sel, (e) => e.tagName) === 'SELECT') await page.selectOption(sel, String(v));
    else await page.fill(sel, String(v));
  }
  await page.evaluate(() => { delete document.querySelector('#tc-result').dataset.request; });
  await page.click('#tc-send');
  if (hazardous) {
    await page.waitForSelector('#modal:not([hidden])');
    await page.click('#modal-yes');
  }
  await page.waitForFunction(() => document.querySelector('#tc-result').dataset.request || document.querySelector('#tc-result.bad'));
  const id = await page.$eval('#tc-result', (e) => e.dataset.request || e.textContent);
  assert(!/error|outside|no /.test(id), `${name} refused: ${id}`);
  return id;
}

try {
  await page.goto(info.url);

  await step('fleet shows both robots with modes and live values', async () => {
    for (const n of [1, 2]) {
      await page.waitForFunction((n) => {
        const c = document.querySelector('#robot-' + n);
        return c && /STANDBY|OPERATIONAL|SAFED/.test(c.querySelector('.mode').textContent)
          && /\d+\.\d+ V/.test(c.querySelector('[data-param="V_BAT_A"]').textContent)
          && c.querySelector('.link').textContent === 'up'
          && c.querySelector('svg.voxel .grip');
      }, n);
    }
    const v1 = await page.$eval('#robot-1 [data-param="V_BAT_A"]', (e) => e.textContent);
    await page.waitForFunction((v) => document.querySelector('#robot-1 [data-param="I_BAT"]').textContent !== '—', v1);
    // live: the last-heard age keeps being small
    const age = await page.$eval('#robot-1 .age', (e) => e.textContent);
    assert(/heard (< 1|\d+) s ago/.test(age), 'age shown: ' + age);
    // The whole mode tree has modes (the collector asks for them), not only names.
    await page.waitForFunction(() => !document.querySelector('#robot-1 .modetree').textContent.includes('?'));
    const tree = await page.$eval('#robot-1 .modetree', (e) => e.textContent);
    assert(tree.includes('SIDE_A') && tree.includes('GRIPPER_B'), 'mode tree: ' + tree);
    // V_REG's limits hold only in OPERATIONAL/SAFED (MIB limits_in): no colour in STANDBY.
    const vreg = await page.$eval('#robot-1 [data-param="V_REG"]', (e) => e.className);
    assert(vreg.includes('lim-off'), 'V_REG in STANDBY: ' + vreg);
    await shot('dashboard-fleet.png');
  });

  await step('PING sent from the page completes with its stages shown', async () => {
    const id = await sendTc(1, 'PING');
    await page.waitForSelector(`#history tr[data-request="${id}"] td[data-stage="completion"] .ok`);
    const acc = await page.$eval(`#history tr[data-request="${id}"] td[data-stage="acceptance"]`, (e) => e.textContent);
    assert(acc.startsWith('✓'), 'acceptance shown: ' + acc);
    const api = await page.evaluate(async (id) => (await fetch('/api/tc/' + id)).json(), id);
    const stages = api.stages.map((s) => s.stage + ':' + s.success);
    assert(stages.includes('acceptance:true') && stages.includes('completion:true'), 'API stages ' + stages);
  });

  await step('a refused TC shows its failure code name', async () => {
    // RECONFIGURE is refused in standby: acceptance or start fails with a MIB code name.
    const id = await sendTc(2, 'RECONFIGURE', { from: 'Xneg', to: 'Xpos' });
    await page.waitForSelector(`#history tr[data-request="${id}"] .failure`);
    const f = await page.$eval(`#history tr[data-request="${id}"] .failure`, (e) => e.textContent);
    assert(/[A-Z_]{4,}/.test(f), 'failure name: ' + f);
    await shot('dashboard-commands.png');
  });

  await step('injected battery sag raises an alarm that is acknowledged from the page', async () => {
    await sendTc(1, 'MODE_SET', { node: 'ROBOT', mode: 'OPERATIONAL', submode: 0 }, true);
    await tab('fleet');
    await page.waitForFunction(() => document.querySelector('#robot-1 .mode').textContent === 'OPERATIONAL');
    const ctl = info.robots.find((r) => r.robot === 1).sim_ctl.split(':');
    const sock = createSocket('udp4');
    await new Promise((res, rej) => sock.send('battery-sag 9.2\n', Number(ctl[1]), ctl[0], (e) => (e ? rej(e) : res())));
    sock.close();
    await page.waitForSelector('#robot-1 .ralarms .alarm button.ack');
    const text = await page.$eval('#robot-1 .ralarms', (e) => e.textContent);
    assert(/V_BAT|LOW_BATTERY/.test(text), 'battery alarm: ' + text);
    await shot('dashboard-alarm.png');
    await tab('alarms');
    await page.waitForSelector('#alarms tr.st-active button.ack');
    await shot('dashboard-alarms.png');
    const id = await page.$eval('#alarms tr.st-active', (e) => e.dataset.alarm);
    await page.click(`#alarms tr[data-alarm="${id}"] button.ack`);
    await page.waitForSelector(`#alarms tr[data-alarm="${id}"].st-acknowledged`);
    // One alarm set: the collector's archive has the acknowledgement.
    const rows = execFileSync(groundBin, ['--archive', join(work, 'a.db'), 'alarms', 'list', '--json'], { encoding: 'utf8' })
      .split('\n').filter((l) => l.trim()).map((l) => JSON.parse(l));
    const row = rows.find((r) => String(r.id) === String(id));
    assert(row && row.state === 'acknowledged', `ground alarms list: ${JSON.stringify(row)}`);
    // The sag is cleared after the telemetry step, which looks for its limit colours
    // (clearing it here raced the next HK report).
  });

  await step('events list names events and their parameters', async () => {
    await tab('events');
    await page.waitForSelector('#events tbody tr');
    const t = await page.$eval('#events tbody', (e) => e.textContent);
    assert(/MODE_CHANGED/.test(t) && /OPERATIONAL/.test(t), 'events: ' + t.slice(0, 200));
    await shot('dashboard-events.png');
  });

  await step('telemetry table has units and limit colours; plot draws', async () => {
    await tab('hk');
    await page.selectOption('#hk-robot', '1');
    await page.waitForSelector('#hk-table tr[data-param="V_BAT_A"][class^="lim-"]');
    const unit = await page.$eval('#hk-table tr[data-param="V_BAT_A"] td:nth-child(3)', (e) => e.textContent);
    assert(unit === 'V', 'unit of V_BAT_A: ' + unit);
    await page.waitForSelector('#hk-table tr.lim-hard, #hk-table tr.lim-soft', { timeout: 10_000 }).catch(() => null);
    assert(await page.$('#hk-table tr.lim-hard, #hk-table tr.lim-soft'), 'some value out of limits is coloured');
    const ctl = info.robots.find((r) => r.robot === 1).sim_ctl.split(':');
    const sock2 = createSocket('udp4');
    await new Promise((res, rej) => sock2.send('clear\n', Number(ctl[1]), ctl[0], (e) => (e ? rej(e) : res())));
    sock2.close();
    await page.click('#hk-table tr[data-param="V_BAT_A"] a');
    await page.waitForSelector('#plot .u-over');
    await page.click('[data-range="60"]');
    const mode = await page.$eval('#hk-table tr[data-param="MODE"] td.num', (e) => e.textContent);
    assert(/STANDBY|OPERATIONAL|SAFED/.test(mode), 'MODE by name: ' + mode);
    await page.waitForFunction(() => /columns/.test(document.querySelector('#plot-info').textContent));
    await shot('dashboard-telemetry.png');
  });

  await step('event stream resumes after a reconnect without loss', async () => {
    const r = await page.evaluate(async () => {
      // Count messages with IDs; drop the connection; the browser reconnects with
      // Last-Event-ID and the IDs must continue without a gap.
      const seen = [];
      const q = new URLSearchParams({ since: String(window.dashState.lastId) });
      const es1 = new EventSource('/api/stream?' + q);
      await new Promise((res) => { es1.onmessage = (e) => { seen.push(Number(e.lastEventId)); if (seen.length >= 5) res(); }; });
      es1.close();
      await new Promise((r) => setTimeout(r, 1500));
      const es2 = new EventSource('/api/stream?since=' + seen[seen.length - 1]);
      await new Promise((res) => { es2.onmessage = (e) => { seen.push(Number(e.lastEventId)); if (seen.length >= 40) res(); }; });
      es2.close();
      return seen;
    });
    for (let i = 1; i < r.length; i++) assert(r[i] === r[i - 1] + 1, `gap between ${r[i - 1]} and ${r[i]}`);
  });

  await step('a plan started from the page runs with live step progress to completion', async () => {
    await tab('plans');
    await page.waitForSelector('#plan-list button[data-plan="r2-mode"]');
    const card = await page.$eval('[data-plan-card="r2-mode"]', (e) => e.textContent);
    assert(/robots 2, 4 steps/.test(card) && /2 hazardous/.test(card), 'plan card: ' + card);
    // The page keeps every plan message it is sent: the steps' states are recorded as
    // they arrive over the event stream.
    await page.evaluate(() => {
      window.planTrail = {};
      const orig = window.dashState.plans.set.bind(window.dashState.plans);
      window.dashState.plans.set = (k, v) => {
        for (const s of v.steps) {
          const t = (window.planTrail[s.id] ||= []);
          if (t[t.length - 1] !== s.state) t.push(s.state);
        }
        return orig(k, v);
      };
    });
    await page.click('#plan-list button[data-plan="r2-mode"]');
    // MODE_SET is hazardous: the page asks first.
    await page.waitForSelector('#modal:not([hidden])');
    const q = await page.$eval('#modal-text', (e) => e.textContent);
    assert(/MODE_SET/.test(q), 'confirmation names the hazardous TC: ' + q);
    await page.click('#modal-yes');
    await page.waitForFunction(() => document.querySelector('#plan-result').dataset.run);
    const run = await page.$eval('#plan-result', (e) => e.dataset.run);
    await page.waitForSelector(`[data-run="${run}"] tr.step-running`);
    // A second start while it runs: refused, the page says why.
    await page.click('#plan-list button[data-plan="r2-mode"]');
    await page.waitForSelector('#modal:not([hidden])');
    await page.click('#modal-yes');
    await page.waitForFunction(() => /one plan per robot/.test(document.querySelector('#plan-result').textContent));
    await page.waitForSelector(`[data-run="${run}"][data-state="done"]`);
    await shot('dashboard-plans.png');
    const rows = await page.$$eval(`[data-run="${run}"] tr`, (trs) => trs.map((t) => t.querySelector('.state').textContent));
    assert(rows.length === 4 && rows.every((x) => x === 'done'), 'steps: ' + rows);
    const trail = await page.evaluate(() => window.planTrail);
    for (const id of ['ping', 'operational', 'pause', 'standby']) {
      const t = (trail[id] || []).join('>');
      assert(/running/.test(t) && t.endsWith('done'), `step ${id} seen live as ${t}`);
    }
    // Its TCs are in the command history, sent by the plan over the collector's link.
    await tab('commands');
    await page.waitForFunction(() => [...document.querySelectorAll('#history tbody tr')]
      .filter((t) => t.lastChild.textContent === 'plan r2-mode').length === 3);
  });

  await step('the page is still live after the 30 s downlink lease (the collector renews it)', async () => {
    const wait = 40_000 - (Date.now() - started);
    if (wait > 0) await sleep(wait);
    await tab('fleet');
    const heard = await page.evaluate(async () => (await (await fetch('/api/snapshot')).json()).robots.map((r) => [r.link, Date.now() - r.last_heard_ms]));
    for (const [link, age] of heard) assert(link === 'up' && age < 5000, `link ${link}, last heard ${age} ms ago`);
    const age = await page.$eval('#robot-1 .age', (e) => e.textContent);
    assert(/heard (< 1|[0-4]) s ago/.test(age), 'age shown: ' + age);
  });

  // ---- modules and team: robots 3, 4, 5 with a team, robot 5 without bolters -------
  const here = new URL('.', import.meta.url).pathname;
  const modulesDir = join(here, '../../../plans/modules');
  const teamPorts = [await freePort(), await freePort(), await freePort()];
  // Team packets are authenticated (--team-key) where the obsw supports it; the page test
  // runs them bare on loopback.
  const bare = execFileSync(obswBin, ['--help'], { encoding: 'utf8' }).includes('--lab-team-bare') ? ['--lab-team-bare'] : [];
  const teamArgs = (robot) => {
    const a = ['--team-udp', `127.0.0.1:${teamPorts[robot - 3]}`, '--team-state', join(work, `team-${robot}.state`), ...bare];
    for (const r of [3, 4, 5]) if (r !== robot) a.push('--peer', `${r}=127.0.0.1:${teamPorts[r - 3]}`);
    return a;
  };
  const setOf = (robot) => join(modulesDir, robot === 5 ? 'locomotion-only.toml' : 'full.toml');
  const teamRobots = [];
  for (const r of [3, 4, 5]) teamRobots.push(await startObsw(r, [...teamArgs(r), '--modules', setOf(r)]));
  const relays = [];
  for (const o of teamRobots) relays.push(await groundRelay(o.udp));
  const dir3 = mkdtempSync(join(tmpdir(), 'dash-e2e-team-'));
  const c3 = await startCollector(dir3, teamRobots.map((o, i) => ({ robot: o.robot, udp: relays[i].udp })), `127.0.0.1:${await freePort()}`);
  const p3 = await browser.newPage();
  p3.setDefaultTimeout(T);
  p3.on('pageerror', (e) => { failures++; console.log('FAIL page error:', e.message); });
  const shot3 = async (name) => { if (shotDir) await p3.screenshot({ path: join(shotDir, name), fullPage: false }); };
  await p3.goto(c3.url);
  const tab3 = (v) => p3.click(`#tabs button[data-view="${v}"]`);

  await step('modules: each robot\'s module set and configuration state', async () => {
    await p3.waitForSelector('#robot-5 .cfgline .modules[data-config="LOCOMOTION_ONLY"]', { state: 'attached' });
    const line = await p3.$eval('#robot-5 .cfgline', (e) => e.textContent);
    // ACCEPTED, or NOT_ACCEPTED where the obsw accepts the factory (full) set at start.
    assert(/LOCOMOTION_ONLY/.test(line) && /ACCEPTED/.test(line) && /0x[0-9a-f]{8}/.test(line) && /2 slot\(s\) absent/.test(line), 'fleet line: ' + line);
    await tab3('modules');
    await p3.waitForSelector('[data-modules="3"][data-config="FULL"][data-status="ACCEPTED"] tr[data-slot="BOLTER_A"][data-state="ok"]');
    await p3.waitForSelector('[data-modules="5"][data-config="LOCOMOTION_ONLY"] tr[data-slot="BOLTER_B"][data-state="absent"]');
    // The obsw accepts the factory (full) set at start: without bolters it waits for the
    // ground to accept its hash. Accepted from the page (hazardous: confirmed).
    const st5 = await p3.$eval('[data-modules="5"]', (e) => e.dataset.status);
    assert(st5 === 'NOT_ACCEPTED', 'robot 5 state ' + st5);
    const g = await p3.$eval('[data-modules="5"] tr[data-slot="GRIPPER_A"]', (e) => [...e.children].map((c) => c.textContent));
    assert(g[2] === 'gripper' && /^\d+$/.test(g[4]) && /^\d+$/.test(g[5]) && g[6] === 'present' && g[7] === 'ok', 'gripper A row: ' + g);
    const rows = await p3.$$eval('[data-modules="3"] tbody tr', (t) => t.length);
    assert(rows === 14, 'slots of robot 3: ' + rows);
    const h3 = await p3.$eval('[data-modules="3"]', (e) => e.dataset.hash), h5 = await p3.$eval('[data-modules="5"]', (e) => e.dataset.hash);
    assert(h3 !== h5 && /^0x[0-9a-f]{8}$/.test(h3), `hashes ${h3} ${h5}`);
    await shot3('dashboard-modules.png');
    await p3.click('[data-modules="5"] button.accept');
    await p3.waitForSelector('#modal:not([hidden])');
    await p3.click('#modal-yes');
    await p3.waitForSelector('[data-modules="5"][data-status="ACCEPTED"]', { timeout: 20_000 });
    assert(!(await p3.$('[data-modules="5"] button.accept')), 'no accept button once accepted');
  });

  await step('team: roster from the page, the leader elected while the ground is silent', async () => {
    const roster = { robot_1: 3, robot_2: 4, robot_3: 5, robot_4: 0, robot_5: 0, robot_6: 0, robot_7: 0, robot_8: 0 };
    for (const r of [3, 4, 5]) {
      const st = await p3.evaluate(async (b) => (await fetch('/api/tc', { method: 'POST', headers: { 'Content-Type': 'application/json' }, body: JSON.stringify(b) })).status,
        { robot: r, name: 'TEAM_ROSTER', args: roster });
      assert(st === 200, 'TEAM_ROSTER: ' + st);
    }
    await tab3('team');
    await p3.waitForFunction(() => {
      const rows = [...document.querySelectorAll('#team tbody tr')];
      return rows.length === 3 && rows.every((r) => r.children[4].textContent === '3, 4, 5' && r.children[5].textContent === 'seen');
    });
    const t0 = Date.now();
    for (const r of relays) r.silent = true;
    await p3.waitForFunction(() => {
      const rows = [...document.querySelectorAll('#team tbody tr')];
      const lead = document.querySelector('#team-summary').dataset.leader;
      return lead && rows.length === 3 && rows.filter((r) => r.dataset.role === 'LEADER').length === 1
        && document.querySelector(`#team tr[data-robot="${lead}"]`).dataset.role === 'LEADER'
        && rows.every((r) => r.children[3].textContent === 'robot ' + lead && r.children[5].textContent === 'lost');
    });
    const summary = await p3.$eval('#team-summary', (e) => e.textContent);
    console.log(`     ${summary}, shown ${((Date.now() - t0) / 1000).toFixed(1)} s after the ground went silent`);
    await shot3('dashboard-team.png');
    for (const r of relays) r.silent = false;
    // The ground is back: every robot sees it, the leader steps down.
    await p3.waitForFunction(() => [...document.querySelectorAll('#team tbody tr')].every((r) => r.children[5].textContent === 'seen' && r.dataset.role !== 'LEADER'));
    await p3.waitForFunction(() => /No acting leader|No leader/.test(document.querySelector('#team-summary').textContent)
      && /ground seen by all/.test(document.querySelector('#team-summary').textContent) && !document.querySelector('#team-summary').dataset.leader);
  });

  await step('a robot rebuilt with another module set raises CONFIG_CHANGED', async () => {
    const old = teamRobots[2];
    const oldHash = await p3.$eval('[data-modules="5"]', (e) => e.dataset.hash).catch(() => null);
    old.proc.kill('SIGTERM');
    await new Promise((r) => { old.proc.once('exit', r); setTimeout(r, 5000); });
    teamRobots[2] = await startObsw(5, [...teamArgs(5), '--modules', join(modulesDir, 'full.toml')], old.udp);
    await tab3('modules');
    await p3.waitForSelector('[data-modules="5"][data-config="FULL"] tr[data-slot="BOLTER_A"][data-state="changed"]');
    const head = await p3.$eval('[data-modules="5"]', (e) => e.textContent);
    assert(!oldHash || head.includes('was ' + oldHash), 'previous hash shown: ' + head.slice(0, 200));
    await tab3('alarms');
    await p3.selectOption('#al-state', '');
    await p3.waitForSelector('#alarms tbody tr[data-alarm]');
    await p3.waitForFunction(() => [...document.querySelectorAll('#alarms tbody tr')].some((r) => r.children[2].textContent === 'CONFIG_CHANGED' && r.children[1].textContent === '5'));
    await shot3('dashboard-config-changed.png');
    const rows = execFileSync(groundBin, ['--archive', join(dir3, 'a.db'), 'alarms', 'list', '--json'], { encoding: 'utf8' })
      .split('\n').filter((l) => l.trim()).map((l) => JSON.parse(l));
    assert(rows.some((r) => r.source === 'CONFIG_CHANGED' && r.robot === 5), 'ground alarms list: ' + JSON.stringify(rows.map((r) => r.source)));
  });
  await step('team: a robot whose link is lost keeps its last row, marked and left out', async () => {
    await tab3('team');
    const lead = await p3.$eval('#team-summary', (e) => e.textContent);
    const gone = teamRobots[1];
    gone.proc.kill('SIGKILL');
    await p3.waitForSelector('#team tr.stale[data-robot="4"]', { state: 'attached' });
    const row = await p3.$eval('#team tr[data-robot="4"] td', (e) => e.textContent);
    assert(/link lost/.test(row), 'row of robot 4: ' + row);
    const now = await p3.$eval('#team-summary', (e) => e.textContent);
    assert(!/disagree/.test(now), `summary ${lead} -> ${now}`);
  });
  await p3.close();
  c3.proc.kill('SIGTERM');
  for (const r of relays) r.close();
  for (const o of teamRobots) if (o.proc.exitCode === null) o.proc.kill('SIGTERM');

  await step('bound beyond localhost: the page needs the token, and commands with it', async () => {
    const dir2 = mkdtempSync(join(tmpdir(), 'dash-e2e-tok-'));
    // Its own robot: the first collector holds robots[0], and a second ground process on
    // one robot is refused (one commanding ground per robot, ground::robot_lock).
    const own = await startObsw(1);
    const c2 = await startCollector(dir2, [own], `0.0.0.0:${await freePort()}`, ['--http-token', 'e2e-secret']);
    try {
      const i2 = { url: c2.url + '?token=e2e-secret' };
      const url = new URL(i2.url);
      url.hostname = '127.0.0.1';
      const p2 = await browser.newPage();
      const bare = url.origin + '/';
      await p2.goto(bare);
      await p2.waitForFunction(() => /error/.test(document.querySelector('#conn').textContent));
      const refused = await p2.evaluate(async () => (await fetch('/api/tc', { method: 'POST', headers: { 'Content-Type': 'application/json' }, body: JSON.stringify({ robot: 1, name: 'PING', args: {} }) })).status);
      assert(refused === 401, 'POST /api/tc without the token: ' + refused);
      const planRefused = await p2.evaluate(async () => (await fetch('/api/plans', { method: 'POST', headers: { 'Content-Type': 'application/json' }, body: JSON.stringify({ name: 'r2-mode', confirm: true }) })).status);
      assert(planRefused === 401, 'POST /api/plans without the token: ' + planRefused);
      await p2.goto(url.href);
      await p2.waitForSelector('#robot-1');
      await p2.click('#tabs button[data-view="commands"]');
      await p2.selectOption('#tc-name', 'PING');
      await p2.click('#tc-send');
      await p2.waitForFunction(() => document.querySelector('#tc-result').dataset.request);
      const id = await p2.$eval('#tc-result', (e) => e.dataset.request);
      await p2.waitForSelector(`#history tr[data-request="${id}"] td[data-stage="completion"] .ok`);
      await p2.close();
    } finally {
      c2.proc.kill('SIGTERM');
      await new Promise((r) => { c2.proc.once('exit', r); setTimeout(r, 5000); });
      rmSync(dir2, { recursive: true, force: true });
    }
  });

  // ---- on-board plans: robots 6 and 7 run their plan themselves ---------------------------
  const obDir = mkdtempSync(join(tmpdir(), 'dash-e2e-onboard-'));
  const obRobots = [await startObsw(6), await startObsw(7)];
  // Robot 6: a ping, a 15 s wait, a ping; robot 7: a ping and a 120 s wait (aborted).
  writeFileSync(join(obDir, 'onboard.toml'), `name = "onboard"
description = "robots 6 and 7 on board"
[[robot]]
number = 6
[[robot]]
number = 7
[[step]]
id = "r6-ping"
robot = 6
action = "command"
tc = "PING"
[[step]]
id = "r6-hold"
robot = 6
action = "wait"
seconds = 15
[[step]]
id = "r6-ping2"
robot = 6
action = "command"
tc = "PING"
[[step]]
id = "r7-ping"
robot = 7
action = "command"
tc = "PING"
[[step]]
id = "r7-hold"
robot = 7
action = "wait"
seconds = 120
`);
  // Uploaded and started by the CLI, which then leaves the robots to it (one commanding
  // ground per robot: the collector follows them afterwards).
  execFileSync(groundBin, ['--archive', join(obDir, 'run.db'), 'run', '--on-board', '--detach', '--lab-udp',
    ...obRobots.flatMap((o) => ['--robot', `${o.robot}=${o.udp}`]), join(obDir, 'onboard.toml')], { encoding: 'utf8' });
  const c6 = await startCollector(obDir, obRobots, `127.0.0.1:${await freePort()}`);
  const p6 = await browser.newPage();
  const shot6 = async (name) => { if (shotDir) await p6.screenshot({ path: join(shotDir, name), fullPage: false }); };
  p6.setDefaultTimeout(T);
  p6.on('pageerror', (e) => { failures++; console.log('FAIL page error:', e.message); });
  p6.on('dialog', (d) => d.dismiss());
  await p6.goto(c6.url);
  const obState = (n) => p6.$eval(`#robot-${n} .onboard`, (e) => e.dataset.state);
  const enabled = (n) => p6.$$eval(`#robot-${n} .onboard button.ob-ctl:not([disabled])`, (b) => b.map((x) => x.dataset.control).join(','));

  await step('on-board plan: the panel shows it running, suspend and resume from the buttons, completed', async () => {
    // Every plan state the page is sent, per robot, in order.
    await p6.evaluate(() => {
      window.obTrail = {};
      const orig = window.dashState.robots.get.bind(window.dashState.robots);
      const seen = new Set();
      window.dashState.robots.get = (n) => {
        const r = orig(n);
        if (r && !seen.has(r)) {
          seen.add(r);
          let ob = r.onboard;
          if (ob) (window.obTrail[n] ||= []).push(ob.state);
          Object.defineProperty(r, 'onboard', { get: () => ob, set: (v) => {
            const t = (window.obTrail[n] ||= []);
            if (v && t[t.length - 1] !== v.state) t.push(v.state);
            ob = v;
          } });
        }
        return r;
      };
    });
    await p6.waitForSelector('#robot-6 .onboard[data-state="RUNNING"]');
    const line = await p6.$eval('#robot-6 .onboard', (e) => e.textContent);
    assert(/on-board plan/.test(line) && /at step 1 of 3 \(1 done\)/.test(line) && /0x[0-9a-f]{8}/.test(line), 'panel: ' + line);
    assert(await enabled(6) === 'suspend,abort', 'buttons while running: ' + await enabled(6));
    // The server refuses what the robot would: RESUME of a running plan.
    const refused = await p6.evaluate(async () => { const r = await fetch('/api/robots/6/onboard/resume', { method: 'POST', headers: { 'Content-Type': 'application/json' }, body: '{"confirm": true}' }); return [r.status, (await r.json()).error]; });
    assert(refused[0] === 409 && /SUSPENDED/.test(refused[1]), 'resume while running: ' + refused);
    await p6.click('#robot-6 .onboard button[data-control="suspend"]');
    await p6.waitForSelector('#robot-6 .onboard[data-state="SUSPENDED"]');
    await p6.waitForSelector('#robot-6 .ob-result[data-outcome="completed"] [data-stage="completion"].ok');
    const res = await p6.$eval('#robot-6 .ob-result', (e) => e.textContent);
    assert(/PLAN_SUSPEND/.test(res) && /✓ acceptance/.test(res) && /✓ completion/.test(res), 'suspend stages: ' + res);
    assert(await enabled(6) === 'resume,abort,skip', 'buttons while suspended: ' + await enabled(6));
    await shot6('dashboard-onboard.png');
    // RESUME is hazardous in the MIB: the page asks first.
    await p6.click('#robot-6 .onboard button[data-control="resume"]');
    await p6.waitForSelector('#modal:not([hidden])');
    const q = await p6.$eval('#modal-title', (e) => e.textContent);
    assert(/PLAN_RESUME/.test(q) && /robot 6/.test(q), 'confirmation: ' + q);
    await p6.click('#modal-yes');
    await p6.waitForFunction(() => {
      const r = document.querySelector('#robot-6 .ob-result[data-outcome="completed"]');
      return r && /PLAN_RESUME/.test(r.textContent);
    });
    await p6.waitForSelector('#robot-6 .onboard[data-state="COMPLETED"]', { timeout: 40_000 });
    const done = await p6.$eval('#robot-6 .onboard', (e) => e.textContent);
    assert(/3 done/.test(done), 'completed panel: ' + done);
    assert(await enabled(6) === '', 'no control after completion: ' + await enabled(6));
    const trail = (await p6.evaluate(() => window.obTrail[6] || [])).join('>');
    assert(/RUNNING>SUSPENDED>RUNNING>COMPLETED$/.test(trail), 'robot 6 seen as ' + trail);
    // In the command history with its origin.
    await p6.click('#tabs button[data-view="commands"]');
    await p6.waitForFunction(() => [...document.querySelectorAll('#history tbody tr')]
      .filter((t) => /PLAN_(SUSPEND|RESUME)/.test(t.children[3].textContent) && t.lastChild.textContent === 'page: on-board plan').length === 2);
    await p6.click('#tabs button[data-view="fleet"]');
  });

  await step('on-board plan: abort from the panel leaves the plan aborted', async () => {
    await p6.waitForSelector('#robot-7 .onboard[data-state="RUNNING"]');
    await p6.click('#robot-7 .onboard button[data-control="abort"]');
    await p6.waitForSelector('#robot-7 .onboard[data-state="ABORTED"]');
    await p6.waitForSelector('#robot-7 .ob-result[data-outcome="completed"]');
    assert(await enabled(7) === '', 'no control after the abort: ' + await enabled(7));
    const st = await obState(7);
    assert(st === 'ABORTED', 'robot 7: ' + st);
  });
  await p6.close();
  c6.proc.kill('SIGTERM');
  for (const o of obRobots) if (o.proc.exitCode === null) o.proc.kill('SIGTERM');
  rmSync(obDir, { recursive: true, force: true });
} finally {
  await browser.close();
  rmSync(profile, { recursive: true, force: true });
  for (const c of children.reverse()) {
    if (c.exitCode === null) {
      c.kill('SIGTERM');
      await new Promise((r) => { c.once('exit', r); setTimeout(() => { c.kill('SIGKILL'); r(); }, 5000); });
    }
  }
  rmSync(work, { recursive: true, force: true });
}
console.log(failures ? `${failures} check(s) failed` : 'all dashboard browser checks passed');
process.exit(failures ? 1 : 0);
