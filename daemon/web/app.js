// The interface's router: #/rig, #/queue, #/run/<id>, #/results/<id>.
import { takeTokenFromAddress, getJson, bytes } from './api.js';
import { rigPage } from './rig.js';
import { queuePage } from './queue.js';
import { runPage } from './run.js';
import { resultsPage } from './results.js';

const pages = { rig: rigPage, queue: queuePage, run: runPage, results: resultsPage };
let leave = null;  // the open page's clean-up (timers, event streams)

async function latestRunId() {
  const { runs } = await getJson('/runs');
  return runs.length ? runs[runs.length - 1].id : null;
}

async function route() {
  if (leave) leave();
  leave = null;
  const [, name = 'rig', id] = location.hash.split('/');
  const page = pages[name] ? name : 'rig';
  for (const link of document.querySelectorAll('header nav a')) link.classList.toggle('active', link.id === `nav-${page}`);
  const main = document.getElementById('page');
  main.replaceChildren();
  main.dataset.page = page;
  let runId = id ? decodeURIComponent(id) : null;
  if ((page === 'run' || page === 'results') && !runId) {
    runId = await latestRunId();
    if (runId) return location.replace(`#/${page}/${runId}`);
  }
  try {
    leave = await pages[page](main, runId);
  } catch (error) {
    main.append(Object.assign(document.createElement('div'), { className: 'error', textContent: error.message }));
    console.warn(error);
  }
}

async function statusLine() {
  try {
    const health = await getJson('/health');
    document.getElementById('status-line').textContent =
      `${health.status} · ${health.current_run || 'idle'} · ${health.queued} queued · ${bytes(health.free_bytes)} free`;
  } catch (error) {
    document.getElementById('status-line').textContent = `daemon: ${error.message}`;
  }
}

takeTokenFromAddress();
window.addEventListener('hashchange', route);
if (!location.hash.startsWith('#/')) location.replace('#/rig');
else route();
statusLine();
setInterval(statusLine, 3000);
