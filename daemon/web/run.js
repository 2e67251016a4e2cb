// Run: progress from the run's server-sent events (frames, ETA, retries,
// dropped frames, suspensions and their reasons, solve stages), its latest
// frame and journal while it captures, the capture's verdict, and its
// results' key figures once solved.
import { getJson, postJson, el, table, seconds, stateSpan, errorBox, runEvents, throttle, captureVerdict } from './api.js';
import { FrameView, journalRecords } from './frame_view.js';

export async function runPage(main, runId) {
  if (!runId) {
    main.append(el('p', { class: 'muted' }, 'No runs yet: submit one from the ', el('a', { href: '#/queue' }, 'Queue'), '.'));
    return null;
  }
  let run = await getJson(`/runs/${runId}`);
  const state = el('span', { id: 'run-state' });
  const verdict = el('span', { id: 'run-verdict' });
  const reason = el('div', { id: 'run-reason' });
  const progress = el('progress', { id: 'run-progress', max: 1, value: 0 });
  const counters = el('div', { id: 'run-counters' });
  const solve = el('div', { id: 'run-solve' });
  const log = el('pre', { id: 'run-events' });
  const journal = el('pre', { id: 'run-journal' });
  const frame = new FrameView();
  const buttons = ['pause', 'resume', 'abort'].map((action) => el('button', {
    'data-action': action, onclick: () => postJson(`/runs/${runId}/${action}`).catch((error) => reason.append(errorBox(error))),
  }, action));
  main.append(
    el('section', {}, el('h2', {}, `Run ${runId} (${run.recipe})`), el('p', {}, 'State: ', state, verdict, ' ', buttons), reason,
      el('p', {}, progress, ' ', counters), solve),
    el('div', { class: 'row' },
      el('section', {}, el('h2', {}, 'Latest frame'), frame.root),
      el('section', {}, el('h2', {}, 'Events'), log)),
    el('section', {}, el('h2', {}, 'Journal'), journal));

  const started = performance.now();
  let firstFrames = null;  // frames when this page began watching, for the ETA
  let suspensions = 0;
  // What each control can still do in each state (the daemon answers 409 otherwise).
  const allowed = { pause: ['running', 'suspended'], resume: ['paused'], abort: ['queued', 'running', 'paused', 'suspended', 'solving'] };
  function render() {
    state.replaceChildren(stateSpan(run.state));
    verdict.replaceChildren(captureVerdict(run));
    for (const button of buttons) button.disabled = !allowed[button.dataset.action].includes(run.state);
    reason.textContent = run.reason ? `Reason: ${run.reason}` : '';
    const total = run.steps_total || 1;
    progress.max = total;
    progress.value = run.frames;
    let eta = '';
    if (['running', 'suspended', 'paused'].includes(run.state) && firstFrames !== null && run.frames > firstFrames) {
      const rate = (run.frames - firstFrames) / ((performance.now() - started) / 1000);
      eta = `, ETA ${seconds((total - run.frames) / rate)}`;
    }
    counters.textContent = `${run.frames}/${run.steps_total} frames${eta}, ${run.retries} retries, ` +
      `${run.dropped_frames} dropped, ${suspensions} suspensions`;
    if (run.solve) {
      solve.replaceChildren(table(run.solve.stages.map((s) => [s.stage, s.ok ? 'ok' : 'failed', s.termination,
        Object.entries(s.figures || {}).map(([k, v]) => `${k} ${typeof v === 'number' ? +v.toPrecision(4) : v}`).join(', ')]),
      ['stage', '', 'termination', 'figures']));
    }
    if (run.results) solve.append(el('p', {}, el('a', { href: `#/results/${runId}`, id: 'results-link' }, 'Results →')));
  }
  async function showJournal() {
    try {
      const records = await journalRecords(runId);
      journal.textContent = records.slice(-12).map((r) => JSON.stringify(r)).join('\n');
      const last = [...records].reverse().find((r) => r.file);
      if (last) await frame.show(runId, last.file, last);
    } catch (error) {
      if (error.status !== 404) journal.textContent = error.message;
    }
  }
  const note = (text) => { log.textContent = `${text}\n${log.textContent}`.slice(0, 20000); };
  // Frames arrive every 50-80 ms on the simulated dome: the journal and frame
  // are fetched at most every 250 ms, the latest each time.
  const refreshJournal = throttle(showJournal, 250);
  render();
  if (run.frames > 0) refreshJournal();  // before its first frame a run may have no journal yet
  const stream = runEvents(runId, (type, data) => {
    if (type === 'frame') {
      if (firstFrames === null) firstFrames = data.frames - 1;
      run.frames = data.frames;
      run.steps_total = data.total;
      refreshJournal();
    } else if (type === 'state') {
      run.state = data.state;
      run.reason = data.reason;
      if (data.state === 'suspended') { suspensions += 1; run.retries += 1; }
      note(`state ${data.state}${data.reason ? `: ${data.reason}` : ''}`);
    } else if (type === 'solve_progress') {
      counters.textContent = `solving ${data.stage}: ${(100 * data.done / data.total).toFixed(0)} %`;
      return;
    } else if (type === 'solve_started' || type === 'solve_finished') {
      note(`${type} ${data.stage}${type === 'solve_finished' ? (data.ok ? ' ok' : ` failed: ${data.message}`) : ''}`);
    } else if (type === 'stop') {
      // The record, not the event, carries the capture's verdict (its manifest's stop).
      note(`stop: ${data.state}${data.reason ? ` (${data.reason})` : ''}`);
      getJson(`/runs/${runId}`).then((record) => { run = record; render(); }).catch((error) => reason.append(errorBox(error)));
      if (data.frames > 0) refreshJournal();
      return;
    }
    render();
  });
  stream.done.then(async () => {
    run = await getJson(`/runs/${runId}`);
    render();
  }).catch((error) => reason.append(errorBox(error)));
  return () => { stream.cancel(); refreshJournal.cancel(); };
}
