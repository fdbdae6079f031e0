// Avatar mode: the server walks an Avatar toward the goals clicked here and streams its poses over a
// WebSocket at the source rate; this page poses the figure, draws its trail and the goals, and tunes the
// selection. window.modbAvatar is what tests (and the console) read.
import { loadCharacter, saveFile } from './character.js';
import { Course } from './course.js';
import { Rig } from './rig.js';
import { Stage } from './stage.js';
import { token } from './token.js';
import { Tuning } from './tuning.js';

const $ = (id) => document.getElementById(id);
const KEEP_CHOICES = 1000;
const KEEP_FRAMES = 3000;
const KEEP_MESSAGES = 20000; // all but frames, for checks: the older half goes when full
const CLICK_SLOP_PX = 5; // a pointer that moved more than this between press and release dragged the view

const stage = new Stage($('view'));
const course = new Course(stage.scene);
stage.look([0, 7, -7], [0, 0, 3]); // from above and behind the avatar, which starts at the origin facing +Z
const state = {
  connected: false, settings: null, rig: null, character: null, framed: false, frames: 0, frame: null,
  choices: [], goals: [], goalIndex: 0, messages: [], closed: null, pelvisAt: {},
};

function status(text, isError = false) {
  $('status').textContent = text;
  $('status').classList.toggle('error', isError);
}

const socket = new WebSocket(`${location.protocol === 'https:' ? 'wss' : 'ws'}://${location.host}/ws/avatar`);
const send = (message) => socket.send(JSON.stringify(message));
// The tab's token (token.js), first thing: a server started with --require-token needs it, others ignore it.
socket.addEventListener('open', () => { if (token.get()) send({ type: 'auth', token: token.get() }); });
const tuning = new Tuning($('tuning'), send);
let resolveReady;
const ready = new Promise((resolve) => { resolveReady = resolve; });

function showGoals(goals, index) {
  Object.assign(state, { goals, goalIndex: index });
  course.setGoals(goals, index, state.settings ? state.settings.arrival_radius : 0.5);
}

const handlers = {
  ready(m) {
    state.connected = true;
    state.settings = m.settings;
    tuning.build(m);
    status('click the ground to set a goal');
    resolveReady(true);
  },
  skeleton(m) {
    state.rig = new Rig(m.hierarchy, m.pelvis);
    state.framed = false;
    state.character = null;
    stage.setCharacter(null);
    stage.showSkeleton(true); // until the character has loaded, or where the skeleton has none
    loadCharacter(m.id, m.hierarchy.translated).then((character) => {
      if (state.rig === null || state.rig.joints !== m.hierarchy.joints) return; // a newer skeleton came
      state.character = character;
      stage.setCharacter(character);
      stage.showSkeleton($('show-skeleton').checked);
    }).catch(() => {});
  },
  note(m) { status(m.message); },
  file(m) {
    saveFile(m.name, m.media_type, m.data);
    status(m.sources ? `saved ${m.name}: ${m.sources}` : `saved ${m.name}`);
  },
  frame(m) {
    if (!state.rig) return;
    state.rig.pose(m.rotations, m.translations);
    if (state.character) state.character.pose(m.rotations, m.translations);
    const positions = state.rig.worldPositions();
    const pelvis = positions[state.rig.pelvis];
    state.rig.abovePelvis.forEach((k) => { positions[k] = pelvis; }); // no sphere off the body (Bandai's joint_Root)
    if (!state.framed) {
      stage.setFigure(positions.length, pelvis, true);
      state.framed = true;
    }
    stage.draw(state.rig.boneSegments(), positions, state.rig.pelvis, null, $('follow').checked);
    course.addTrail(pelvis[0], pelvis[2]);
    state.frames += 1;
    state.frame = { index: m.index, step: m.step, pelvis };
    state.pelvisAt[m.index] = pelvis; // the recent frames' pelvis, for checks
    delete state.pelvisAt[m.index - KEEP_FRAMES];
  },
  choice(m) {
    state.choices.push(m);
    if (state.choices.length > KEEP_CHOICES) state.choices.shift();
    tuning.showReadout(m);
    showGoals(m.goals, m.goal_index);
    if ($('status').textContent.startsWith('click')) status('');
  },
  goals(m) { showGoals(m.goals, m.goal_index); },
  settings(m) {
    state.settings = m.settings;
    tuning.show(m.settings);
    showGoals(state.goals, state.goalIndex);
  },
  refused(m) {
    status(m.message, true);
    if (m.settings) tuning.show(m.settings);
  },
  stopped(m) { status(m.message, true); },
};

socket.addEventListener('message', (event) => {
  const message = JSON.parse(event.data);
  if (message.type !== 'frame') state.messages.push(message);
  if (state.messages.length > KEEP_MESSAGES) state.messages.splice(0, state.messages.length - KEEP_MESSAGES / 2);
  handlers[message.type](message);
});
socket.addEventListener('close', (event) => {
  state.connected = false;
  state.closed = { code: event.code, reason: event.reason };
  status(`disconnected from the server${event.reason ? `: ${event.reason}` : ''}; reload to reconnect`, true);
  resolveReady(false);
});

// A click (not a drag of the view) on the ground sets the goal; with shift, adds a waypoint after the others.
let pressed = null;
const canvas = stage.renderer.domElement;
canvas.addEventListener('pointerdown', (e) => { pressed = [e.clientX, e.clientY]; });
canvas.addEventListener('click', (e) => {
  if (!state.connected || !pressed || Math.hypot(e.clientX - pressed[0], e.clientY - pressed[1]) > CLICK_SLOP_PX) return;
  const point = stage.groundPointAt(e.clientX, e.clientY);
  if (point) send({ type: 'goal', x: point.x, z: point.z, add: e.shiftKey });
});

$('show-skeleton').addEventListener('change', () => stage.showSkeleton($('show-skeleton').checked || !state.character));
for (const format of ['bvh', 'glb']) {
  $(`download-${format}`).addEventListener('click', () => {
    if (!state.connected) return;
    status('preparing the file…');
    send({ type: 'download', format });
  });
}

function tick() {
  stage.render();
  requestAnimationFrame(tick);
}
requestAnimationFrame(tick);

window.modbAvatar = {
  state,
  stage,
  course,
  ready,
  trail: () => course.trail,
  // Where the ground point (x, z) shows, in pixels from the canvas centre (for a pointer to click it).
  offsetOf: (x, z) => stage.offsetOf(x, 0, z),
};
