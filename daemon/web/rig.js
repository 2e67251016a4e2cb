// Rig: devices, their state and last fault, what the lights and arms last
// did, free disk, and the camera's latest frame.
import { getJson, el, table, bytes, errorBox } from './api.js';
import { FrameView } from './frame_view.js';

export async function rigPage(main) {
  const devicesBox = el('section', { id: 'devices' }, el('h2', {}, 'Devices'));
  const frame = new FrameView();
  const liveBox = el('section', { id: 'live' }, el('h2', {}, 'Camera: latest frame'), frame.root);
  main.append(el('div', { class: 'row' }, devicesBox, liveBox));

  async function refresh() {
    try {
      const [devices, health] = await Promise.all([getJson('/devices'), getJson('/health')]);
      const last = devices.last_frame || {};
      const active = health.current_run && health.current_run === last.run;
      const lights = !active ? 'off (no run)' : last.led >= 0 ? `LED ${last.led} at level ${last.level}` : 'off (dark frame)';
      const pose = last.pose ? Object.entries(last.pose).map(([k, v]) => `${k} ${v.toFixed(1)}°`).join(', ') : '—';
      const body = el('div', {},
        el('p', {}, `Rig ${devices.rig}${devices.simulated ? ' (simulated)' : ''} · daemon ${health.status} · `,
          el('span', { id: 'free-disk' }, `${bytes(health.free_bytes)} free`)),
        table(devices.devices.map((d) => [d.role, d.id ?? '', d.driver, d.state,
          d.role === 'lights' ? `${d.channels} channels; ${lights}` :
            d.role === 'camera' ? `${d.width}×${d.height}` : d.role === 'motion' ? `${d.axes.join(', ')}; last pose ${pose}` : '']),
        ['role', 'id', 'driver', 'state', 'detail']),
        el('p', {}, 'Last fault: ', el('span', { id: 'last-fault' }, devices.last_fault || 'none')));
      devicesBox.replaceChildren(el('h2', {}, 'Devices'), body);
      if (last.run && last.file) await frame.show(last.run, last.file, last);
      else frame.placeholder.textContent = 'no frame taken since the daemon started';
    } catch (error) {
      devicesBox.append(errorBox(error));
    }
  }
  await refresh();
  const timer = setInterval(refresh, 1000);
  return () => clearInterval(timer);
}
