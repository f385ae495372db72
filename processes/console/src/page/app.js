// The harvest console page: one push connection (a WebSocket at /api/live) brings the status
// and the camera views as they are made and carries the page's commands, marks and clock
// readings; nothing is polled. Without a push connection (the console has no room for another
// watcher, or it is being reconnected) commands and marks go as plain POSTs. No framework,
// nothing loaded from elsewhere.
'use strict';

const $ = (id) => document.getElementById(id);
const state = {
  session: Math.floor(Math.random() * 2 ** 52) + 1,
  token: sessionStorage.getItem('harvest-token') || '',
  controlling: false,
  heartbeat: null,
  offsetNs: null,
  bestRttMs: Infinity,
  viewSeq: 0,
  status: null,
  pressures: [[], [], []],
  live: null,
  nextId: 1,
  pending: new Map(),
  clockSent: new Map(),
  liveProblem: null,
};
// Read by the browser test and by anyone curious (devtools).
window.consoleStats = { views: 0, latenciesMs: [], estopClickNs: null, answers: [], statuses: 0, liveOpens: 0 };

const sleep = (ms) => new Promise((resolve) => setTimeout(resolve, ms));
const fmt = (value, digits) => (value === null || value === undefined ? '-' : Number(value).toFixed(digits));

// --- Clock: the stack clock (CLOCK_MONOTONIC) estimated from the page's clock, from readings
// asked over the push connection.
function askClock() {
  const live = state.live;
  if (!live || live.readyState !== WebSocket.OPEN) return;
  const id = state.nextId++;
  state.clockSent.set(id, performance.now());
  live.send(JSON.stringify({ op: 'clock', id }));
}
function onClock(message) {
  const t0 = state.clockSent.get(message.id);
  if (t0 === undefined) return;
  state.clockSent.delete(message.id);
  const t1 = performance.now();
  const rtt = t1 - t0;
  // Keep the estimate of the fastest round trip (its midpoint is the tightest).
  if (rtt <= state.bestRttMs * 1.5 || state.offsetNs === null) {
    state.bestRttMs = Math.min(rtt, state.bestRttMs);
    state.offsetNs = message.now_ns - ((t0 + t1) / 2) * 1e6;
  }
}
function monoNowNs() {
  return performance.now() * 1e6 + state.offsetNs;
}

// --- Camera view: the newest pushed view is shown; a view that arrives while the previous one
// is still being decoded replaces any other waiting one (a slow page skips views).
const views = { waiting: null, decoding: false, previousUrl: null };
function onView(buffer) {
  const length = new DataView(buffer).getUint32(0, true);
  const header = JSON.parse(new TextDecoder().decode(new Uint8Array(buffer, 4, length)));
  views.waiting = { header, blob: new Blob([new Uint8Array(buffer, 4 + length)], { type: 'image/jpeg' }) };
  if (!views.decoding) showViews();
}
async function showViews() {
  views.decoding = true;
  const img = $('camera');
  while (views.waiting) {
    const { header, blob } = views.waiting;
    views.waiting = null;
    const url = URL.createObjectURL(blob);
    img.src = url;
    try {
      await img.decode();
    } catch (error) {
      continue;
    }
    if (views.previousUrl) URL.revokeObjectURL(views.previousUrl);
    views.previousUrl = url;
    if (header.view_seq !== state.viewSeq) {
      state.viewSeq = header.view_seq;
      window.consoleStats.views += 1;
      if (state.offsetNs !== null) {
        const latencies = window.consoleStats.latenciesMs;
        latencies.push((monoNowNs() - header.capture_ns) / 1e6);
        if (latencies.length > 5000) latencies.shift();
      }
      $('view-info').textContent = `view ${header.view_seq}, frame ${header.frame_seq}`;
    }
    drawOverlay();
  }
  views.decoding = false;
}

