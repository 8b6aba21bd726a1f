// The live view page (issue 19): state from server-sent events (/api/events), the camera image
// from /api/image.jpg, the buttons through POST /api/ready|repeat|abort with this page's
// controller token. The token lives in sessionStorage: a reload keeps control, and closing the
// page aborts nothing (its lease runs out and another page may take control).
'use strict';
const $ = (id) => document.getElementById(id);
const KEY = 'msmcal-controller';
let controller = sessionStorage.getItem(KEY) || '';
let state = null;
let events = null;
let imageSeq = -1;
let imageLoading = false;
let repeatsSeen = -1;
let promptSeen = -1;

async function post(path, query) {
  const r = await fetch(path + '?' + new URLSearchParams(query), {
    method: 'POST', headers: {'X-Msmcal-Request': '1'}, cache: 'no-store'});
  let body = {};
  try { body = await r.json(); } catch (e) { /* no JSON */ }
  return {ok: r.ok, status: r.status, body: body};
}

async function claim() {
  const r = await post('/api/claim', {previous: controller});
  if (r.ok) {
    controller = r.body.controller;
    sessionStorage.setItem(KEY, controller);
    $('message').textContent = '';
  } else {
    controller = '';
    sessionStorage.removeItem(KEY);
    $('message').textContent = r.body.error || ('claim refused (HTTP ' + r.status + ')');
  }
  connect();
}

function connect() {
  if (events) events.close();
  events = new EventSource('/api/events' + (controller ? '?controller=' + encodeURIComponent(controller) : ''));
  events.onopen = () => { $('connection').textContent = ''; };
  events.onerror = () => { $('connection').textContent = 'connection to msmcal lost; retrying…'; };
  events.onmessage = (e) => { state = JSON.parse(e.data); render(); };
}

async function command(name) {
  if (!state) return;
  const q = {controller: controller};
  if (name !== 'abort') q.prompt = state.prompt.id;
  for (const b of ['ready', 'repeat', 'abort']) $(b).disabled = true;
  const r = await post('/api/' + name, q);
  $('message').textContent = r.ok ? '' : (r.body.error || ('HTTP ' + r.status));
  if (r.status === 403) { controller = ''; sessionStorage.removeItem(KEY); connect(); }
  render();
}

function duration(s) {
  if (s === null || s === undefined) return '–';
  s = Math.max(0, Math.round(s));
  const m = Math.floor(s / 60), r = s % 60;
  return m + ':' + String(r).padStart(2, '0');
}

function bytes(n) {
  if (n === null || n === undefined) return '–';
  if (n >= 1e9) return (n / 1e9).toFixed(1) + ' GB';
  return (n / 1e6).toFixed(0) + ' MB';
}

function refreshImage() {
  if (!state || imageLoading || state.image.sequence === imageSeq || state.image.sequence === 0) return;
  imageLoading = true;
  const seq = state.image.sequence;
  const img = $('live-image');
  img.onload = img.onerror = () => { imageLoading = false; imageSeq = seq; refreshImage(); };
  img.src = '/api/image.jpg?seq=' + seq;
}

function render() {
  if (!state) return;
  const ended = state.state === 'done' || state.state === 'aborted';
  const st = $('state');
  st.textContent = state.state;
  st.className = 'badge ' + state.state;
  const mine = controller !== '';
  const p = state.prompt;
  $('control').textContent = ended ? '' : mine ? 'this page controls the session'
      : state.controller.active ? 'watching (another page controls the session)' : 'no page controls the session';
  $('claim').hidden = ended || mine || state.controller.active;
  $('ready').disabled = !(mine && p.waiting && !ended);
  $('repeat').disabled = !(mine && p.waiting && !ended);
  $('abort').disabled = !(mine && !ended);
  if (p.id !== promptSeen || p.repeats !== repeatsSeen) {
    const ins = $('instruction');
    ins.textContent = p.id === 0 ? 'Waiting for the first instruction…' : p.instructions;
    if (p.id === promptSeen && p.repeats !== repeatsSeen) {
      ins.classList.remove('flash'); void ins.offsetWidth; ins.classList.add('flash');
    }
    promptSeen = p.id; repeatsSeen = p.repeats;
  }
  $('block').textContent = p.number ? '[' + p.number + '/' + p.total + ']' : '';
  $('counters').textContent = p.step ? 'Step ' + p.step + ', frame ' + p.frame + ' of ' + p.frames_in_step
      : p.number ? 'Hall recording set-up' : '';
  if (ended) $('message').textContent = state.message || ('session ' + state.state);
  else if (state.message) $('message').textContent = state.message;
  const pr = state.progress;
  $('progress-bar').style.width = (100 * pr.fraction).toFixed(1) + '%';
  $('progress').textContent = pr.frames_done + ' of ' + pr.frames_total + ' frames decided, elapsed ' +
      duration(pr.elapsed_s) + ', ETA ' + duration(pr.eta_s);
  const f = state.figures;
  $('totals').textContent = f.accepted + ' accepted, ' + f.rejected + ' rejected, ' + f.retried + ' retried';
  $('last-figures').textContent = f.last;
  const body = document.querySelector('#recent tbody');
  body.innerHTML = '';
  for (const d of f.recent) {
    const tr = document.createElement('tr');
    const cells = [d.file, d.decision, d.dots_expected !== undefined ? d.dots_found + '/' + d.dots_expected : '', d.reason];
    cells.forEach((c, i) => { const td = document.createElement('td'); td.textContent = c; if (i === 1) td.className = d.decision; tr.appendChild(td); });
    body.appendChild(tr);
  }
  const live = state.live || {};
  $('caption').textContent = live.caption || 'no camera image yet';
  $('live-gate').textContent = live.source === 'live'
      ? (live.gate_would_accept ? 'the gate would accept this view' : 'the gate would reject this view: ' + live.reason) : '';
  const rig = state.rig;
  const out = $('outputs');
  out.textContent = rig.outputs_on ? 'GENERATOR OUTPUTS ON' : 'generator outputs off';
  out.className = 'outputs ' + (rig.outputs_on ? 'on' : 'off');
  $('rig-outputs').innerHTML = rig.outputs_on ? '<span class="yes">ON</span>' : '<span class="no">off</span>';
  $('rig-locked').innerHTML = rig.reference_locked ? '<span class="ok">locked</span>' : '<span class="no">–</span>';
  $('rig-hall').textContent = rig.hall_recording
      ? rig.hall_recording + ' recording: ' + Math.round(rig.hall_readings_per_s) + ' readings/s (' + rig.hall_readings + ' so far)'
      : 'not recording' + (rig.hall_readings ? ' (last: ' + rig.hall_readings + ' readings)' : '');
  $('rig-lost').textContent = String(rig.hall_lost);
  $('rig-disk').textContent = bytes(rig.disk_free_bytes);
  const log = $('log');
  log.textContent = state.log.join('\n');
  log.scrollTop = log.scrollHeight;  // newest line in view
  refreshImage();
}

for (const b of ['ready', 'repeat', 'abort']) $(b).addEventListener('click', () => command(b));
$('claim').addEventListener('click', claim);
claim();
