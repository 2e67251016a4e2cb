// Results of a run, each beside its capture's verdict: the photometric-stereo
// maps with legends and read-outs, metrics against ground truth, charts from
// report.json, the mesh in 3D, relighting; an svbrdf fit's materials and
// figures; BRDF samples and fits; slices of NRRD volumes.
import { api, getJson, imageUrl, imageValues, el, table, bytes, errorBox, captureVerdict } from './api.js';
import { relightView } from './relight.js';

// The maps a PS result can have: the file shown, the file read out, and how.
const MAPS = [
  { key: 'normals', show: 'normals.png', values: 'normals.tiff', legend: 'RGB = (n + 1) / 2; n = (x right, y up, z towards the camera)' },
  { key: 'albedo', values: 'albedo.tiff', gamma: 1 },
  { key: 'depth', values: 'depth.tiff', gamma: 1 },
  { key: 'confidence', values: 'confidence.tiff', gamma: 1 },
  { key: 'error', values: 'angular_error.tiff', gamma: 1, low: 0, high: 10, unit: '°' },
  // The lobe's two parameters differ by orders of magnitude: each on its own scale.
  { key: 'rho_s', values: 'specular.tiff', channel: 0, gamma: 1 },
  { key: 'exponent', values: 'specular.tiff', channel: 1, gamma: 1, note: 'roughness where model.png says GGX' },
  { key: 'flags', show: 'flags.png', values: 'flags.png', legendOf: 'flags.png' },
  { key: 'model', show: 'model.png', values: 'model.png', legendOf: 'model.png' },
];

export async function resultsPage(main, runId) {
  if (!runId) {
    main.append(el('p', { class: 'muted' }, 'No runs yet.'));
    return null;
  }
  const [run, listing] = await Promise.all([getJson(`/runs/${runId}`),
    getJson(`/runs/${runId}/files?under=results`).catch(() => ({ files: [] }))]);
  const files = new Set(listing.files.map((f) => f.path));
  // Every result's heading carries the verdict on the frames it was solved from.
  const heading = (text) => el('h2', {}, text, captureVerdict(run));
  main.append(el('section', {}, heading(`Results of ${runId}`),
    listing.files.length ? el('details', {}, el('summary', {}, `${listing.files.length} files, ${bytes(listing.bytes)}`),
      table(listing.files.map((f) => [f.path, bytes(f.size)])))
      : el('p', { class: 'muted' }, 'This run has no results (yet).')));
  const cleanups = [];
  const folders = [...new Set([...files].filter((f) => f.endsWith('/report.json')).map((f) => f.slice(0, -'report.json'.length)))];
  const reports = new Map();
  for (const folder of folders) reports.set(folder, await (await api(`/runs/${runId}/files/${folder}report.json`)).json());
  // A per-material fit (photorig solve svbrdf) keeps photometric stereo's
  // normals in its ps/ folder, and the refined ones, when it refined them,
  // as its own normals.tiff.
  const perMaterial = (folder) => reports.get(folder)?.materials && files.has(`${folder}material.png`) && files.has(`${folder}albedo.tiff`);
  for (const folder of folders) {
    const report = reports.get(folder);
    const parent = folder.replace(/ps\/$/, '');
    if (perMaterial(folder)) materialsTable(main, heading, folder, report);
    else if (files.has(`${folder}normals.tiff`))
      cleanups.push(await psResults(main, heading, runId, folder, report, files,
        parent !== folder && perMaterial(parent) ? { folder: parent, report: reports.get(parent) } : null));
    else if (report.candidates) await brdfResults(main, heading, runId, folder, report, files);
  }
  for (const volume of [...files].filter((f) => f.endsWith('.nrrd'))) await volumeSlices(main, heading, runId, volume);
  return () => cleanups.forEach((c) => c && c());
}

