// The pose editor (issue 64): click a joint of the character to select it, then drag three.js's
// TransformControls gizmo at the current frame: *move* gives an `ik` command (the joint's target moved by
// the gizmo's offset, in the character's heading frame there: x its left, y up, z forward; the gizmo's
// axes are that frame's), *turn* a `rotate` command (a rotation vector in the joint's parent frame: the
// gizmo's rings are that frame's axes). Each command's change is spread over the blend range (before, after:
// seconds, shaded on the plot under the timeline). The server computes the edited motion with the kernel
// that saving runs (POST /api/clips/ID/edit-preview) and the page shows it at once: one request in flight,
// the newest script sent when it answers (a drag never queues requests). Undo drops the last command;
// save stores the script (PUT /api/edit-scripts/NAME) and applies it to the clip as a new version (POST
// /api/edit-scripts/NAME/apply), with this tab's loader token; discard drops every command.
import * as THREE from 'three';
import { TransformControls } from 'three/addons/controls/TransformControls.js';
import { token } from './token.js';

const PICK_PX = 14; // a click this near a joint's place on the canvas selects it
const CLICK_PX = 5; // a press that moves further is the camera's drag, not a click

async function send(url, method, body) {
  const response = await fetch(url, {
    method, headers: { 'Content-Type': 'application/json', ...token.headers() }, body: JSON.stringify(body),
  });
  const answer = await response.json().catch(() => ({}));
  if (!response.ok) throw Object.assign(new Error(answer.error || `${url}: HTTP ${response.status}`), { status: response.status });
  return answer;
}

// The character's heading at a frame, as the kernel takes it (terminators.headings): forward is the hip
// axis (left minus right) turned to the ground's +Z side, averaged over +-0.25 s; the angle about +Y.
export function headingAt(positions, frame, leftHip, rightHip, fps) {
  // Python's round(): halves to even (at 10, 50, 90 fps Math.round would widen the window by a frame)
  const scaled = 0.25 * fps, floor = Math.floor(scaled);
  const half = scaled - floor === 0.5 ? floor + (floor % 2) : Math.round(scaled);
  let x = 0, z = 0;
  for (let f = Math.max(0, frame - half); f < Math.min(positions.length, frame + half + 1); f++) {
    const l = positions[f][leftHip], r = positions[f][rightHip];
    const fx = -(l[2] - r[2]), fz = l[0] - r[0];
    const size = Math.max(Math.hypot(fx, fz), 1e-12);
    x += fx / size;
    z += fz / size;
  }
  return Math.atan2(x, z);
}

export class PoseEditor {
  // ui: {mode, before, after, chain, undo, save, discard, status, notes}; viewer: {state(), setFrame(i), pause(),
  // reload(clipId), redrawPlot(), plotJoint(index)}
  constructor(ui, viewer, stage) {
    Object.assign(this, { ui, viewer, stage, clip: null, original: null, commands: [], pending: null,
                          selected: null, standard: {}, revision: 0, inFlight: null, shownScript: '[]',
                          lastNotes: [], drag: null });
    this.proxy = new THREE.Object3D(); // what the gizmo moves: placed at the selected joint
    stage.scene.add(this.proxy);
    this.gizmo = new TransformControls(stage.camera, stage.renderer.domElement);
    this.gizmo.setSize(0.8);
    stage.scene.add(this.gizmo.getHelper());
    this.gizmo.addEventListener('dragging-changed', (e) => (e.value ? this.dragStarted() : this.dragEnded()));
    this.gizmo.addEventListener('objectChange', () => this.dragged());
    const canvas = stage.renderer.domElement;
    let down = null;
    canvas.addEventListener('pointerdown', (e) => {
      down = this.gizmo.axis === null ? { x: e.clientX, y: e.clientY } : null; // on the gizmo: its drag
    });
    canvas.addEventListener('pointerup', (e) => {
      if (down && Math.hypot(e.clientX - down.x, e.clientY - down.y) <= CLICK_PX) this.pick(e.clientX, e.clientY);
      down = null;
    });
    ui.mode.addEventListener('change', () => this.place());
    for (const input of [ui.before, ui.after]) input.addEventListener('input', () => this.viewer.redrawPlot());
    ui.undo.addEventListener('click', () => this.undo());
    ui.discard.addEventListener('click', () => this.discard());
    ui.save.addEventListener('click', () => this.save());
    // the blend range chosen on the timeline's plot: a shift-click left of the frame shown sets where the
    // change starts (before), right of it where it ends (after)
    const plot = document.getElementById('plot');
    plot?.addEventListener('click', (e) => {
      if (!e.shiftKey || this.selected === null || !this.clip) return;
      const rect = plot.getBoundingClientRect();
      const frame = Math.round(((e.clientX - rect.left) / rect.width) * (this.clip.n_frames - 1));
      const seconds = (Math.abs(frame - this.viewer.state().frame) / this.clip.fps).toFixed(2);
      (frame < this.viewer.state().frame ? ui.before : ui.after).value = String(Math.min(10, seconds));
      this.viewer.redrawPlot();
    });
    this.show();
    this.say('click a joint of the character (or in the joint tree) to edit its pose');
  }

