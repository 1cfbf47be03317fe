// Dashboard benchmark: the page of a running `ground collect --http` following N real
// obsw processes with HK at F Hz (started by ground/bench/dashboard_bench.sh), shown in
// headless Chromium. Measures, over the same run:
// - update latency: HK generation time → value drawn on the fleet view (page's own
//   metric, sampled per robot card per frame), against the baseline of a bare
//   EventSource in the same page (HK time → message delivered to JS, nothing drawn);
// - browser CPU: renderer main-thread busy share (DevTools Performance.getMetrics
//   TaskDuration) and the CPU of every Chromium process (/proc), fleet view vs the
//   baseline of the same page on a view that draws no HK (Plans);
// - server CPU (/proc of the collector process) and the obsw processes' CPU.
// Usage: node bench.mjs URL COLLECTOR_PID OBSW_PIDS(comma-separated) [robots=50] [hz=10] [seconds=20]
import { mkdtempSync, rmSync, readdirSync, readFileSync } from 'node:fs';
import { tmpdir } from 'node:os';
import { join } from 'node:path';
import { chromium } from 'playwright-core';

const [url, collectorPid, obswPids, robots = '50', hz = '10', seconds = '20'] = process.argv.slice(2);
const secs = Number(seconds);
const TICK = 100; // USER_HZ on Linux
const info = { url };

function cpuTicks(pids) {
  let t = 0;
  for (const p of pids) {
    try {
      const f = readFileSync(`/proc/${p}/stat`, 'utf8');
      const parts = f.slice(f.lastIndexOf(')') + 2).split(' ');
      t += Number(parts[11]) + Number(parts[12]);
    } catch { /* process ended */ }
  }
  return t;
}
function pidsWith(text) {
  // The browser process (its command line names our profile) and all its descendants.
  const procs = [];
  for (const d of readdirSync('/proc')) {
    if (!/^\d+$/.test(d)) continue;
    try {
      const stat = readFileSync(`/proc/${d}/stat`, 'utf8');
      const ppid = Number(stat.slice(stat.lastIndexOf(')') + 2).split(' ')[1]);
      procs.push({ pid: Number(d), ppid, cmd: readFileSync(`/proc/${d}/cmdline`, 'utf8') });
    } catch { /* gone */ }
  }
  const out = new Set(procs.filter((p) => p.cmd.includes(text)).map((p) => p.pid));
  for (let grew = true; grew;) {
    grew = false;
    for (const p of procs) if (out.has(p.ppid) && !out.has(p.pid)) { out.add(p.pid); grew = true; }
  }
  return [...out];
}
const median = (a) => { const s = [...a].sort((x, y) => x - y); return s.length ? s[Math.floor(s.length / 2)] : NaN; };
const pct = (a, p) => { const s = [...a].sort((x, y) => x - y); return s.length ? s[Math.min(s.length - 1, Math.floor(s.length * p))] : NaN; };

const profile = mkdtempSync(join(tmpdir(), 'dash-bench-'));
const ctx = await chromium.launchPersistentContext(profile, {
  executablePath: process.env.CHROMIUM || '/usr/bin/chromium', headless: true, viewport: { width: 1600, height: 1000 },
  args: ['--no-sandbox', '--disable-gpu', '--disable-background-networking', '--disable-component-update', '--disable-sync', '--no-first-run'],
});
const page = ctx.pages()[0] || await ctx.newPage();
const cdp = await ctx.newCDPSession(page);
await cdp.send('Performance.enable');
await page.goto(info.url);
await page.waitForFunction((n) => document.querySelectorAll('.robot').length >= n, Number(robots), { timeout: 60000 });
// Baseline transport latency: a bare EventSource in the same page.
await page.evaluate(() => {
  window.rawLat = [];
  const es = new EventSource('/api/stream?since=' + window.dashState.lastId);
  es.onmessage = (e) => { const m = JSON.parse(e.data); if (m.type === 'hk') window.rawLat.push(Date.now() - m.t_ms); };
});
const chromePids = pidsWith(profile);
const serverPid = [Number(collectorPid)];
const obsw = obswPids.split(',').map(Number);

async function phase(view) {
  await page.click(`#tabs button[data-view="${view}"]`);
  await page.waitForTimeout(2000);
  await page.evaluate(() => { window.dashMetrics.latency.length = 0; window.rawLat.length = 0; window.dashMetrics.messages = 0; });
  const m0 = Object.fromEntries((await cdp.send('Performance.getMetrics')).metrics.map((m) => [m.name, m.value]));
  const c0 = cpuTicks(chromePids), s0 = cpuTicks(serverPid), o0 = cpuTicks(obsw), w0 = Date.now();
  await page.waitForTimeout(secs * 1000);
  const m1 = Object.fromEntries((await cdp.send('Performance.getMetrics')).metrics.map((m) => [m.name, m.value]));
  const c1 = cpuTicks(chromePids), s1 = cpuTicks(serverPid), o1 = cpuTicks(obsw), wall = (Date.now() - w0) / 1000;
  const r = await page.evaluate(() => ({ lat: window.dashMetrics.latency.slice(), raw: window.rawLat.slice(), msgs: window.dashMetrics.messages }));
  return {
    view,
    messages_per_s: +(r.msgs / wall).toFixed(1),
    main_thread_busy_pct: +((100 * (m1.TaskDuration - m0.TaskDuration)) / wall).toFixed(1),
    script_pct: +((100 * (m1.ScriptDuration - m0.ScriptDuration)) / wall).toFixed(1),
    chromium_cpu_pct: +((100 * (c1 - c0)) / TICK / wall).toFixed(1),
    server_cpu_pct: +((100 * (s1 - s0)) / TICK / wall).toFixed(1),
    obsw_cpu_pct_all: +((100 * (o1 - o0)) / TICK / wall).toFixed(1),
    drawn_latency_ms: r.lat.length ? { median: median(r.lat), p95: pct(r.lat, 0.95), p99: pct(r.lat, 0.99), n: r.lat.length } : null,
    delivered_latency_ms: { median: median(r.raw), p95: pct(r.raw, 0.95), p99: pct(r.raw, 0.99), n: r.raw.length },
  };
}

const results = { robots: Number(robots), hz: Number(hz), seconds: secs, phases: [] };
results.phases.push(await phase('plans')); // baseline: same page and stream, HK not drawn
results.phases.push(await phase('fleet'));
// A day of 10 Hz data (864 000 samples) drawn: click "1 day" five times.
await page.click('#tabs button[data-view="hk"]');
await page.selectOption('#plot-robot', '1');
await page.selectOption('#plot-param', 'V_BAT_A');
await page.waitForSelector('#plot .u-over');
const dayTimes = [];
for (let i = 0; i < 5; i++) {
  const before = await page.evaluate(() => window.dashMetrics.plots.length);
  await page.click('[data-range="86400"]');
  await page.waitForFunction((b) => window.dashMetrics.plots.length > b && window.dashMetrics.plots.at(-1).span_s > 80000, before);
  dayTimes.push(await page.evaluate(() => window.dashMetrics.plots.at(-1)));
  await page.waitForTimeout(500);
}
results.day_plot_ms = { median: median(dayTimes.map((p) => p.ms)), max: Math.max(...dayTimes.map((p) => p.ms)), columns: dayTimes[0].points };
console.log(JSON.stringify(results, null, 1));
await ctx.close();
rmSync(profile, { recursive: true, force: true });