// The materials of a per-material fit with their lobes (docs/reflectance.md),
// and its own figures.
function materialsTable(main, heading, folder, report) {
  const f = (x) => (+x.toPrecision(3)).toString();
  main.append(el('section', { id: 'materials' }, heading(`Materials (${folder})`),
    table(report.materials.map((m, i) => [i, m.model, m.pixels, m.specular.map(f).join(', '),
      m.model === 'lambertian' ? '' : `${m.model === 'ggx' ? 'roughness' : 'exponent'} ${f(m.shape)}`, m.warnings.join(', ')]),
    ['material', 'lobe', 'pixels', 'k_s or F0 (r, g, b)', 'shape', 'warnings'])));
  const rows = [['termination', `${report.termination}${report.message ? `: ${report.message}` : ''}`],
    ['pixels', figure(report.pixels)], ['materials', `${report.materials.length}, merged ${report.materials_merged}, unobserved ${figure(report.materials_unobserved)}`],
    ['reduced chi-square', figure(report.noise?.reduced_chi_square)], ['warnings', figure(report.warnings)]];
  if (report.normal_refinement) rows.push(['normal refinement', figure(report.normal_refinement)]);
  if (report.held_out) rows.push(['held-out lights: mean', figure(report.held_out.mean)]);
  const truth = { normals_vs_truth_deg: 'normals (deg)', albedo_median_relative_error_vs_truth: 'albedo median relative error',
    albedo_ciede2000_vs_truth: 'albedo CIEDE2000', material_agreement_vs_truth: 'materials agreeing' };
  for (const [key, label] of Object.entries(truth))
    if (report[key] !== undefined) rows.push([`vs ground truth: ${label}`, figure(report[key])]);
  metricsSection(main, folder, rows);
}

const metricsSection = (main, folder, rows) =>
  main.append(el('section', { class: 'metrics', 'data-folder': folder }, el('h2', {}, `Metrics (${folder})`), table(rows)));

// A report's value as text: numbers to 4 digits, lists joined, objects as "key value" lists.
function figure(v) {
  if (typeof v === 'number') return (+v.toPrecision(4)).toString();
  if (Array.isArray(v)) return v.length ? v.map(figure).join(', ') : 'none';
  if (v && typeof v === 'object')
    return Object.entries(v).map(([k, x]) => `${k} ${x && typeof x === 'object' && !Array.isArray(x) ? `(${figure(x)})` : figure(x)}`).join(', ');
  return v === null || v === undefined ? '—' : String(v);
}

