// Environment maps for relighting: Radiance .hdr (RGBE) decoding and the
// projection of a lat-long map onto 9 spherical-harmonic coefficients per
// colour, whose irradiance convolution lights a Lambertian surface
// (Ramamoorthi and Hanrahan 2001). Lat-long convention as solvers/lighting
// (docs/lighting.md): row 0 up (+y), azimuth 0 at +z (towards the camera).

// {width, height, data: Float32Array RGB} from a .hdr file's bytes.
export function decodeHdr(bytes) {
  let at = 0;
  const line = () => {
    let end = bytes.indexOf(10, at);
    if (end < 0) throw new Error('not a Radiance .hdr file: its header does not end');
    const text = new TextDecoder().decode(bytes.subarray(at, end));
    at = end + 1;
    return text;
  };
  if (!line().startsWith('#?')) throw new Error('not a Radiance .hdr file');
  for (let text = line(); text !== ''; text = line())
    if (text.startsWith('FORMAT=') && text !== 'FORMAT=32-bit_rle_rgbe') throw new Error(`.hdr ${text} is not read (RGBE is)`);
  const size = line().match(/^-Y (\d+) \+X (\d+)$/);
  if (!size) throw new Error('.hdr orientation other than -Y H +X W is not read');
  const height = +size[1], width = +size[2];
  const rgbe = new Uint8Array(width * height * 4);
  for (let y = 0; y < height; ++y) {
    const row = rgbe.subarray(y * width * 4, (y + 1) * width * 4);
    if (width >= 8 && width < 32768 && bytes[at] === 2 && bytes[at + 1] === 2 && !(bytes[at + 2] & 0x80)) {
      at += 4;  // run-length encoded: each of the 4 components in turn
      for (let c = 0; c < 4; ++c) {
        for (let x = 0; x < width;) {
          let count = bytes[at++];
          if (count > 128) {
            count -= 128;
            const value = bytes[at++];
            while (count-- > 0) row[4 * x++ + c] = value;
          } else {
            while (count-- > 0) row[4 * x++ + c] = bytes[at++];
          }
        }
      }
    } else {
      row.set(bytes.subarray(at, at + width * 4));
      at += width * 4;
    }
  }
  const data = new Float32Array(width * height * 3);
  for (let i = 0; i < width * height; ++i) {
    const e = rgbe[4 * i + 3];
    const f = e ? 2 ** (e - 136) : 0;
    for (let c = 0; c < 3; ++c) data[3 * i + c] = rgbe[4 * i + c] * f;
  }
  return { width, height, data };
}

// The 9 irradiance SH coefficients (RGB each, 27 numbers) of `map` turned by
// `azimuth` radians about +y, scaled so the brightest of the surfaces the
// camera sees best (normals +z, ±x, ±y) with albedo 1 shows 1 in its brightest channel.
export function irradianceSh(map, azimuth = 0) {
  const { width, height, data } = map;
  const L = new Float64Array(27);
  const a = [Math.PI, 2 * Math.PI / 3, 2 * Math.PI / 3, 2 * Math.PI / 3, Math.PI / 4, Math.PI / 4, Math.PI / 4, Math.PI / 4, Math.PI / 4];
  for (let v = 0; v < height; ++v) {
    const theta = Math.PI * (v + 0.5) / height;
    const solid = 2 * Math.PI / width * (Math.cos(Math.PI * v / height) - Math.cos(Math.PI * (v + 1) / height));
    for (let u = 0; u < width; ++u) {
      const phi = 2 * Math.PI * (u + 0.5) / width - Math.PI + azimuth;
      const y = basis(Math.sin(theta) * Math.sin(phi), Math.cos(theta), Math.sin(theta) * Math.cos(phi));
      const i = 3 * (v * width + u);
      for (let k = 0; k < 9; ++k) for (let c = 0; c < 3; ++c) L[3 * k + c] += data[i + c] * y[k] * solid;
    }
  }
  for (let k = 0; k < 9; ++k) for (let c = 0; c < 3; ++c) L[3 * k + c] *= a[k] / Math.PI;  // radiance of albedo 1
  let reference = 0;
  for (const n of [[0, 0, 1], [1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0]]) {
    const y = basis(...n);
    for (let c = 0; c < 3; ++c) reference = Math.max(reference, y.reduce((sum, yk, k) => sum + yk * L[3 * k + c], 0));
  }
  return Float32Array.from(L, (x) => x / (reference > 0 ? reference : 1));
}

export function basis(x, y, z) {
  return [0.282095, 0.488603 * y, 0.488603 * z, 0.488603 * x, 1.092548 * x * y, 1.092548 * y * z,
    0.315392 * (3 * z * z - 1), 1.092548 * x * z, 0.546274 * (x * x - y * y)];
}
