// Interactive relighting of a photometric-stereo result in WebGL2: drag the
// light over the pad, the object is shaded from its per-pixel normals with
//   model 0 (Lambertian):      albedo * max(n.l, 0)
//   model 1 (per-pixel lobe):  + rho_s * max(n.h, 0)^exponent where specular.tiff has a lobe
//   model 2 (environment map): albedo * E(n), E the map's irradiance from 9 SH coefficients
// Every reflectance result reaches the shader the same way: per-pixel float
// textures (normals, albedo, lobe) and a model switch. A per-material result
// (a material-index map and a table of lobe parameters per material) adds a
// texture pair and one branch in shade() (docs/ui.md, "Relighting").
import { el, errorBox } from './api.js';
import { decodeHdr, irradianceSh } from './envmap.js';

const VERTEX = `#version 300 es
in vec2 a_position;
out vec2 v_uv;
void main() {
  v_uv = vec2(a_position.x, -a_position.y) * 0.5 + 0.5;  // row 0 of the maps at the top
  gl_Position = vec4(a_position, 0.0, 1.0);
}`;

// The SH basis of envmap.js as GLSL, written out once.
const SH_GLSL = '0.282095, 0.488603 * n.y, 0.488603 * n.z, 0.488603 * n.x, 1.092548 * n.x * n.y, 1.092548 * n.y * n.z, ' +
  '0.315392 * (3.0 * n.z * n.z - 1.0), 1.092548 * n.x * n.z, 0.546274 * (n.x * n.x - n.y * n.y)';

const FRAGMENT = `#version 300 es
precision highp float;
uniform highp sampler2D u_normals;  // RGB32F: (x, y, z), NaN where unsolved
uniform highp sampler2D u_albedo;   // R32F
uniform highp sampler2D u_lobe;     // RG32F: (rho_s, exponent); 0 where no lobe was fitted
uniform int u_model;                // 0 Lambertian, 1 with the per-pixel lobe, 2 environment map
uniform vec3 u_light;               // unit vector towards the light, camera coordinates
uniform float u_scale;              // albedo value shown as white
uniform vec3 u_sh[9];               // model 2: irradiance SH coefficients (RGB), envmap.js
in vec2 v_uv;
out vec4 color;

vec3 shade(vec3 n, vec2 uv) {
  if (u_model == 2) {
    float y[9] = float[9](${SH_GLSL});
    vec3 irradiance = vec3(0.0);
    for (int k = 0; k < 9; ++k) irradiance += u_sh[k] * y[k];
    return texture(u_albedo, uv).r * max(irradiance, 0.0) / u_scale;
  }
  vec3 l = normalize(u_light);
  float ndotl = max(dot(n, l), 0.0);
  float radiance = texture(u_albedo, uv).r * ndotl;
  if (u_model == 1 && ndotl > 0.0) {
    vec2 lobe = texture(u_lobe, uv).rg;
    vec3 h = normalize(l + vec3(0.0, 0.0, 1.0));  // orthographic camera looking down -z
    radiance += lobe.x * pow(max(dot(n, h), 0.0), max(lobe.y, 1.0));
  }
  return vec3(radiance / u_scale);
}

void main() {
  vec3 n = texture(u_normals, v_uv).xyz;
  if (any(isnan(n)) || dot(n, n) < 0.25) { color = vec4(0.08, 0.08, 0.1, 1.0); return; }
  vec3 linear = clamp(shade(normalize(n), v_uv), 0.0, 1.0);
  color = vec4(pow(linear, vec3(1.0 / 2.2)), 1.0);
}`;

function texture(gl, unit, image, internal, format) {
  const t = gl.createTexture();
  gl.activeTexture(gl.TEXTURE0 + unit);
  gl.bindTexture(gl.TEXTURE_2D, t);
  for (const p of [gl.TEXTURE_MIN_FILTER, gl.TEXTURE_MAG_FILTER]) gl.texParameteri(gl.TEXTURE_2D, p, gl.NEAREST);
  gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_WRAP_S, gl.CLAMP_TO_EDGE);
  gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_WRAP_T, gl.CLAMP_TO_EDGE);
  gl.pixelStorei(gl.UNPACK_ALIGNMENT, 1);
  gl.texImage2D(gl.TEXTURE_2D, 0, internal, image.width, image.height, 0, format, gl.FLOAT, image.data);
}