// `svbrdf`: {folder, report} of a per-material fit made on these normals, or null.
async function psResults(main, heading, runId, folder, report, files, svbrdf) {
  const maps = MAPS.filter((m) => files.has(folder + m.values));
  const image = el('img', { id: 'map-image', alt: 'map' });
  const legend = el('div', { id: 'map-legend', class: 'muted' });
  const readout = el('div', { class: 'readout', id: 'map-readout' }, 'move the cursor over the map');
  const tabs = el('p', {}, maps.map((m) => el('button', { 'data-map': m.key, onclick: () => show(m) }, m.key)));
  let values = null, current = null;
  const cache = new Map();
  // A file's float values, fetched once (the lobe's two maps both read specular.tiff).
  const valuesOf = (file) => {
    if (!cache.has(file)) cache.set(file, imageValues(runId, folder + file));
    return cache.get(file);
  };
  // The daemon's PNG or tone-mapped preview, and the range it maps to black .. white.
  async function served(map) {
    const query = map.show ? null : new URLSearchParams({ gamma: map.gamma ?? 2.2, ...(map.low !== undefined ? { low: map.low, high: map.high } : {}) });
    const { url, headers } = await imageUrl(map.show ? `/runs/${runId}/files/${folder}${map.show}` : `/runs/${runId}/preview/${folder}${map.values}?${query}`);
    return { url, range: { low: +headers.get('X-Preview-Low'), high: +headers.get('X-Preview-High') } };
  }

  async function show(map) {
    current = map;
    values = null;
    const { url, range } = map.channel !== undefined ? await channelImage(await valuesOf(map.values), map.channel) : await served(map);
    if (image.src) URL.revokeObjectURL(image.src);
    image.src = url;
    image.dataset.map = map.key;
    await image.decode();
    legend.replaceChildren(legendFor(map, report, range));
    const read = await valuesOf(map.values);
    if (current === map) values = read;
  }
  image.addEventListener('mousemove', (event) => {
    if (!values) return;
    const box = image.getBoundingClientRect();
    const x = Math.floor((event.clientX - box.left) / box.width * image.naturalWidth);
    const y = Math.floor((event.clientY - box.top) / box.height * image.naturalHeight);
    if (x < 0 || y < 0 || x >= values.width || y >= values.height) { readout.textContent = ''; return; }
    const at = (y * values.width + x) * values.channels;
    const v = Array.from(values.data.slice(at, at + values.channels));
    readout.textContent = `(${x}, ${y}): ${describe(current, v, report)}`;
  });

  main.append(el('section', { id: 'maps' }, heading(`Maps (${folder})`), tabs,
    el('div', { class: 'map' }, image), readout, legend));
  if (maps.length) await show(maps[0]);

  metrics(main, folder, report);
  charts(main, report).catch((error) => main.append(errorBox(error)));
  const cleanups = [];
  if (files.has(`${folder}mesh.ply`)) cleanups.push(await meshView(main, runId, `${folder}mesh.ply`));
  // Relit with the normals the per-material fit used (refined, when it refined them), as `photorig relight` does.
  const normalsFile = svbrdf && files.has(`${svbrdf.folder}normals.tiff`) ? `${svbrdf.folder}normals.tiff` : `${folder}normals.tiff`;
  const [normals, albedo] = await Promise.all([imageValues(runId, normalsFile), imageValues(runId, `${folder}albedo.tiff`)]);
  const lobe = files.has(`${folder}specular.tiff`) ? await valuesOf('specular.tiff') : null;
  const hasLobe = lobe && lobe.data.some((v, i) => i % 3 === 0 && v > 0);
  const section = el('section', { id: 'relight' }, el('h2', {}, 'Relighting'));
  main.append(section);
  try {
    const envmaps = [...files].filter((f) => f.endsWith('.hdr')).map((f) => ({
      name: f, bytes: async () => new Uint8Array(await (await api(`/runs/${runId}/files/${f}`)).arrayBuffer()),
    }));
    let perMaterial = null;
    if (svbrdf) {
      const [colour, material] = await Promise.all([imageValues(runId, `${svbrdf.folder}albedo.tiff`),
        imageValues(runId, `${svbrdf.folder}material.png`)]);
      perMaterial = { albedo: colour, material, materials: svbrdf.report.materials };
    }
    section.append(relightView(normals, albedo, hasLobe ? lobe : null, envmaps, perMaterial).root);
  } catch (error) {
    section.append(errorBox(error));
  }
  return () => cleanups.forEach((c) => c());
}

function describe(map, v, report) {
  const f = (x) => Number.isFinite(x) ? (+x.toPrecision(4)).toString() : 'none';
  if (map.legendOf) {
    const legend = report.previews?.[map.legendOf]?.legend || [];
    const hit = legend.find((e) => e.rgb[0] === v[0] && e.rgb[1] === v[1] && e.rgb[2] === v[2]);
    return hit ? `${hit.name} (code ${hit.code})` : `RGB ${v.join(', ')}`;
  }
  if (map.key === 'normals') return `n = (${v.map(f).join(', ')})`;
  if (map.channel !== undefined) return `${map.key} ${f(v[map.channel])}`;
  return `${f(v[0])}${map.unit || ''}`;
}

function legendFor(map, report, { low, high }) {
  if (map.legend) return el('span', {}, map.legend);
  if (map.legendOf) {
    const legend = report.previews?.[map.legendOf]?.legend || [];
    return el('span', {}, legend.map((e) => el('span', { style: 'margin-right:1em' },
      el('span', { style: `display:inline-block;width:12px;height:12px;background:rgb(${e.rgb.join(',')});border:1px solid #999` }), ` ${e.name}`)));
  }
  const bar = el('canvas', { class: 'legend', width: 256, height: 12 });
  const g = bar.getContext('2d');
  const gamma = map.gamma ?? 2.2;
  for (let i = 0; i < 256; ++i) {
    const level = Math.round(255 * (i / 255) ** (1 / gamma));
    g.fillStyle = `rgb(${level},${level},${level})`;
    g.fillRect(i, 0, 1, 12);
  }
  return el('div', {}, bar, `${+low.toPrecision(4)} … ${+high.toPrecision(4)}${map.unit || ''}; ` +
    `${map.channel !== undefined ? `${map.key}${map.note ? ` (${map.note})` : ''}; pixels without a lobe and ` : ''}unsolved pixels black`);
}

