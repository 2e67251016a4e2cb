// Interactive relighting of a reflectance result in WebGL2: drag the light
// over the pad, the object is shaded from its per-pixel normals with
//   model 0 (Lambertian):      rho * max(n.l, 0)
//   model 1 (per-pixel lobe):  + rho_s * max(n.h, 0)^exponent where specular.tiff has a lobe
//   model 2 (environment map): rho * E(n), E the map's irradiance from 9 SH coefficients
//   model 3 (per-material):    (rho + pi f_lobe(material)) * max(n.l, 0), the lobes of solvers/brdf/models.h;
//                              a pixel without a material: rho_ps * max(n.l, 0), hatched blue
// rho is the diffuse albedo: the colour albedo of the per-material fit where
// the run has one (so models 0 and 3 differ by the lobes alone), else the
// photometric-stereo albedo; model 1 keeps the latter, the albedo its lobe was
// fitted against (docs/ui.md, "Relighting").
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
uniform highp sampler2D u_normals;    // RGB32F: (x, y, z), NaN where unsolved
uniform highp sampler2D u_albedo;     // RGB32F: the diffuse albedo rho (grey repeated where the run has one channel)
uniform highp sampler2D u_ps_albedo;  // RGB32F: photometric stereo's albedo, which the per-pixel lobe goes with
uniform highp sampler2D u_lobe;       // RG32F: (rho_s, exponent); 0 where no lobe was fitted
uniform highp sampler2D u_material;   // R32F: material index, 255 where the fit left the pixel out
uniform highp sampler2D u_materials;  // RGBA32F, one row per material: (model, shape, 0, 0), (specular rgb, 0)
uniform int u_model;                  // 0 Lambertian, 1 with the per-pixel lobe, 2 environment map, 3 per-material
uniform int u_material_count;
uniform vec3 u_light;                 // unit vector towards the light, camera coordinates
uniform float u_scale;                // radiance shown as white
uniform vec3 u_sh[9];                 // model 2: irradiance SH coefficients (RGB), envmap.js
in vec2 v_uv;
out vec4 color;

const float PI = 3.14159265358979;
const vec3 VIEW = vec3(0.0, 0.0, 1.0);  // orthographic camera looking down -z

// The lobe of solvers/brdf/src/lobes.h, f_r in 1/sr per channel: 1 Blinn-Phong
// (k_s, exponent; Giesen's normalisation), 2 GGX (F0, roughness; Trowbridge-Reitz
// D, separable Smith G, Schlick F).
vec3 materialLobe(int model, vec3 specular, float shape, float cos_i, float cos_o, float cos_h, float cos_d) {
  if (model == 1) {
    float normalisation = (shape + 2.0) * (shape + 4.0) / (8.0 * PI * (exp2(-0.5 * shape) + shape));
    return specular * normalisation * pow(cos_h, shape);
  }
  if (model == 2) {
    float a2 = shape * shape;
    float t = cos_h * cos_h * (a2 - 1.0) + 1.0;
    float d = a2 / (PI * t * t);
    float g_i = 2.0 * cos_i / (cos_i + sqrt(a2 + (1.0 - a2) * cos_i * cos_i));
    float g_o = 2.0 * cos_o / (cos_o + sqrt(a2 + (1.0 - a2) * cos_o * cos_o));
    vec3 fresnel = specular + (1.0 - specular) * pow(1.0 - cos_d, 5.0);
    return d * g_i * g_o * fresnel / (4.0 * cos_i * cos_o);
  }
  return vec3(0.0);
}

// As RenderReflectance (solvers/reflectance) with unit irradiance, times pi so
// that the diffuse part reads rho cos(theta_i) like the other models.
bool hasMaterial(vec2 uv) {
  float index = texture(u_material, uv).r;
  return index >= 0.0 && index < float(u_material_count);
}

vec3 perMaterial(vec3 n, vec3 l, vec2 uv) {
  // A pixel the fit left without a material (mixed, not assigned) has a
  // normal and a photometric-stereo albedo but no lobe: shaded Lambertian
  // from those, and hatched in main() so it never reads as a dark paint.
  if (!hasMaterial(uv)) return texture(u_ps_albedo, uv).rgb * max(dot(n, l), 0.0);
  float index = texture(u_material, uv).r;
  float cos_i = dot(n, l), cos_o = dot(n, VIEW);
  if (cos_i <= 0.0 || cos_o <= 0.0) return vec3(0.0);
  vec3 h = normalize(l + VIEW);
  vec4 row = texelFetch(u_materials, ivec2(0, int(index)), 0);
  vec3 specular = texelFetch(u_materials, ivec2(1, int(index)), 0).rgb;
  vec3 lobe = materialLobe(int(row.x + 0.5), specular, row.y, cos_i, cos_o, dot(n, h), dot(l, h));
  return (texture(u_albedo, uv).rgb + PI * lobe) * cos_i;
}

vec3 shade(vec3 n, vec2 uv) {
  if (u_model == 2) {
    float y[9] = float[9](${SH_GLSL});
    vec3 irradiance = vec3(0.0);
    for (int k = 0; k < 9; ++k) irradiance += u_sh[k] * y[k];
    return texture(u_albedo, uv).rgb * max(irradiance, 0.0) / u_scale;
  }
  vec3 l = normalize(u_light);
  if (u_model == 3) return perMaterial(n, l, uv) / u_scale;
  float ndotl = max(dot(n, l), 0.0);
  if (u_model == 0) return texture(u_albedo, uv).rgb * ndotl / u_scale;
  vec3 radiance = texture(u_ps_albedo, uv).rgb * ndotl;
  if (ndotl > 0.0) {
    vec2 lobe = texture(u_lobe, uv).rg;
    vec3 h = normalize(l + VIEW);
    radiance += lobe.x * pow(max(dot(n, h), 0.0), max(lobe.y, 1.0));
  }
  return radiance / u_scale;
}

