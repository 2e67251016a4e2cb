// Talks to photorigd's API (docs/api.md) from the page it served. A token,
// when the daemon has one, comes once in the address (#token=...) and is kept
// in sessionStorage for this tab; every request sends it as a bearer token.

const TOKEN_KEY = 'photorig.token';

export function takeTokenFromAddress() {
  const match = location.hash.match(/token=([^&]+)/);
  if (!match) return;
  sessionStorage.setItem(TOKEN_KEY, decodeURIComponent(match[1]));
  history.replaceState(null, '', location.pathname + '#/rig');
}

function headers(extra = {}) {
  const token = sessionStorage.getItem(TOKEN_KEY);
  return token ? { ...extra, Authorization: `Bearer ${token}` } : extra;
}

// One question at a time: every request that met a 401 waits for the same answer.
let tokenAnswer = null;
function askForToken() {
  tokenAnswer ??= new Promise((resolve) => {
    const dialog = document.getElementById('token-dialog');
    dialog.addEventListener('close', () => {
      sessionStorage.setItem(TOKEN_KEY, document.getElementById('token-input').value.trim());
      tokenAnswer = null;
      resolve();
    }, { once: true });
    dialog.showModal();
  });
  return tokenAnswer;
}

// fetch under /api/v1; throws an Error carrying the daemon's message and status.
export async function api(path, options = {}) {
  const response = await fetch(`/api/v1${path}`, { ...options, headers: headers(options.headers) });
  if (response.status === 401) {
    await askForToken();
    return api(path, options);
  }
  if (!response.ok) {
    let body = {};
    try { body = await response.json(); } catch { /* not JSON */ }
    const error = new Error(body.error || `${response.status} ${response.statusText}`);
    error.status = response.status;
    error.body = body;
    throw error;
  }
  return response;
}

export const getJson = async (path) => (await api(path)).json();

export async function postJson(path, body) {
  const response = await api(path, {
    method: 'POST', headers: { 'Content-Type': 'application/json' }, body: JSON.stringify(body ?? {}),
  });
  return response.json();
}

// An object URL for an image the API serves (an <img> cannot send the token).
export async function imageUrl(path) {
  const response = await api(path);
  const blob = await response.blob();
  return { url: URL.createObjectURL(blob), headers: response.headers };
}

// GET .../values/...: {width, height, channels, data: Float32Array}.
export async function imageValues(runId, file) {
  const response = await api(`/runs/${runId}/values/${file}`);
  const h = response.headers;
  return {
    width: +h.get('X-Image-Width'), height: +h.get('X-Image-Height'), channels: +h.get('X-Image-Channels'),
    data: new Float32Array(await response.arrayBuffer()),
  };
}

// Server-sent events of a run, read through fetch (EventSource cannot send a
// token). onEvent(type, data) per event; resolves when the stream ends.
// Returns {done, cancel}.
export function runEvents(runId, onEvent) {
  const controller = new AbortController();
  const done = (async () => {
    const response = await api(`/runs/${runId}/events`, { signal: controller.signal });
    const reader = response.body.pipeThrough(new TextDecoderStream()).getReader();
    let buffer = '';
    for (;;) {
      const { value, done: ended } = await reader.read();
      if (ended) return;
      buffer += value;
      let end;
      while ((end = buffer.indexOf('\n\n')) >= 0) {
        const block = buffer.slice(0, end);
        buffer = buffer.slice(end + 2);
        let type = 'message', data = '';
        for (const line of block.split('\n')) {
          if (line.startsWith('event: ')) type = line.slice(7);
          else if (line.startsWith('data: ')) data += line.slice(6);
        }
        if (data) onEvent(type, JSON.parse(data));
      }
    }
  })().catch((error) => { if (error.name !== 'AbortError') throw error; });
  return { done, cancel: () => controller.abort() };
}

// Small DOM helpers shared by the pages.
export function el(tag, attributes = {}, ...children) {
  const node = document.createElement(tag);
  for (const [key, value] of Object.entries(attributes)) {
    if (key.startsWith('on')) node.addEventListener(key.slice(2), value);
    else if (value !== undefined && value !== null && value !== false) node.setAttribute(key, value);
  }
  for (const child of children.flat()) if (child !== null && child !== undefined) node.append(child);
  return node;
}

export function table(rows, head) {
  return el('table', {}, head ? el('tr', {}, head.map((h) => el('th', {}, h))) : null,
    rows.map((row) => el('tr', {}, row.map((cell) => el('td', {}, cell)))));
}

// Calls the async `task` at once, then at most once every `ms` while calls
// keep coming, and once more after the last: a stream of events faster than
// `task` neither starves it (as restarting a timer on every event would) nor
// runs it twice at a time. Returns the trigger; trigger.cancel() stops it.
export function throttle(task, ms) {
  let timer = null, running = false, again = false, cancelled = false, last = -Infinity;
  async function run() {
    timer = null;
    running = true;
    again = false;
    last = performance.now();
    try { await task(); } finally { running = false; }
    if (again && !cancelled) trigger();
  }
  function trigger() {
    if (running) again = true;
    else if (!timer && !cancelled) timer = setTimeout(run, Math.max(0, last + ms - performance.now()));
  }
  trigger.cancel = () => { cancelled = true; clearTimeout(timer); };
  return trigger;
}

export const bytes = (n) => n >= 2 ** 30 ? `${(n / 2 ** 30).toFixed(1)} GiB` : n >= 2 ** 20 ? `${(n / 2 ** 20).toFixed(1)} MiB` : `${(n / 1024).toFixed(0)} KiB`;
export const seconds = (s) => s >= 3600 ? `${(s / 3600).toFixed(1)} h` : s >= 60 ? `${(s / 60).toFixed(1)} min` : `${s.toFixed(1)} s`;
export const stateSpan = (state) => el('span', { class: `state-${state}`, 'data-state': state }, state);
// The capture's verdict in a run record (GET /runs/{id}): its manifest's stop
// status and reason once final (docs/run-format.md); a run solving or done
// had a complete capture, as only a complete capture is solved.
export function captureVerdict(run) {
  const stop = run.stop ?? (['solving', 'done'].includes(run.state) ? { status: 'complete' } : null);
  const [status, detail] = stop ? [stop.status, stop.reason]
    : run.manifest_error ? ['unreadable', run.manifest_error]
      : run.state === 'queued' ? ['not started', '']
        : ['running', 'paused', 'suspended', 'aborting'].includes(run.state) ? ['in progress', '']
          : [run.state, run.reason];  // final without a manifest: it ended before its first frame
  const kind = status === 'complete' ? 'complete' : ['not started', 'in progress'].includes(status) ? 'pending' : 'bad';
  return el('span', { class: `verdict verdict-${kind}`, 'data-verdict': status }, `capture ${status}${detail ? `: ${detail}` : ''}`);
}

export function errorBox(error) { return el('div', { class: 'error' }, String(error.message || error)); }

// The first line of a run's journal: its header (camera, lights, ...).
const headerCache = new Map();
export async function runHeader(runId) {
  if (!headerCache.has(runId)) {
    const text = await (await api(`/runs/${runId}/files/journal.jsonl`)).text();
    headerCache.set(runId, JSON.parse(text.slice(0, text.indexOf('\n'))).run);
  }
  return headerCache.get(runId);
}