// One channel of a lobe map as a linear grey image of its own range: its
// minimum .. 99.5th percentile over the pixels with a lobe (rho_s > 0), as
// the daemon's preview chooses a range; the others black.
async function channelImage(image, channel) {
  const { width, height, channels, data } = image;
  const lobe = (i) => data[i * channels] > 0 && Number.isFinite(data[i * channels + channel]);
  const shown = [];
  for (let i = 0; i < width * height; ++i) if (lobe(i)) shown.push(data[i * channels + channel]);
  shown.sort((a, b) => a - b);
  const low = shown.length ? shown[0] : 0, high = shown.length ? shown[Math.floor(0.995 * (shown.length - 1))] : 1;
  const canvas = el('canvas', { width, height });
  const g = canvas.getContext('2d'), pixels = g.createImageData(width, height);
  for (let i = 0; i < width * height; ++i) {
    const level = lobe(i) ? 255 * Math.min(1, Math.max(0, (data[i * channels + channel] - low) / (high - low || 1))) : 0;
    pixels.data.set([level, level, level, 255], 4 * i);
  }
  g.putImageData(pixels, 0, 0);
  const blob = await new Promise((resolve) => canvas.toBlob(resolve, 'image/png'));
  return { url: URL.createObjectURL(blob), range: { low, high } };
}

function metrics(main, folder, report) {
  const rows = [['method', report.method], ['termination', report.termination], ['lights', report.lights],
    ['pixels solved', `${report.pixels?.solved} of ${report.pixels?.total}`], ['mean confidence', report.mean_confidence?.toFixed(3)]];
  const truth = report.ground_truth;
  if (truth) for (const [k, v] of Object.entries(truth)) rows.push([`vs ground truth: ${k}`, figure(v)]);
  if (report.depth) rows.push(['depth', `${report.depth.integrator}, residual rms ${report.depth.residual_rms?.toPrecision(3)}` +
    (report.depth.rms_error_vs_truth !== undefined ? `, rms vs truth ${report.depth.rms_error_vs_truth.toPrecision(3)}` : '')]);
  metricsSection(main, folder, rows);
}

async function charts(main, report) {
  const { Chart, registerables } = await import('/vendor/chart.js/chart.esm.js');
  Chart.register(...registerables);
  const section = el('section', { id: 'charts' }, el('h2', {}, 'From report.json'));
  const row = el('div', { class: 'row' });
  section.append(row);
  main.append(section);
  const bar = (title, data) => {
    const canvas = el('canvas', { width: 320, height: 220 });
    row.append(el('div', { style: 'width:320px' }, canvas));
    new Chart(canvas, {
      type: 'bar', data: { labels: Object.keys(data), datasets: [{ label: title, data: Object.values(data), backgroundColor: '#4a78b8' }] },
      options: { responsive: false, animation: false, plugins: { title: { display: true, text: title }, legend: { display: false } } },
    });
  };
  if (report.pixels) bar('pixels by outcome', Object.fromEntries(Object.entries(report.pixels).filter(([k]) => k !== 'total')));
  if (report.models) bar('pixels by model kept', report.models);
  if (report.timings_ms) bar('time (ms)', report.timings_ms);
}