void main() {
  vec3 n = texture(u_normals, v_uv).xyz;
  if (any(isnan(n)) || dot(n, n) < 0.25) { color = vec4(0.08, 0.08, 0.1, 1.0); return; }
  vec3 linear = clamp(shade(normalize(n), v_uv), 0.0, 1.0);
  vec3 shown = pow(linear, vec3(1.0 / 2.2));
  if (u_model == 3 && !hasMaterial(v_uv) && mod(gl_FragCoord.x + gl_FragCoord.y, 6.0) < 2.0)
    shown = mix(shown, vec3(0.12, 0.56, 1.0), 0.6);  // the flags map's colour for mixed
  color = vec4(shown, 1.0);
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

// The brightness shown as white: the albedo's 99th percentile over solved pixels and channels.
function albedoScale(albedo) {
  const finite = albedo.data.filter((v) => Number.isFinite(v) && v > 0).sort();
  return finite.length ? finite[Math.floor(0.99 * (finite.length - 1))] : 1;
}

// An image of 1 or 3 channels as 3 (grey repeated), NaN as 0 (left out: shaded black).
function asRgb(image) {
  const n = image.width * image.height, data = new Float32Array(3 * n);
  for (let i = 0; i < n; ++i)
    for (let c = 0; c < 3; ++c) {
      const v = image.data[image.channels === 3 ? 3 * i + c : i];
      data[3 * i + c] = Number.isFinite(v) ? v : 0;
    }
  return { width: image.width, height: image.height, data };
}

const LOBE_MODELS = { lambertian: 0, blinn_phong: 1, ggx: 2 };

// The lobe table of a per-material result (report.json `materials`): row m is
// (model, shape, 0, 0), (specular r, g, b, 0).
function materialTable(materials) {
  const data = new Float32Array(8 * Math.max(1, materials.length));
  materials.forEach((m, i) => {
    const model = LOBE_MODELS[m.model];
    if (model === undefined) throw new Error(`material ${i}: lobe model '${m.model}' is not one the page can shade`);
    data.set([model, m.shape, 0, 0, ...m.specular.slice(0, 3), 0], 8 * i);
  });
  return { width: 2, height: Math.max(1, materials.length), data };
}

// {root, setLight(x, y)}: normals {width, height, channels 3}, albedo (1 or 3 channels),
// lobe (specular.tiff, 3 channels: rho_s, exponent, 0) or null; envmaps:
// [{name, bytes: async () => Uint8Array}], the run's .hdr maps (a file from
// this computer can be chosen too); perMaterial: null, or a per-material
// result {albedo (1 or 3 channels), material (index image), materials
// (report.json's list)}, which then gives the diffuse albedo of every model
// but the per-pixel lobe.
export function relightView(normals, albedo, lobe, envmaps = [], perMaterial = null) {
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
  const none = (channels) => ({ width: 1, height: 1, data: new Float32Array(channels) });
  const diffuse = perMaterial ? perMaterial.albedo : albedo;
  texture(gl, 0, normals, gl.RGB32F, gl.RGB);
  texture(gl, 1, asRgb(diffuse), gl.RGB32F, gl.RGB);
  texture(gl, 2, asRgb(albedo), gl.RGB32F, gl.RGB);
  const lobeRg = lobe ? { width: lobe.width, height: lobe.height, data: new Float32Array(lobe.width * lobe.height * 2) }
    : none(2);
  if (lobe) for (let i = 0; i < lobe.width * lobe.height; ++i) {
    lobeRg.data[2 * i] = lobe.data[3 * i];
    lobeRg.data[2 * i + 1] = lobe.data[3 * i + 1];
  }
  texture(gl, 3, lobeRg, gl.RG32F, gl.RG);
  texture(gl, 4, perMaterial ? perMaterial.material : none(1), gl.R32F, gl.RED);
  texture(gl, 5, materialTable(perMaterial ? perMaterial.materials : []), gl.RGBA32F, gl.RGBA);
  const uniform = (name) => gl.getUniformLocation(p, name);
  ['u_normals', 'u_albedo', 'u_ps_albedo', 'u_lobe', 'u_material', 'u_materials'].forEach((name, unit) => gl.uniform1i(uniform(name), unit));
  gl.uniform1i(uniform('u_material_count'), perMaterial ? perMaterial.materials.length : 0);
  // White is each model's own albedo's 99th percentile (times 2^exposure).
  const diffuseScale = albedoScale(diffuse), lobeScale = albedoScale(albedo);

  const light = { x: -0.4, y: 0.4 };
  // The richest model the run has is shown first.
  const model = el('select', { id: 'relight-model' },
    el('option', { value: 0 }, perMaterial ? 'Lambertian (normals + colour albedo)' : 'Lambertian (normals + albedo)'),
    lobe ? el('option', { value: 1, selected: !perMaterial }, 'with the per-pixel lobe (specular.tiff)') : null,
    el('option', { value: 2 }, 'environment map (Lambertian)'),
    perMaterial ? el('option', { value: 3, selected: true }, `per-material (${perMaterial.materials.map((m) => m.model).join(', ')})`) : null);
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
    canvas.dataset.light = [light.x, light.y, z].join(',');  // the exact direction drawn, for scripts and tests
    gl.uniform1i(uniform('u_model'), +model.value);
    const white = (model.value === '1' ? lobeScale : diffuseScale) / 2 ** +exposure.value;
    gl.uniform1f(uniform('u_scale'), white);
    canvas.dataset.white = white;  // the linear value drawn white, for scripts and tests
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