  // A clip opened (or saved and read again): its frames as stored are the original; no commands.
  open(clip, skeleton) {
    const state = this.viewer.state();
    Object.assign(this, { clip, original: state.frames, commands: [], pending: null, selected: null,
                          shownScript: '[]', lastNotes: [] });
    this.names = skeleton.hierarchy.joints.map((j) => j.name);
    this.parents = skeleton.hierarchy.joints.map((j) => j.parent);
    this.standard = Object.fromEntries(Object.entries(skeleton.joint_map).map(([s, name]) => [name, s]));
    this.hips = ['left_hip', 'right_hip'].map((s) => this.names.indexOf(skeleton.joint_map[s]));
    this.revision++;
    this.gizmo.detach();
    this.say('');
    this.show();
  }

  // Selects a joint (a skeleton index, or null): highlighted, the gizmo on it, its height plotted.
  select(index) {
    const state = this.viewer.state();
    if (index !== null) this.viewer.pause(); // a joint is edited at the frame shown: the clip stops there
    this.selected = index;
    state.highlighted = index;
    this.ui.notes.classList.toggle('editing', index !== null);
    if (index === null || !this.standard[this.names[index]]) {
      this.gizmo.detach();
      if (index !== null) this.say(`${this.names[index]} has no standard name in the skeleton's joint map: it cannot be edited`, true);
    } else {
      this.gizmo.attach(this.proxy);
      this.say(`${this.standard[this.names[index]]} (${this.names[index]}): drag the gizmo at frame ${state.frame}`);
    }
    this.viewer.setFrame(state.frame);
    if (index !== null) this.viewer.plotJoint(index);
    this.stage.render();
  }

  // The joint nearest the pointer on the canvas (within PICK_PX), else none.
  pick(clientX, clientY) {
    const state = this.viewer.state();
    if (!state.rig || this.drag) return;
    const rect = this.stage.renderer.domElement.getBoundingClientRect();
    const x = clientX - rect.left - rect.width / 2, y = clientY - rect.top - rect.height / 2;
    let best = null, nearest = PICK_PX;
    state.rig.worldPositions().forEach((p, i) => {
      const at = this.stage.offsetOf(p[0], p[1], p[2]);
      const d = Math.hypot(at.x - x, at.y - y);
      if (at.visible && d < nearest) { nearest = d; best = i; }
    });
    this.select(best);
  }

  mode() { return this.ui.mode.value; } // 'move' or 'turn'

  // The gizmo at the selected joint in the frame shown: its axes the heading frame (move) or the joint's
  // parent frame (turn).
  place() {
    const state = this.viewer.state();
    if (this.selected === null || this.drag || !state.rig) return;
    const node = state.rig.nodes[this.selected];
    node.getWorldPosition(this.proxy.position);
    if (this.mode() === 'turn') {
      const parent = this.parents[this.selected];
      if (parent >= 0) state.rig.nodes[parent].getWorldQuaternion(this.proxy.quaternion);
      else this.proxy.quaternion.identity();
    } else {
      this.proxy.quaternion.setFromAxisAngle(new THREE.Vector3(0, 1, 0), this.heading(state.frame));
    }
    this.gizmo.setMode(this.mode() === 'turn' ? 'rotate' : 'translate');
    this.gizmo.setSpace('local');
    this.proxy.updateMatrixWorld(true);
  }