async function meshView(main, runId, file) {
  const THREE = await import('/vendor/three/build/three.module.js');
  const { OrbitControls } = await import('/vendor/three/examples/jsm/controls/OrbitControls.js');
  const { PLYLoader } = await import('/vendor/three/examples/jsm/loaders/PLYLoader.js');
  const buffer = await (await api(`/runs/${runId}/files/${file}`)).arrayBuffer();
  const geometry = new PLYLoader().parse(buffer);
  geometry.computeVertexNormals();
  geometry.computeBoundingSphere();
  const { center, radius } = geometry.boundingSphere;
  const renderer = new THREE.WebGLRenderer({ antialias: true, preserveDrawingBuffer: true });
  renderer.setSize(480, 360);
  renderer.domElement.id = 'mesh-canvas';
  const scene = new THREE.Scene();
  scene.background = new THREE.Color(0x20242c);
  const camera = new THREE.PerspectiveCamera(35, 480 / 360, radius / 100, radius * 20);
  camera.position.set(center.x, center.y - radius * 1.2, center.z + radius * 3);
  const controls = new OrbitControls(camera, renderer.domElement);
  controls.target.copy(center);
  controls.update();
  scene.add(new THREE.Mesh(geometry, new THREE.MeshStandardMaterial({ color: 0xd8d0c0, roughness: 0.6, side: THREE.DoubleSide })));
  scene.add(new THREE.HemisphereLight(0xffffff, 0x444455, 0.6));
  const sun = new THREE.DirectionalLight(0xffffff, 0.8);
  sun.position.set(1, 1, 2);
  scene.add(sun);
  // Drawn when the view changes, not every animation frame: software WebGL is slow.
  const render = () => renderer.render(scene, camera);
  controls.addEventListener('change', render);
  render();
  main.append(el('section', { id: 'mesh' }, el('h2', {}, `Mesh (${file}: ${geometry.index ? geometry.index.count / 3 : 0} triangles; drag to turn, wheel to zoom)`), renderer.domElement));
  return () => { controls.dispose(); renderer.dispose(); };
}

// BRDF: every candidate's fit, and a polar plot of f_r (red channel) against
// the half vector's angle theta_h from the normal (left of the axis: the half
// vector's azimuth on the -x side): the measured samples, and each fitted
// model in the plane of incidence at the samples' median difference angle theta_d.
async function brdfResults(main, heading, runId, folder, report, files) {
  const section = el('section', { id: 'brdf' }, heading(`BRDF (${folder}): chosen ${report.chosen || 'none'}`),
    table(report.candidates.map((c) => [c.model, c.termination, figure(c.held_out_rms), figure(c.bic), brdfParameters(c)]),
      ['model', 'termination', 'held-out rms', 'BIC', 'parameters']));
  main.append(section);
  if (!files.has(`${folder}samples.csv`)) return;
  const lines = (await (await api(`/runs/${runId}/files/${folder}samples.csv`)).text()).trim().split('\n').slice(1);
  const samples = lines.map((l) => l.split(',').map(Number)).map(([ix, iy, iz, ox, oy, oz, fr]) => {
    const h = [ix + ox, iy + oy, iz + oz], n = Math.hypot(...h);
    const thetaH = Math.acos(h[2] / n), thetaD = Math.acos(Math.min(1, (ix * h[0] + iy * h[1] + iz * h[2]) / n));
    return { thetaH: h[0] < 0 ? -thetaH : thetaH, thetaD, fr };
  });
  const thetaD = samples.map((s) => s.thetaD).sort((a, b) => a - b)[Math.floor(samples.length / 2)] ?? 0;
  const curves = report.candidates.map((c) => {
    const points = [];
    for (let deg = -89; deg <= 89; deg += 1) {
      const th = Math.abs(deg) * Math.PI / 180;
      const cosI = Math.cos(th + thetaD), cosO = Math.cos(th - thetaD);
      if (cosI <= 0 || cosO <= 0) continue;
      points.push({ thetaH: deg * Math.PI / 180, fr: brdfRed(c, { cosI, cosO, cosH: Math.cos(th), cosD: Math.cos(thetaD) }) });
    }
    return { model: c.model, label: `${c.model}${c.model === report.chosen ? ' (chosen)' : ''} at θd ${(thetaD * 180 / Math.PI).toFixed(0)}°`, points };
  });
  const peak = Math.max(...samples.map((s) => s.fr), ...curves.flatMap((c) => c.points.map((p) => p.fr)));
  const polar = (p) => ({ x: p.fr / peak * Math.sin(p.thetaH), y: p.fr / peak * Math.cos(p.thetaH) });
  const { Chart, registerables } = await import('/vendor/chart.js/chart.esm.js');
  Chart.register(...registerables);
  const canvas = el('canvas', { width: 560, height: 320, id: 'brdf-polar' });
  section.append(canvas);
  // Fill as well as line: Chart.js draws a legend's swatch with the fill.
  const dataset = (label, data, colour, line) => ({ label, data, borderColor: colour, backgroundColor: colour,
    ...(line ? { showLine: true, pointRadius: 0, borderWidth: 2 } : { pointRadius: 2 }) });
  new Chart(canvas, {
    type: 'scatter',
    data: {
      datasets: [dataset('measured (red channel)', samples.map(polar), MEASURED_COLOUR, false),
        ...curves.map((c) => dataset(c.label, c.points.map(polar), MODEL_COLOURS[c.model] ?? '#000', true))],
    },
    options: {
      responsive: false, animation: false,
      plugins: { title: { display: true, text: 'f_r / max against θh (polar: straight up is the normal)' } },
      scales: { x: { min: -1, max: 1 }, y: { min: 0, max: 1 } },
    },
  });
}

