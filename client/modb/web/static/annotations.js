// The timeline annotation editor (as in the DFKI motion database's client): a clip version's segments
// (name, start, end: frames, 0-based, inclusive) drawn over the clip's length, edited at the frame slider,
// and its tags; saved through the REST interface with the token of this tab and the ETag the meta was read
// with, so a save over someone else's newer edit is refused (409) instead of undoing it.
//
// Keys (outside text fields): n new segment at the slider, c cut the selected one at the slider, m merge it
// with the next, Delete remove it, [ and ] move its start or end to the slider, Tab select the next, s save.
import { token } from './token.js';

// A segment as meta stores it: keyframes and the automatic mark only when it has them.
function stored({ name, start, end, keyframes, auto }) {
  return { name, start, end, ...(keyframes && keyframes.length ? { keyframes } : {}), ...(auto ? { auto } : {}) };
}

const SHORTCUTS = { n: 'create', c: 'cut', m: 'merge', Delete: 'remove', Backspace: 'remove', '[': 'setStart',
                    ']': 'setEnd', Tab: 'selectNext', s: 'save' };

export class AnnotationEditor {
  // ui: {bar, plot, name, tags, status, joint, quantity, buttons: {action: element}}; viewer: {frame(),
  // setFrame(i), positions(), jointNames()}
  constructor(ui, viewer) {
    Object.assign(this, { ui, viewer, clip: null, meta: {}, segments: [], tags: [], etag: null, selected: -1,
                          dirty: false });
    Object.entries(ui.buttons).forEach(([action, button]) => button.addEventListener('click', () => this[action]()));
    ui.name.addEventListener('change', () => this.rename(ui.name.value));
    ui.tags.addEventListener('change', () => {
      this.tags = ui.tags.value.split(',').map((t) => t.trim()).filter(Boolean);
      this.changed();
    });
    ui.joint.addEventListener('change', () => this.drawPlot());
    ui.quantity.addEventListener('change', () => this.drawPlot());
    window.addEventListener('keydown', (e) => this.key(e));
    window.addEventListener('resize', () => this.render());
  }

  async open(clip) {
    this.clip = clip;
    const response = await fetch(`/api/clips/${clip.id}/versions/${clip.version}/meta`, { headers: token.headers() });
    const body = await response.json();
    if (!response.ok) return this.say(body.error || `HTTP ${response.status}`, true);
    this.take(body.meta, response.headers.get('ETag'));
    const names = this.viewer.jointNames();
    this.ui.joint.replaceChildren(...names.map((name, i) => new Option(name, i)));
    if (names.includes(this.viewer.plotJoint())) this.ui.joint.value = String(names.indexOf(this.viewer.plotJoint()));
    this.drawPlot();
    this.say('');
  }

  take(meta, etag) {
    Object.assign(this, { meta, etag, dirty: false, selected: -1, tags: [...(meta.tags || [])],
                          segments: (meta.annotations || []).map((s) => ({ ...s })) });
    this.sort();
    this.render();
  }

  key(e) {
    if (!this.clip || ['INPUT', 'SELECT', 'TEXTAREA'].includes(e.target.tagName)) return;
    const action = SHORTCUTS[e.key];
    if (!action || e.ctrlKey || e.metaKey || e.altKey) return;
    e.preventDefault();
    this[action]();
  }

  sort() {
    const chosen = this.segments[this.selected];
    this.segments.sort((a, b) => a.start - b.start || a.end - b.end);
    this.selected = this.segments.indexOf(chosen);
  }

  // A segment a person changed is theirs: it loses the automatic mark (so `modb annotate --steps`
  // run again keeps it) and any keyframe it no longer holds.
  changed(...touched) {
    for (const s of touched) {
      delete s.auto;
      if (s.keyframes) s.keyframes = s.keyframes.filter((k) => s.start <= k && k <= s.end);
    }
    this.dirty = true;
    this.sort();
    this.render();
    this.say('unsaved changes (s saves)');
  }

  need(what) {
    if (this.selected < 0) { this.say(`select a segment to ${what} first`, true); return null; }
    return this.segments[this.selected];
  }

  last() { return this.clip.n_frames - 1; }

  create() {
    const f = this.viewer.frame();
    const name = this.ui.name.value.trim() || 'segment';
    this.segments.push({ name, start: f, end: Math.min(f + 29, this.last()) });
    this.selected = this.segments.length - 1;
    this.changed();
  }