  heading(frame) {
    return headingAt(this.viewer.state().frames.positions, frame, this.hips[0], this.hips[1], this.clip.fps);
  }

  frameChanged() { this.place(); }

  blend() {
    const seconds = (input) => Math.min(10, Math.max(0, Number(input.value) || 0));
    return { before: seconds(this.ui.before), after: seconds(this.ui.after) };
  }

  // The frames the next command changes (the blend range about the frame shown), for the plot's shading.
  blendRange() {
    if (this.selected === null || !this.clip) return null;
    const { before, after } = this.blend();
    const f = this.viewer.state().frame;
    return [Math.max(0, f - before * this.clip.fps), Math.min(this.clip.n_frames - 1, f + after * this.clip.fps)];
  }

  // The stored frames' world positions while the motion shown is edited (the plot draws them dashed).
  originalPositions() {
    return this.commands.length || this.pending ? this.original.positions : null;
  }

  dragStarted() {
    const state = this.viewer.state();
    this.viewer.pause();
    this.stage.controls.enabled = false;
    this.drag = { frame: state.frame, position: this.proxy.position.clone(), quaternion: this.proxy.quaternion.clone(),
                  joint: this.standard[this.names[this.selected]], mode: this.mode() };
  }

  // The command the gizmo's drag makes so far.
  command() {
    const d = this.drag;
    const time = d.frame / this.clip.fps;
    const { before, after } = this.blend();
    const round = (v) => Math.round(v * 1e6) / 1e6;
    if (d.mode === 'turn') {
      // the proxy turned from the parent's world rotation W to q: the joint's local rotation becomes
      // W^-1 q times the original, a rotation in the parent's frame
      const turn = d.quaternion.clone().invert().multiply(this.proxy.quaternion);
      if (turn.w < 0) turn.set(-turn.x, -turn.y, -turn.z, -turn.w);
      const half = Math.acos(Math.min(1, turn.w));
      const scale = half > 1e-9 ? (2 * half * 180) / Math.PI / Math.sin(half) : 0;
      return { op: 'rotate', joint: d.joint, time, rotation: [turn.x, turn.y, turn.z].map((v) => round(v * scale)),
               before, after };
    }
    // the move in the gizmo's axes, the heading frame at the frame
    const offset = this.proxy.position.clone().sub(d.position).applyQuaternion(d.quaternion.clone().invert());
    // chain: how many joints above it turn, 1 to 10 (empty: the default chain)
    const chain = this.ui.chain.value === '' ? null : Math.min(10, Math.max(1, Math.round(Number(this.ui.chain.value)) || 1));
    return { op: 'ik', joint: d.joint, time, offset: offset.toArray().map(round), before, after,
             ...(chain === null ? {} : { chain }) };
  }

  dragged() {
    if (!this.drag) return;
    this.pending = this.command();
    this.preview();
  }

  dragEnded() {
    this.stage.controls.enabled = true;
    if (!this.drag) return;
    if (this.pending) this.commands.push(this.command());
    this.pending = null;
    this.drag = null;
    this.preview();
    this.show();
  }

  undo() {
    if (!this.commands.length) return;
    this.commands.pop();
    this.preview();
    this.show();
  }

  discard() {
    this.commands = [];
    this.pending = null;
    this.preview();
    this.show();
    this.say('discarded: the clip as stored');
  }

  script() { return this.pending ? [...this.commands, this.pending] : [...this.commands]; }