// --- The push connection.
function connectLive() {
  const scheme = location.protocol === 'https:' ? 'wss' : 'ws';
  const live = new WebSocket(`${scheme}://${location.host}/api/live?session=${state.session}`);
  live.binaryType = 'arraybuffer';
  state.live = live;
  let opened = false;
  live.onopen = () => {
    opened = true;
    state.liveProblem = null;
    window.consoleStats.liveOpens += 1;
    askClock();
  };
  live.onmessage = (event) => {
    if (typeof event.data !== 'string') {
      onView(event.data);
      return;
    }
    const message = JSON.parse(event.data);
    if (message.type === 'status') {
      window.consoleStats.statuses += 1;
      renderStatus(message);
    } else if (message.type === 'answer') {
      const waiting = state.pending.get(message.id);
      if (waiting) {
        state.pending.delete(message.id);
        waiting(message);
      }
    } else if (message.type === 'clock') {
      onClock(message);
    }
  };
  live.onclose = async () => {
    state.live = null;
    // Commands still waiting for an answer over this connection: sent, answer lost.
    for (const [id, waiting] of state.pending) {
      waiting({ accepted: false, reason: 'the push connection closed before the answer came' });
      state.pending.delete(id);
    }
    state.liveProblem = opened
      ? 'the console connection was lost; reconnecting'
      : 'the console has no room for another live view; the e-stop and commands still go through';
    $('mode-name').textContent = opened ? 'reconnecting' : $('mode-name').textContent;
    showReach(state.status ? reachProblems(state.status) : [state.liveProblem]);
    await sleep(opened ? 500 : 5000);
    connectLive();
  };
}

function drawOverlay() {
  const canvas = $('overlay');
  const status = state.status;
  const view = status && status.view;
  if (!view) return;
  canvas.width = view.width_px;
  canvas.height = view.height_px;
  const ctx = canvas.getContext('2d');
  ctx.clearRect(0, 0, canvas.width, canvas.height);
  const detections = status.detections;
  if (!detections) return;
  ctx.font = '11px system-ui, sans-serif';
  for (const apple of detections.apples) {
    const [x, y, w, h] = apple.box_px.map((v) => v / view.scale);
    const reachable = apple.reachable[0] || apple.reachable[1];
    ctx.setLineDash(reachable ? [] : [4, 3]);
    ctx.lineWidth = apple.target_of ? 3 : 1.5;
    ctx.strokeStyle = apple.target_of ? '#ffd400' : reachable ? '#2fbf4a' : '#e0412f';
    ctx.beginPath();
    ctx.ellipse(x + w / 2, y + h / 2, w / 2 + 2, h / 2 + 2, 0, 0, 2 * Math.PI);
    ctx.stroke();
    let label = `#${apple.id} ${Math.round(apple.confidence * 100)}% ${apple.depth_source}`;
    if (apple.target_of) label += ` arm ${apple.target_of}`;
    else if (!reachable) label += ' out of reach';
    ctx.setLineDash([]);
    ctx.fillStyle = '#000a';
    const width = ctx.measureText(label).width + 6;
    ctx.fillRect(x, Math.max(0, y - 14), width, 13);
    ctx.fillStyle = '#fff';
    ctx.fillText(label, x + 3, Math.max(10, y - 4));
  }
}