  cut() {
    const s = this.need('cut');
    const f = this.viewer.frame();
    if (!s) return;
    if (!(s.start < f && f <= s.end)) return this.say(`the slider (${f}) is not inside ${s.name} ${s.start}-${s.end}`, true);
    this.segments.push({ name: s.name, start: f, end: s.end, keyframes: s.keyframes });
    s.end = f - 1;
    this.changed(s, this.segments[this.segments.length - 1]);
  }

  merge() {
    const s = this.need('merge');
    if (!s) return;
    const next = this.segments[this.selected + 1];
    if (!next) return this.say('no segment after this one to merge with', true);
    s.end = Math.max(s.end, next.end);
    s.keyframes = [...(s.keyframes || []), ...(next.keyframes || [])];
    this.segments.splice(this.selected + 1, 1);
    this.changed(s);
  }

  remove() {
    if (!this.need('delete')) return;
    this.segments.splice(this.selected, 1);
    this.selected = -1;
    this.changed();
  }

  rename(name) {
    const s = this.need('rename');
    if (!s || !name.trim()) return;
    s.name = name.trim();
    this.changed(s);
  }

  setStart() {
    const s = this.need('move');
    if (!s) return;
    s.start = Math.min(this.viewer.frame(), s.end);
    this.changed(s);
  }

  setEnd() {
    const s = this.need('move');
    if (!s) return;
    s.end = Math.max(this.viewer.frame(), s.start);
    this.changed(s);
  }

  selectNext() {
    if (!this.segments.length) return;
    this.select((this.selected + 1) % this.segments.length);
  }

  select(i) {
    this.selected = i;
    const s = this.segments[i];
    if (s) { this.ui.name.value = s.name; this.viewer.setFrame(s.start); }
    this.render();
  }

  async save() {
    if (!this.clip) return;
    if (!token.get()) return this.say('saving needs a loader token: paste one under "Access token"', true);
    const meta = { ...this.meta, annotations: this.segments.map(stored), tags: this.tags };
    if (!meta.annotations.length) delete meta.annotations;
    if (!meta.tags.length) delete meta.tags;
    const response = await fetch(`/api/clips/${this.clip.id}/versions/${this.clip.version}/meta`, {
      method: 'PUT',
      headers: { 'Content-Type': 'application/json', 'If-Match': this.etag, ...token.headers() },
      body: JSON.stringify({ meta }),
    });
    const body = await response.json();
    if (response.status === 409) {
      return this.say('someone saved this clip since you opened it: reopen it to see theirs (yours is not saved)', true);
    }
    if (!response.ok) return this.say(body.error || `HTTP ${response.status}`, true);
    this.take(body.meta, response.headers.get('ETag'));
    this.say('saved');
  }

  say(text, isError = false) {
    this.ui.status.textContent = text;
    this.ui.status.classList.toggle('error', isError);
  }

  // Segments in lanes (an overlapping one goes a lane down), each with handles that drag its ends.
  render() {
    const bar = this.ui.bar;
    bar.replaceChildren();
    this.ui.tags.value = this.tags.join(', ');
    if (!this.clip) return;
    const width = bar.clientWidth || 1;
    const x = (frame) => (frame / Math.max(this.last(), 1)) * width;
    const lanes = [];
    this.segments.forEach((s, i) => {
      let lane = lanes.findIndex((end) => end < s.start);
      if (lane < 0) { lane = lanes.length; lanes.push(0); }
      lanes[lane] = s.end;
      const div = document.createElement('div');
      div.className = `segment${i === this.selected ? ' selected' : ''}${s.auto ? ' auto' : ''}`;
      Object.assign(div.style, { left: `${x(s.start)}px`, width: `${Math.max(x(s.end) - x(s.start), 4)}px`,
                                 top: `${lane * 22}px` });
      div.textContent = s.name;
      div.title = `${s.name}: frames ${s.start}-${s.end}`
        + (s.keyframes && s.keyframes.length ? `, keyframes ${s.keyframes.join(', ')}` : '')
        + (s.auto ? ' (found from the feet; editing makes it yours)' : '');
      div.dataset.index = i;
      div.addEventListener('mousedown', (e) => { if (!e.target.classList.contains('handle')) this.select(i); });
      for (const end of ['start', 'end']) {
        const handle = document.createElement('span');
        handle.className = `handle ${end}`;
        handle.addEventListener('mousedown', (e) => this.drag(e, i, end, x));
        div.appendChild(handle);
      }
      bar.appendChild(div);
    });
    bar.style.height = `${Math.max(lanes.length, 1) * 22}px`;
    this.drawPlot();
  }

