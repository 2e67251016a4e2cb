// A frame of a run as the camera saw it: tone-mapped preview with clipped
// pixels in red, its exposure and gain, and a histogram of its raw values.
import { api, getJson, imageUrl, el, runHeader } from './api.js';

export class FrameView {
  constructor() {
    // Hidden until it has a frame: an <img> without one shows a broken-image icon.
    this.image = el('img', { class: 'thumb', id: 'frame-image', alt: 'latest frame', hidden: true });
    this.placeholder = el('div', { class: 'thumb frame-placeholder', id: 'frame-placeholder' }, 'no frame yet');
    this.caption = el('div', { class: 'muted', id: 'frame-caption' });
    this.histogram = el('canvas', { width: 384, height: 90, id: 'frame-histogram', hidden: true });
    this.root = el('div', {}, this.placeholder, this.image, this.caption, this.histogram);
    this.shown = null;
    this.busy = false;
  }

  // Shows `file` of run `runId` (a journal record, when known, gives exposure and gain).
  async show(runId, file, record = null) {
    const key = `${runId}/${file}`;
    if (this.busy || key === this.shown) return;
    this.busy = true;
    try {
      const header = await runHeader(runId);
      const saturation = header.camera.saturation_dn > 0 ? header.camera.saturation_dn : 2 ** header.camera.bit_depth - 1;
      const query = `saturation=${saturation}&max_side=512`;
      const [{ url, headers }, stats] = await Promise.all([
        imageUrl(`/runs/${runId}/preview/${file}?${query}`), getJson(`/runs/${runId}/stats/${file}?${query}`)]);
      if (this.image.src) URL.revokeObjectURL(this.image.src);
      this.image.src = url;
      this.image.dataset.file = file;
      this.image.hidden = this.histogram.hidden = false;
      this.placeholder.remove();
      const exposure = record ? `${record.exposure_us} us, ${record.gain_db} dB, ` : '';
      this.caption.textContent = `${file}: ${exposure}${stats.width}×${stats.height}, ` +
        `${stats.min}..${stats.max} DN (shown ${(+headers.get('X-Preview-Low')).toFixed(0)}..` +
        `${(+headers.get('X-Preview-High')).toFixed(0)}), ${stats.clipped} clipped at ${saturation} DN (red)`;
      this.drawHistogram(stats, saturation);
      this.shown = key;
    } finally {
      this.busy = false;
    }
  }

  drawHistogram(stats, saturation) {
    const g = this.histogram.getContext('2d');
    const { width, height } = this.histogram;
    g.clearRect(0, 0, width, height);
    const peak = Math.log1p(Math.max(...stats.histogram));
    const bar = width / stats.histogram.length;
    stats.histogram.forEach((count, i) => {
      const top = (i + 1) / stats.histogram.length * (stats.max - stats.min) + stats.min;
      g.fillStyle = top >= saturation ? '#d22' : '#567';
      const h = Math.log1p(count) / peak * (height - 12);
      g.fillRect(i * bar, height - 12 - h, bar - 1, h);
    });
    g.fillStyle = '#333';
    g.font = '10px sans-serif';
    g.fillText(`${stats.min}`, 0, height - 1);
    g.fillText(`${stats.max} DN (log counts)`, width - 110, height - 1);
  }
}

// Every frame record of a run's journal (exposure, gain, LED, pose of each frame).
export async function journalRecords(runId) {
  const text = await (await api(`/runs/${runId}/files/journal.jsonl`)).text();
  return text.trim().split('\n').slice(1).map((line) => JSON.parse(line));
}