// One colour per model of solvers/brdf/models.h, none the measured samples' blue.
const MEASURED_COLOUR = '#4a78b8';
const MODEL_COLOURS = { lambertian: '#777777', blinn_phong: '#d0502a', ward: '#2a8a4a', ggx: '#8a3ab8',
  cook_torrance: '#c89b00', two_blinn_phong: '#16a3b3' };

// A candidate's parameters as the models name them, to 3 digits.
function brdfParameters(c) {
  const f = (x) => (typeof x === 'number' ? (+x.toPrecision(3)).toString() : '—');
  const channels = (v) => (v ?? []).map(f).join(', ');
  const shape = { ggx: 'roughness', ward: 'alpha', cook_torrance: 'm' }[c.model] ?? 'exponent';
  const parts = [`rho_d ${channels(c.diffuse)}`];
  if (c.model !== 'lambertian') parts.push(`${c.model === 'ggx' ? 'F0' : c.model === 'ward' ? 'rho_s' : 'k_s'} ${channels(c.specular)}`, `${shape} ${f(c.shape)}`);
  if (c.model === 'ggx') parts.push(`scale ${f(c.specular_scale ?? 1)}`);
  if (c.model === 'cook_torrance') parts.push(`F0 ${f(c.fresnel_f0)}`);
  if (c.model === 'two_blinn_phong') parts.push(`k_s2 ${channels(c.specular2)}`, `exponent2 ${f(c.shape2)}`);
  return parts.join('; ');
}

// f_r of the red channel for a fitted model, from the cosines: the lobes of
// solvers/brdf/src/lobes.h written out once more.
function brdfRed(c, g) {
  const diffuse = c.diffuse[0] / Math.PI;
  const ks = c.specular?.[0] ?? 0, e = c.shape;
  const tan2H = (1 - g.cosH * g.cosH) / (g.cosH * g.cosH), cos4H = g.cosH ** 4;
  const blinnPhong = (k, n) => k * (n + 2) * (n + 4) / (8 * Math.PI * (2 ** (-n / 2) + n)) * g.cosH ** n;
  const schlick = (f0) => f0 + (1 - f0) * (1 - g.cosD) ** 5;
  switch (c.model) {
    case 'blinn_phong': return diffuse + blinnPhong(ks, e);
    case 'two_blinn_phong': return diffuse + blinnPhong(ks, e) + blinnPhong(c.specular2[0], c.shape2);
    case 'ward': return diffuse + ks * Math.exp(-tan2H / (e * e)) / (4 * Math.PI * e * e * g.cosD * g.cosD * cos4H);
    case 'ggx': {
      const a2 = e * e, t = g.cosH * g.cosH * (a2 - 1) + 1, d = a2 / (Math.PI * t * t);
      const g1 = (cos) => 2 * cos / (cos + Math.sqrt(a2 + (1 - a2) * cos * cos));
      return diffuse + (c.specular_scale ?? 1) * d * g1(g.cosI) * g1(g.cosO) * schlick(ks) / (4 * g.cosI * g.cosO);
    }
    case 'cook_torrance': {
      const d = Math.exp(-tan2H / (e * e)) / (e * e * cos4H);
      const masking = Math.min(1, 2 * g.cosH * g.cosO / g.cosD, 2 * g.cosH * g.cosI / g.cosD);
      return diffuse + ks * d * masking * schlick(c.fresnel_f0) / (Math.PI * g.cosI * g.cosO);
    }
    default: return diffuse;
  }
}

