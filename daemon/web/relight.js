// Interactive relighting of a photometric-stereo result in WebGL2: drag the
// light over the pad, the object is shaded from its per-pixel normals with
//   model 0 (Lambertian):      albedo * max(n.l, 0)
//   model 1 (per-pixel lobe):  + rho_s * max(n.h, 0)^exponent where specular.tiff has a lobe
// Every reflectance result reaches the shader the same way: per-pixel float
// textures (normals, albedo, lobe) and a model switch. A per-material result
// (a material-index map and a table of lobe parameters per material) adds a
// texture pair and one branch in shade() (docs/ui.md, "Relighting").
import { el } from './api.js';

const VERTEX = `#version 300 es
in vec2 a_position;
out vec2 v_uv;
void main() {
  v_uv = vec2(a_position.x, -a_position.y) * 0.5 + 0.5;  // row 0 of the maps at the top
  gl_Position = vec4(a_position, 0.0, 1.0);
}`;

const FRAGMENT = `#version 300 es
precision highp float;
uniform highp sampler2D u_normals;  // RGB32F: (x, y, z), NaN where unsolved
uniform highp sampler2D u_albedo;   // R32F
uniform highp sampler2D u_lobe;     // RG32F: (rho_s, exponent); 0 where no lobe was fitted
uniform int u_model;                // 0 Lambertian, 1 with the per-pixel lobe
uniform vec3 u_light;               // unit vector towards the light, camera coordinates
uniform float u_scale;              // albedo value shown as white
in vec2 v_uv;
out vec4 color;

vec3 shade(vec3 n, vec2 uv) {
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
// lobe (specular.tiff, 3 channels: rho_s, exponent, 0) or null.
export function relightView(normals, albedo, lobe) {
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
    lobe ? el('option', { value: 1, selected: true }, 'with the per-pixel lobe (specular.tiff)') : null);
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
    el('div', {}, el('p', {}, 'Drag the light:'), pad, readout, el('p', {}, model), el('p', {}, 'exposure ', exposure)));
  return { root, setLight };
}