  // The edited motion from the server: one request at a time; when it answers, the newest script is sent
  // if it changed meanwhile (the latest wins, none queue).
  async preview() {
    if (this.inFlight) return;
    const script = this.script();
    const text = JSON.stringify(script);
    if (text === this.shownScript) return this.show();
    if (!script.length) { this.showFrames(null, text); return; }
    const clip = this.clip;
    this.inFlight = text;
    try {
      const answer = await send(`/api/clips/${clip.id}/edit-preview`, 'POST', { commands: script });
      if (clip === this.clip) this.showFrames(answer, text);
    } catch (error) {
      if (clip === this.clip) {
        this.say(`preview: ${error.message}`, true);
        // the server refused the script (400): its last command is not kept; a busy server (503) or a
        // lost connection keeps it, and the next change asks again
        if (error.status === 400 && this.commands.length && text === JSON.stringify(this.commands)) this.commands.pop();
        this.shownScript = text; // not sent again unless it changes
      }
    } finally {
      this.inFlight = null;
    }
    if (clip === this.clip && JSON.stringify(this.script()) !== this.shownScript) this.preview();
  }

  // The preview's frames over the stored ones (null: the stored frames).
  showFrames(answer, text) {
    const state = this.viewer.state();
    if (!answer) {
      state.frames = this.original;
      this.lastNotes = [];
    } else {
      const merged = { rotations: [...this.original.rotations], translations: [...this.original.translations],
                       positions: [...this.original.positions] };
      for (const key of ['rotations', 'translations', 'positions']) merged[key].splice(answer.start, answer.count, ...answer[key]);
      state.frames = merged;
      this.lastNotes = answer.notes.filter((n) => n);
    }
    this.shownScript = text;
    this.revision++;
    this.viewer.setFrame(state.frame);
    this.show();
  }

  // The script so far, its notes (an ik target out of reach: the nearest point and its distance) and the
  // buttons that apply.
  show() {
    const n = this.commands.length;
    this.ui.undo.disabled = !n;
    this.ui.save.disabled = !n;
    this.ui.discard.disabled = !n;
    const lines = this.lastNotes.map((note) => {
      if (note.message) return note.message;
      if (note.op === 'ik') return `command ${note.command}: ik ${note.joint} at frame ${note.frame}: met (${(note.distance_m * 1000).toFixed(2)} mm), frames ${note.frames[0]}-${note.frames[1]}`;
      return `command ${note.command}: rotate ${note.joint} at frame ${note.frame}, frames ${note.frames[0]}-${note.frames[1]}`;
    });
    this.ui.notes.textContent = n ? `${n} command${n > 1 ? 's' : ''}\n${lines.join('\n')}` : '';
    this.ui.notes.classList.toggle('error', this.lastNotes.some((note) => note.message));
  }

  say(text, isError = false) {
    this.ui.status.textContent = text;
    this.ui.status.title = text; // the whole of it where the line cuts it short
    this.ui.status.classList.toggle('error', isError);
  }

  // The script stored under a new name and applied to the clip: a new version, which the page then plays.
  async save() {
    if (!this.commands.length || !this.clip) return;
    if (!token.get()) return this.say('saving needs a loader token: paste one under "Access token"', true);
    const clip = this.clip;
    // the edits were made on the version shown: saved only onto that one (another tab may have saved since)
    const current = await fetch(`/api/clips/${clip.id}`, { headers: token.headers() }).then((r) => r.json()).catch(() => ({}));
    if (current.version !== undefined && current.version !== clip.version) {
      return this.say(`save: clip ${clip.id} has a newer version (${current.version}) than the one edited (${clip.version}): discard and edit it again`, true);
    }
    const name = `pose edit of clip ${clip.id} ${new Date().toISOString()}`;
    const path = `/api/edit-scripts/${encodeURIComponent(name)}`;
    this.say('saving…');
    try {
      await send(path, 'PUT', { commands: this.commands, comment: `the web view's pose editor, on clip ${clip.id} version ${clip.version}` });
      const applied = await send(`${path}/apply`, 'POST', { clips: [clip.id] });
      const made = applied.results[0];
      const notes = (made.notes || []).filter((note) => note.message).map((note) => note.message);
      await this.viewer.reload(clip.id);
      this.saved = { name, version: made.version };
      this.say(`saved as version ${made.version} (edit script "${name}")${notes.length ? `: ${notes.join('; ')}` : ''}`);
    } catch (error) {
      this.say(`save: ${error.message}`, true);
    }
  }
}