// --- Top view: x forward (up on the screen), y left (left on the screen).
function drawTopView(status) {
  const canvas = $('topview');
  const ctx = canvas.getContext('2d');
  const scale = 170; // px per m
  const origin = [canvas.width / 2, canvas.height - 20];
  const toScreen = (p) => [origin[0] - p[1] * scale, origin[1] - p[0] * scale];
  ctx.clearRect(0, 0, canvas.width, canvas.height);
  ctx.strokeStyle = '#dde3db';
  ctx.lineWidth = 1;
  for (let x = 0; x <= 2.0; x += 0.5) {
    const [, sy] = toScreen([x, 0]);
    ctx.beginPath(); ctx.moveTo(0, sy); ctx.lineTo(canvas.width, sy); ctx.stroke();
    ctx.fillStyle = '#9aa69a'; ctx.fillText(`${x.toFixed(1)} m`, 4, sy - 2);
  }
  const colours = ['#1f6fd1', '#d17a1f'];
  status.arms.forEach((arm, i) => {
    if (!arm || !arm.tip_m) return;
    const points = [arm.base_m, arm.pivot_m, arm.tip_m].map(toScreen);
    ctx.strokeStyle = colours[i];
    ctx.lineWidth = 5;
    ctx.beginPath();
    ctx.moveTo(...points[0]);
    for (const p of points.slice(1)) ctx.lineTo(...p);
    ctx.stroke();
    ctx.fillStyle = colours[i];
    ctx.beginPath(); ctx.arc(...points[2], 5, 0, 2 * Math.PI); ctx.fill();
    ctx.fillText(`arm ${i + 1} ${arm.phase}`, points[0][0] + (i === 0 ? -70 : 10), points[0][1] + 14);
  });
  const detections = status.detections;
  if (detections) {
    for (const apple of detections.apples) {
      if (!apple.position_m) continue;
      const [sx, sy] = toScreen(apple.position_m);
      const reachable = apple.reachable[0] || apple.reachable[1];
      ctx.fillStyle = apple.target_of ? '#ffd400' : reachable ? '#2fbf4a' : '#e0412f';
      ctx.beginPath(); ctx.arc(sx, sy, Math.max(3, apple.radius_m * scale), 0, 2 * Math.PI); ctx.fill();
    }
  }
}

function drawPressures() {
  const canvas = $('plot-pressure');
  const ctx = canvas.getContext('2d');
  ctx.clearRect(0, 0, canvas.width, canvas.height);
  const max = 3000;
  const colours = ['#1f6fd1', '#d17a1f', '#555'];
  state.pressures.forEach((series, k) => {
    ctx.strokeStyle = colours[k];
    ctx.lineWidth = 1.5;
    ctx.beginPath();
    series.forEach((value, i) => {
      const x = (i / 149) * canvas.width;
      const y = canvas.height - (Math.min(value, max) / max) * (canvas.height - 4) - 2;
      if (i === 0) ctx.moveTo(x, y); else ctx.lineTo(x, y);
    });
    ctx.stroke();
  });
  ctx.fillStyle = '#6b756a';
  ctx.fillText('0-3000 mmH2O, 30 s: arm 1 blue, arm 2 orange, source grey', 4, 10);
}

// --- Reach: whether the page can command the robot. Every reason it cannot is shown in the
// banner under the header (a console that cannot reach the executive must not look alive).
const EXECUTIVE_SILENT_MS = 1000;
function reachProblems(status) {
  const problems = [];
  if (state.liveProblem) problems.push(state.liveProblem);
  const links = status.links || {};
  if (links.estop && !links.estop.ok) problems.push(`e-stop path down: ${links.estop.problem}`);
  if (links.commands && !links.commands.ok) problems.push(`command path down: ${links.commands.problem}`);
  const mode = status.mode;
  if (!mode) problems.push('no executive heard (is it running?)');
  else if (mode.age_ms > EXECUTIVE_SILENT_MS) problems.push(`executive silent for ${(mode.age_ms / 1000).toFixed(1)} s`);
  return problems;
}
function showReach(problems) {
  const banner = $('reach');
  banner.hidden = problems.length === 0;
  banner.textContent = problems.length ? 'NOT LIVE OR CANNOT REACH THE EXECUTIVE: ' + problems.join('; ') : '';
}

