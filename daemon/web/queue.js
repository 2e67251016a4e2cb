// Queue: choose a recipe (from the daemon's recipe folders, or a file from
// this computer), see its dry-run plan, submit it; the queue and its history.
import { getJson, postJson, el, table, bytes, seconds, stateSpan, errorBox } from './api.js';

const ACTIVE = new Set(['queued', 'running', 'paused', 'suspended', 'solving']);

export async function queuePage(main) {
  const { recipes } = await getJson('/recipes');
  const select = el('select', { id: 'recipe-select' },
    el('option', { value: '' }, '— choose a recipe —'),
    recipes.map((r, i) => el('option', { value: i }, `${r.name} (${r.file}, ${r.source})`)));
  const upload = el('input', { type: 'file', id: 'recipe-file', accept: '.yaml,.yml' });
  const text = el('textarea', { id: 'recipe-text', spellcheck: 'false' });
  const description = el('p', { class: 'muted' });
  const plan = el('div', { id: 'plan' });
  const submit = el('button', { id: 'submit', disabled: true }, 'Submit');
  let chosen = { name: 'recipe.yaml', path: '' };

  select.addEventListener('change', () => {
    const recipe = recipes[select.value];
    if (!recipe) return;
    chosen = { name: recipe.file, path: recipe.path };
    text.value = recipe.text;
    description.textContent = recipe.description || '';
    dryRun();
  });
  upload.addEventListener('change', async () => {
    const file = upload.files[0];
    if (!file) return;
    chosen = { name: file.name, path: '' };  // a relative recipe.rig is matched by its name
    text.value = await file.text();
    description.textContent = `uploaded ${file.name}`;
    dryRun();
  });
  let timer = null;
  text.addEventListener('input', () => { clearTimeout(timer); timer = setTimeout(dryRun, 500); });

  const body = () => ({ name: chosen.name, recipe: text.value, ...(chosen.path ? { path: chosen.path } : {}) });
  async function dryRun() {
    submit.disabled = true;
    plan.replaceChildren(el('p', { class: 'muted' }, 'planning…'));
    try {
      const p = await postJson('/dry-run', body());
      plan.replaceChildren(planView(p));
      submit.disabled = false;
    } catch (error) {
      plan.replaceChildren(errorBox(error), error.body?.plan ? planView(error.body.plan) : '');
    }
  }
  submit.addEventListener('click', async () => {
    submit.disabled = true;
    try {
      const run = await postJson('/runs', body());
      location.hash = `#/run/${run.id}`;
    } catch (error) {
      plan.prepend(errorBox(error));
      submit.disabled = false;
    }
  });

  const history = el('section', { id: 'history' });
  main.append(
    el('section', {}, el('h2', {}, 'Recipe'), el('p', {}, select, ' or a file: ', upload), description, text),
    el('section', {}, el('h2', {}, 'Plan (dry run)'), plan, submit),
    history);

  async function refresh() {
    const { runs } = await getJson('/runs');
    const control = (run, action) => el('button', {
      'data-action': action, onclick: async (event) => {
        event.target.disabled = true;
        try { await postJson(`/runs/${run.id}/${action}`); } catch (error) { history.append(errorBox(error)); }
        refresh();
      },
    }, action);
    const rows = runs.slice().reverse().map((run) => [
      el('a', { href: `#/run/${run.id}` }, run.id), run.recipe, stateSpan(run.state), `${run.frames}/${run.steps_total}`,
      run.reason || '',
      ACTIVE.has(run.state) ? el('span', {}, run.state !== 'queued' ? [control(run, 'pause'), control(run, 'resume')] : [], control(run, 'abort'))
        : run.results ? el('a', { href: `#/results/${run.id}` }, 'results') : '']);
    history.replaceChildren(el('h2', {}, 'Queue and history'),
      rows.length ? table(rows, ['run', 'recipe', 'state', 'frames', 'outcome', '']) : el('p', { class: 'muted' }, 'no runs yet'));
  }
  await refresh();
  const poll = setInterval(refresh, 2000);
  return () => { clearInterval(poll); clearTimeout(timer); };
}

function planView(p) {
  const poses = p.steps.filter((s) => s.pose).length;
  return el('div', {},
    table([
      ['frames', el('span', { id: 'plan-frames' }, `${p.frames}`)],
      ['duration', seconds(p.duration_s)],
      ['data', bytes(p.bytes)],
      ['max LED duty', `${(100 * p.max_led_duty).toFixed(2)} % (LED ${p.max_duty_led})`],
      ['free space', p.free_bytes !== undefined ? bytes(p.free_bytes) : ''],
      ['poses', `${poses}`],
    ]),
    p.errors?.length ? el('div', { class: 'error' }, p.errors.join('\n')) : null,
    el('details', {}, el('summary', {}, `steps (${p.steps.length}${p.steps_listed < p.frames ? ' listed' : ''})`),
      table(p.steps.slice(0, 200).map((s) => [s.index ?? '', s.label ?? s.kind ?? '', s.exposure_us ?? '',
        s.pose ? Object.entries(s.pose).map(([k, v]) => `${k} ${(+v).toFixed(1)}`).join(', ') : '']),
      ['#', 'step', 'exposure (us)', 'pose'])));
}