function program(gl) {
  const p = gl.createProgram();
  for (const [type, source] of [[gl.VERTEX_SHADER, VERTEX], [gl.FRAGMENT_SHADER, FRAGMENT]]) {
    const s = gl.createShader(type);
    gl.shaderSource(s, source);
    gl.compileShader(s);
    if (!gl.getShaderParameter(s, gl.COMPILE_STATUS)) throw new Error(`relighting shader: ${gl.getShaderInfoLog(s)}`);
    gl.attachShader(p, s);
  }
  gl.linkProgram(p);
  if (!gl.getProgramParameter(p, gl.LINK_STATUS)) throw new Error(`relighting shader: ${gl.getProgramInfoLog(p)}`);
  return p;
}

// The brightness shown as white: the albedo's 99th percentile over solved pixels.
function albedoScale(albedo) {
  const finite = albedo.data.filter((v) => Number.isFinite(v) && v > 0).sort();
  return finite.length ? finite[Math.floor(0.99 * (finite.length - 1))] : 1;
}

// {root, setLight(x, y)}: normals {width, height, channels 3}, albedo (1 channel),
// lobe (specular.tiff, 3 channels: rho_s, exponent, 0) or null; envmaps:
// [{name, bytes: async () => Uint8Array}], the run's .hdr maps (a file from
// this computer can be chosen too).
export function relightView(normals, albedo, lobe, envmaps = []) {
  const canvas = el('canvas', { id: 'relight-canvas', width: normals.width, height: normals.height });
  const gl = canvas.getContext('webgl2', { preserveDrawingBuffer: true });
  if (!gl) throw new Error('relighting needs WebGL2, which this browser does not offer');
  const p = program(gl);
  gl.useProgram(p);
  const quad = gl.createBuffer();
  gl.bindBuffer(gl.ARRAY_BUFFER, quad);
  gl.bufferData(gl.ARRAY_BUFFER, new Float32Array([-1, -1, 1, -1, -1, 1, 1, 1]), gl.STATIC_DRAW);
  const a = gl.getAttribLocation(p, 'a_position');
  gl.enableVertexAttribArray(a);
  gl.vertexAttribPointer(a, 2, gl.FLOAT, false, 0, 0);
  texture(gl, 0, normals, gl.RGB32F, gl.RGB);
  texture(gl, 1, albedo, gl.R32F, gl.RED);
  const lobeRg = lobe ? { width: lobe.width, height: lobe.height, data: new Float32Array(lobe.width * lobe.height * 2) }
    : { width: 1, height: 1, data: new Float32Array(2) };
  if (lobe) for (let i = 0; i < lobe.width * lobe.height; ++i) {
    lobeRg.data[2 * i] = lobe.data[3 * i];
    lobeRg.data[2 * i + 1] = lobe.data[3 * i + 1];
  }
  texture(gl, 2, lobeRg, gl.RG32F, gl.RG);
  const uniform = (name) => gl.getUniformLocation(p, name);
  gl.uniform1i(uniform('u_normals'), 0);
  gl.uniform1i(uniform('u_albedo'), 1);
  gl.uniform1i(uniform('u_lobe'), 2);
  const scale = albedoScale(albedo);

  const light = { x: -0.4, y: 0.4 };
  const model = el('select', { id: 'relight-model' }, el('option', { value: 0 }, 'Lambertian (normals + albedo)'),
    lobe ? el('option', { value: 1, selected: true }, 'with the per-pixel lobe (specular.tiff)') : null,
    el('option', { value: 2 }, 'environment map (Lambertian)'));
  const mapSelect = el('select', { id: 'envmap-select' }, envmaps.map((m, i) => el('option', { value: i }, m.name)));
  const mapFile = el('input', { type: 'file', accept: '.hdr', id: 'envmap-file' });
  const azimuth = el('input', { type: 'range', min: -180, max: 180, step: 5, value: 0, id: 'envmap-azimuth' });
  const envError = el('div');
  const envControls = el('div', { hidden: true }, el('p', {}, 'map ', mapSelect, ' or ', mapFile),
    el('p', {}, 'turn ', azimuth), envError);
  let environment = null;  // the decoded map in use
  async function useMap(load) {
    envError.replaceChildren();
    try {
      environment = decodeHdr(await load());
      setEnvironment();
    } catch (error) {
      envError.append(errorBox(error));
    }
  }
  function setEnvironment() {
    if (!environment) return;
    gl.uniform3fv(uniform('u_sh'), irradianceSh(environment, +azimuth.value * Math.PI / 180));
    draw();
  }
  mapSelect.addEventListener('change', () => useMap(envmaps[mapSelect.value].bytes));
  mapFile.addEventListener('change', () => mapFile.files[0] && useMap(async () => new Uint8Array(await mapFile.files[0].arrayBuffer())));
  azimuth.addEventListener('input', setEnvironment);
  model.addEventListener('change', () => {
    envControls.hidden = model.value !== '2';
    if (model.value === '2' && !environment && envmaps.length) useMap(envmaps[0].bytes);
  });
  const exposure = el('input', { type: 'range', min: -3, max: 3, step: 0.1, value: -0.5, id: 'relight-exposure' });
  const pad = el('canvas', { class: 'light-pad', width: 160, height: 160, id: 'light-pad' });
  const readout = el('div', { class: 'readout', id: 'light-readout' });

  function draw() {
    const z = Math.sqrt(Math.max(0, 1 - light.x ** 2 - light.y ** 2));
    gl.viewport(0, 0, canvas.width, canvas.height);
    gl.uniform3f(uniform('u_light'), light.x, light.y, z);
    gl.uniform1i(uniform('u_model'), +model.value);
    gl.uniform1f(uniform('u_scale'), scale / 2 ** +exposure.value);
    gl.drawArrays(gl.TRIANGLE_STRIP, 0, 4);
    const g = pad.getContext('2d');
    g.clearRect(0, 0, 160, 160);
    g.strokeStyle = '#556';
    for (const r of [26.7, 53.3, 80]) { g.beginPath(); g.arc(80, 80, r, 0, 2 * Math.PI); g.stroke(); }
    g.fillStyle = '#ffd94a';
    g.beginPath(); g.arc(80 + 80 * light.x, 80 - 80 * light.y, 7, 0, 2 * Math.PI); g.fill();
    readout.textContent = `light (${light.x.toFixed(2)}, ${light.y.toFixed(2)}, ${z.toFixed(2)}), ` +
      `${(Math.acos(z) * 180 / Math.PI).toFixed(0)}° from the camera axis`;
  }
  // The pad is the hemisphere seen from above: x right, y up, the rim 90° from the axis.
  function setLight(x, y) {
    const r = Math.hypot(x, y);
    light.x = r > 0.999 ? 0.999 * x / r : x;
    light.y = r > 0.999 ? 0.999 * y / r : y;
    draw();
  }
  const drag = (event) => {
    if (event.buttons !== 1 && event.type !== 'pointerdown') return;
    const box = pad.getBoundingClientRect();
    setLight((event.clientX - box.left) / box.width * 2 - 1, 1 - (event.clientY - box.top) / box.height * 2);
  };
  pad.addEventListener('pointerdown', drag);
  pad.addEventListener('pointermove', drag);
  model.addEventListener('change', draw);
  exposure.addEventListener('input', draw);
  draw();
  const root = el('div', { class: 'row' }, canvas,
    el('div', {}, el('p', {}, 'Drag the light:'), pad, readout, el('p', {}, model), envControls,
      el('p', {}, 'exposure ', exposure)));
  return { root, setLight };
}