// --- Status.
function renderStatus(status) {
  showReach(reachProblems(status));
  state.status = status;
  const mode = status.mode;
  $('mode-name').textContent = mode ? mode.name : 'unknown (no executive)';
  const estop = $('estop-state');
  if (mode && mode.estop) {
    estop.textContent = 'E-STOP ENGAGED';
    estop.className = 'estop-engaged';
  } else {
    estop.textContent = 'e-stop released';
    estop.className = 'estop-released';
  }
  $('controller').textContent = mode && mode.controller ? mode.controller : 'none';
  // "Next stop" is a harvesting command (the executive refuses it in any other mode).
  $('btn-next-stop').disabled = !(mode && mode.name === 'harvesting');
  $('mode-change').textContent = mode ? mode.last_change : '';
  status.arms.forEach((arm, i) => {
    const n = i + 1;
    $(`arm${n}-phase`).textContent = arm ? arm.phase : 'no state';
    $(`arm${n}-apple`).textContent = arm && arm.apple_id ? arm.apple_id : '-';
    $(`arm${n}-harvested`).textContent = arm ? arm.harvested : '-';
    $(`arm${n}-enabled`).textContent = mode ? (mode.arms_enabled[i] ? 'yes' : 'no') : '-';
    $(`arm${n}-target`).textContent = arm && arm.target_apple_id ? arm.target_apple_id : '-';
  });
  const vacuum = status.vacuum;
  if (vacuum) {
    vacuum.valve_open.forEach((open, k) => {
      $(`valve${k + 1}`).className = 'valve' + (open ? ' open' : '') + (vacuum.in_transit[k] ? ' moving' : '');
      $(`valve${k + 1}`).dataset.open = open ? '1' : '0';
    });
    vacuum.pressure_mmh2o.forEach((value, k) => {
      $(`pressure${k + 1}`).textContent = value.toFixed(0);
      state.pressures[k].push(value);
      if (state.pressures[k].length > 150) state.pressures[k].shift();
    });
    drawPressures();
  }
  const fruit = status.fruit;
  $('fruit-attempted').textContent = fruit.apples_attempted;
  $('fruit-harvested').textContent = fruit.apples_harvested;
  $('fruit-success').textContent = fruit.rates.success_rate === null ? '-' : fmt(fruit.rates.success_rate * 100, 1) + ' %';
  $('fruit-s-apple').textContent = fmt(fruit.rates.seconds_per_apple, 2);
  $('fruit-s-attempt').textContent = fmt(fruit.rates.seconds_per_attempt, 2);
  $('processes').innerHTML = status.processes.map((p) =>
    `<tr class="${p.state === 'failed' ? 'failed' : p.age_ms > 2000 ? 'stale' : ''}"><td>${p.name}</td><td>${p.state === 'failed' ? 'FAILED (not critical: the stack goes on)' : p.state}</td><td>${p.pid}</td>` +
    `<td>${p.restarts}</td><td>${p.rate_hz.toFixed(1)}</td><td>${p.detail} ${p.value}</td><td>${p.device_error ?? '-'}</td><td>${(p.age_ms / 1000).toFixed(1)} s</td></tr>`).join('');
  const recorder = status.recorder;
  $('recorder').textContent = recorder
    ? `${recorder.state}, ${recorder.messages} messages, ${recorder.detail} ${recorder.value} (file and size: see \`harvest rec info\`)`
    : 'not running';
  const events = $('events');
  const atBottom = events.scrollTop + events.clientHeight >= events.scrollHeight - 4;
  events.textContent = status.events.join('\n');
  if (atBottom) events.scrollTop = events.scrollHeight;
  if (mode && mode.platform.present && mode.platform.position_m) {
    const p = mode.platform.position_m;
    $('platform-state').textContent = `at ${p[0].toFixed(3)} / ${p[1].toFixed(3)} m${mode.platform.moving ? ', moving' : ''}`;
  }
  drawTopView(status);
  drawOverlay();
}

// --- Commands.
// Over the push connection when it is open (no new connection needed: a console full of
// watchers cannot keep a command out), else as a POST.
function request(op, fields, path) {
  const live = state.live;
  if (live && live.readyState === WebSocket.OPEN) {
    const id = state.nextId++;
    return new Promise((resolve) => {
      state.pending.set(id, resolve);
      live.send(JSON.stringify({ op, id, ...fields }));
    });
  }
  return fetch(path, { method: 'POST', headers: { 'Content-Type': 'application/json' }, body: JSON.stringify(fields) })
    .then((response) => response.json());
}