  drag(event, i, end, x) {
    event.preventDefault();
    event.stopPropagation();
    this.selected = i;
    const s = this.segments[i];
    const rect = this.ui.bar.getBoundingClientRect();
    const move = (e) => {
      const frame = Math.round(((e.clientX - rect.left) / rect.width) * this.last());
      const f = Math.max(0, Math.min(this.last(), frame));
      if (end === 'start') s.start = Math.min(f, s.end); else s.end = Math.max(f, s.start);
      this.viewer.setFrame(end === 'start' ? s.start : s.end);
      this.changed(s);
    };
    const up = () => { window.removeEventListener('mousemove', move); window.removeEventListener('mouseup', up); };
    window.addEventListener('mousemove', move);
    window.addEventListener('mouseup', up);
  }

  // The plotted values: the chosen joint's height, world x or z (m), or horizontal speed (m/s) in every
  // frame (of the motion shown, or of `given` frames' positions).
  plotValues(given = null) {
    const positions = given || this.viewer.positions();
    if (!this.clip || !positions || !positions.length) return null;
    const joint = Number(this.ui.joint.value || 0);
    const edit = given ? 'stored' : (this.viewer.revision ? this.viewer.revision() : 0); // the pose editor's
    const key = `${this.clip.id}/${this.clip.version}/${joint}/${this.ui.quantity.value}/${edit}`;
    const cache = given ? 'plottedStored' : 'plotted';
    if (this[cache] && this[cache].key === key) return this[cache].values;
    const fps = this.clip.fps;
    const values = positions.map((p, f) => {
      const axis = { x: 0, height: 1, z: 2 }[this.ui.quantity.value];
      if (axis !== undefined) return p[joint][axis];
      const after = Math.min(f + 1, positions.length - 1);
      const before = Math.max(f - 1, 0);
      const q = positions[after][joint];
      const r = positions[before][joint];
      return after > before ? Math.hypot(q[0] - r[0], q[2] - r[2]) * fps / (after - before) : 0;
    });
    this[cache] = { key, values };
    return values;
  }

  drawCursor() { this.drawPlot(); }

  // The plot, and a line at the current frame: where a foot plants or a hand stops is where to cut.
  drawPlot() {
    const canvas = this.ui.plot;
    const ctx = canvas.getContext('2d');
    if (canvas.width !== (canvas.clientWidth || 300)) canvas.width = canvas.clientWidth || 300;
    ctx.clearRect(0, 0, canvas.width, canvas.height);
    const values = this.plotValues();
    if (!values) return;
    // while the pose editor shows an edit: the stored motion dashed, the edited one solid
    const stored = this.viewer.originalPositions ? this.viewer.originalPositions() : null;
    const before = stored ? this.plotValues(stored) : null;
    const all = before ? values.concat(before) : values;
    const lo = all.reduce((a, v) => Math.min(a, v), Infinity);
    const hi = Math.max(all.reduce((a, v) => Math.max(a, v), -Infinity), lo + 1e-6);
    const x = (f) => (f / Math.max(values.length - 1, 1)) * canvas.width;
    const y = (v) => canvas.height - 2 - ((v - lo) / (hi - lo)) * (canvas.height - 4);
    const range = this.viewer.blendRange ? this.viewer.blendRange() : null;
    if (range) { // the frames the next pose edit changes
      ctx.fillStyle = 'rgba(232, 137, 43, 0.18)';
      ctx.fillRect(x(range[0]), 0, Math.max(x(range[1]) - x(range[0]), 1), canvas.height);
    }
    const line = (vs, colour, dash) => {
      ctx.strokeStyle = colour;
      ctx.setLineDash(dash);
      ctx.beginPath();
      vs.forEach((v, f) => (f ? ctx.lineTo(x(f), y(v)) : ctx.moveTo(x(f), y(v))));
      ctx.stroke();
      ctx.setLineDash([]);
    };
    if (before) line(before, '#7d8590', [4, 3]);
    line(values, '#2f6fc4', []);
    ctx.strokeStyle = '#b00020';
    ctx.beginPath();
    ctx.moveTo(x(this.viewer.frame()), 0);
    ctx.lineTo(x(this.viewer.frame()), canvas.height);
    ctx.stroke();
    this.ui.plotRange.textContent = `${lo.toFixed(2)}-${hi.toFixed(2)} ${this.ui.quantity.value === 'speed' ? 'm/s' : 'm'}`;
  }
}