// An NRRD volume (raw or gzip encoding, attached data): its slices along z.
async function volumeSlices(main, heading, runId, file) {
  const section = el('section', { class: 'volume' }, heading(`Volume ${file}`));
  main.append(section);
  try {
    const buffer = new Uint8Array(await (await api(`/runs/${runId}/files/${file}`)).arrayBuffer());
    let end = 0;
    while (end < buffer.length - 1 && !(buffer[end] === 10 && buffer[end + 1] === 10)) ++end;
    const fields = {};
    for (const line of new TextDecoder().decode(buffer.slice(0, end)).split('\n')) {
      const m = line.match(/^([^:#]+):=?\s*(.*)$/);
      if (m) fields[m[1].trim().toLowerCase()] = m[2].trim();
    }
    if (fields['data file']) throw new Error('detached NRRD data files are not shown');
    let data = buffer.slice(end + 2);
    if (fields.encoding === 'gzip' || fields.encoding === 'gz')
      data = new Uint8Array(await new Response(new Blob([data]).stream().pipeThrough(new DecompressionStream('gzip'))).arrayBuffer());
    else if (fields.encoding !== 'raw') throw new Error(`NRRD encoding '${fields.encoding}' is not shown (raw and gzip are)`);
    const [nx, ny, nz = 1] = fields.sizes.split(/\s+/).map(Number);
    const types = { float: Float32Array, double: Float64Array, uchar: Uint8Array, uint8: Uint8Array, ushort: Uint16Array,
      uint16: Uint16Array, short: Int16Array, int16: Int16Array, int: Int32Array, int32: Int32Array };
    const Type = types[fields.type];
    if (!Type) throw new Error(`NRRD type '${fields.type}' is not shown`);
    if (Type.BYTES_PER_ELEMENT > 1 && fields.endian === 'big') throw new Error('big-endian NRRD data are not shown');
    const voxels = new Type(data.buffer.slice(data.byteOffset, data.byteOffset + nx * ny * nz * Type.BYTES_PER_ELEMENT));
    let low = Infinity, high = -Infinity;
    for (const v of voxels) if (Number.isFinite(v)) { low = Math.min(low, v); high = Math.max(high, v); }
    const canvas = el('canvas', { width: nx, height: ny, style: `width:${Math.max(256, nx)}px;image-rendering:pixelated` });
    const slider = el('input', { type: 'range', min: 0, max: nz - 1, value: Math.floor(nz / 2) });
    const label = el('span');
    const draw = () => {
      const z = +slider.value, g = canvas.getContext('2d'), img = g.createImageData(nx, ny);
      for (let i = 0; i < nx * ny; ++i) {
        const level = 255 * (voxels[z * nx * ny + i] - low) / (high - low || 1);
        img.data.set([level, level, level, 255], 4 * i);
      }
      g.putImageData(img, 0, 0);
      label.textContent = ` slice z = ${z} of ${nz}; ${+low.toPrecision(4)} (black) … ${+high.toPrecision(4)} (white)`;
    };
    slider.addEventListener('input', draw);
    draw();
    section.append(canvas, el('p', {}, slider, label));
  } catch (error) {
    section.append(errorBox(error));
  }
}