async function sendCommand(command, quiet) {
  let answer;
  try {
    answer = await request('command', { token: state.token, session: state.session, command }, '/api/command');
  } catch (error) {
    answer = { accepted: false, unreachable: true, reason: 'console unreachable: ' + error };
  }
  if (answer.unreachable) showReach([answer.reason]);
  if (!quiet || !answer.accepted) {
    const element = $('last-answer');
    element.textContent = `${command.command}: ${answer.accepted ? 'accepted' : 'REFUSED'}: ${answer.reason}`;
    element.className = answer.accepted ? 'accepted' : 'refused';
    window.consoleStats.answers.push({ command: command.command, ...answer });
  }
  return answer;
}

function setControlling(on, why) {
  state.controlling = on;
  if (state.heartbeat) clearInterval(state.heartbeat);
  state.heartbeat = null;
  if (on) {
    state.heartbeat = setInterval(async () => {
      const answer = await sendCommand({ command: 'heartbeat' }, true);
      if (!answer.accepted) setControlling(false, answer.reason);
    }, 200);
  }
  $('control-status').textContent = on ? 'in control (heartbeat every 200 ms)' : 'not in control' + (why ? `: ${why}` : '');
}

function wire() {
  $('token').value = state.token;
  $('token').addEventListener('change', () => {
    state.token = $('token').value.trim();
    sessionStorage.setItem('harvest-token', state.token);
  });
  $('take-control').addEventListener('click', async () => {
    state.token = $('token').value.trim();
    sessionStorage.setItem('harvest-token', state.token);
    const answer = await sendCommand({ command: 'heartbeat' });
    setControlling(answer.accepted, answer.accepted ? '' : answer.reason);
  });
  $('leave-control').addEventListener('click', async () => {
    setControlling(false, 'left');
    await sendCommand({ command: 'leave-control' });
  });
  $('btn-estop').addEventListener('click', () => {
    if (state.offsetNs !== null) window.consoleStats.estopClickNs = monoNowNs();
    // Sent with whatever token is typed, or none: the executive takes a stop from anyone.
    state.token = $('token').value.trim() || state.token;
    sendCommand({ command: 'estop' });
  });
  for (const button of document.querySelectorAll('button[data-command]')) {
    button.addEventListener('click', () => {
      const command = { command: button.dataset.command };
      if (button.dataset.arm) command.arm = Number(button.dataset.arm);
      sendCommand(command);
    });
  }
  const jog = (sign) => sendCommand({
    command: 'jog',
    arm: Number($('jog-arm').value),
    joint: $('jog-joint').value,
    delta: sign * Number($('jog-delta').value),
  });
  $('jog-plus').addEventListener('click', () => jog(1));
  $('jog-minus').addEventListener('click', () => jog(-1));
  $('btn-mark').addEventListener('click', async () => {
    let answer;
    try {
      answer = await request('mark', { text: $('mark-text').value }, '/api/mark');
    } catch (error) {
      answer = { accepted: false, reason: 'console unreachable: ' + error };
    }
    const element = $('mark-answer');
    element.textContent = answer.accepted ? answer.reason : `mark REFUSED: ${answer.reason}`;
    element.className = answer.accepted ? 'accepted' : 'refused';
    window.consoleStats.answers.push({ command: 'mark', ...answer });
    if (answer.accepted) $('mark-text').value = '';
  });
  $('platform-move').addEventListener('click', () => sendCommand({
    command: 'platform',
    in_out_m: Number($('platform-in-out').value),
    up_down_m: Number($('platform-up-down').value),
  }));
}

wire();
connectLive();
// The clock estimate is refreshed every 5 s (this also tells the console the page is alive).
setInterval(askClock, 5000);
