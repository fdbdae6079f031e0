// Avatar mode: the server walks an Avatar toward the goals clicked here and streams its poses over a
// WebSocket at the source rate; this page poses the figure, draws its trail and the goals, and tunes the
// selection. The avatar walks by motion matching (snippets) or on a graph of models (the mode selector);
// in both it stands at the origin from the start. On a graph of models it also performs the graph's actions (a hand
// raised to a target placed in the air). window.modbAvatar is what tests (and the console) read.
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
const KEEP_POSES = 600; // the last frames' joint positions and arrival times: how fast a click is answered

const stage = new Stage($('view'));
const course = new Course(stage.scene);
stage.look([0, 7, -7], [0, 0, 3]); // from above and behind the avatar, which starts at the origin facing +Z
const state = {
  connected: false, settings: null, rig: null, character: null, framed: false, frames: 0, frame: null,
  choices: [], goals: [], goalIndex: 0, messages: [], closed: null, pelvisAt: {},
  mode: { models: null, seed: null }, steps: [], poses: [], clicks: [], actions: [],
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

function fixed(value, digits) {
  return value === null || value === undefined ? '-' : Number(value).toFixed(digits);
}
const cm = (metres) => `${fixed(100 * metres, 1)} cm`;

// The mode in force, as the server says: motion matching (models null) or a graph of models and its seed.
function showMode(mode) {
  state.mode = mode;
  const models = mode.models !== null;
  $('mode').value = mode.models || '';
  if (models) $('seed').value = mode.seed;
  $('seed-choice').style.display = models ? '' : 'none';
  if (!models) showActions([]);
  $('model-readouts').hidden = !models;
  document.querySelectorAll('#tuning .snippets-only').forEach((section) => { section.hidden = models; });
}

function chooseMode() {
  const models = $('mode').value || null;
  const seed = Math.max(0, Math.floor(Number($('seed').value) || 0));
  status(models ? `loading the graph of models ${models}…` : 'back to motion matching…');
  send({ type: 'mode', models, seed });
}

// The graph's actions (its action nodes), offered beside the mode; none in motion matching.
// The graph's actions in the selector; those that repeat (a wave) also take how long.
let repeatedActions = [];
function showActions(names, repeated = []) {
  repeatedActions = repeated;
  const chosen = $('action').value;
  $('action').replaceChildren(Object.assign(document.createElement('option'), {
    value: '', textContent: 'none: shift-click adds a waypoint',
  }), ...names.map((name) => Object.assign(document.createElement('option'), { value: name, textContent: name })));
  if (names.includes(chosen)) $('action').value = chosen;
  $('action-choice').style.display = names.length ? '' : 'none';
  $('height-choice').style.display = names.length ? '' : 'none';
  showSecondsChoice();
}

function showSecondsChoice() {
  $('seconds-choice').style.display = repeatedActions.includes($('action').value) ? '' : 'none';
}

// A step of the walk on models, as it starts to play: its primitive, the search, its constraint error. An action's
// piece: the hand's error at the keyframe, after the tree search, the refinement and IK (where the server has it).
function showStep(step) {
  const r = step.readout;
  $('step').textContent = `${step.step} (${step.goal === null ? 'after the last goal' : `goal ${step.goal}`})`;
  $('primitive').textContent = `${step.node} (${step.model})`;
  $('step-candidates').textContent = String(step.candidates);
  $('error').textContent = cm(step.error_m);
  $('error-compare').textContent = `${cm(step.tree_error_m)} / ${cm(step.random_error_m)}`;
  $('error-medians').textContent = `${cm(r.error_m_median)}; ${cm(r.tree_error_m_median)} / ${cm(r.random_error_m_median)} (${r.steps} steps)`;
  const a = step.action;
  $('action-row').hidden = !a;
  if (a) {
    const ik = a.ik_error_m === undefined ? 'no IK' : cm(a.ik_error_m);
    $('action-errors').textContent = `${cm(a.tree_error_m)} / ${cm(a.refined_error_m)} / ${ik}${a.cut ? ' (cut)' : ''}`;
  }
}

function showGoals(goals, index, actions) {
  Object.assign(state, { goals, goalIndex: index });
  course.setGoals(goals, index, state.settings ? state.settings.arrival_radius : 0.5);
  if (actions) {
    state.actions = actions;
    course.setActions(actions);
  }
}

const handlers = {
  ready(m) {
    state.connected = true;
    state.settings = m.settings;
    tuning.build(m);
    // the demo's graph of models comes first (the server lists it so), named as the demo's
    const demo = (name) => (name === m.demo_model_graph ? " (modb demo's)" : '');
    $('mode').append(...m.model_graphs.map((name) => Object.assign(document.createElement('option'), {
      value: name, textContent: `graph of models: ${name}${demo(name)}`,
    })));
    showMode(m.mode);
    m.standing.forEach((message) => handlers[message.type](message)); // the avatar, standing at the origin
    status('click the ground to set a goal');
    resolveReady(true);
    // /avatar?models=NAME: on that graph of models from the start (the demo's last lines give the link)
    const asked = new URLSearchParams(location.search).get('models');
    if (asked && m.model_graphs.includes(asked)) {
      $('mode').value = asked;
      chooseMode();
    } else if (asked) status(`no graph of models "${asked}" here: walking by motion matching`, true);
  },
  mode(m) {
    showMode({ models: m.models, seed: m.seed });
    state.settings = m.settings;
    if (m.models === null) tuning.show(m.settings);
    // a new avatar, standing at the origin: the last one's trail, goals and frames go
    course.trail = [];
    course.trailLine.geometry.setDrawRange(0, 0);
    state.pelvisAt = {};
    state.steps = [];
    document.querySelectorAll('#model-readouts td').forEach((cell) => { cell.textContent = '-'; });
    $('action-row').hidden = true;
    showActions(m.actions || [], m.repeated_actions || []);
    showGoals([], 0, []);
    status(m.models === null ? 'click the ground to set a goal (motion matching)'
      : `on the graph of models ${m.models} (seed ${m.seed}): click the ground to set a goal`);
  },
  step(m) {
    const last = state.steps[state.steps.length - 1];
    if (last && last.step === m.step) state.steps.pop(); // the step re-planned toward a new goal
    state.steps.push(m);
    if (state.steps.length > KEEP_CHOICES) state.steps.shift();
    showStep(m);
    showGoals(m.goals, m.goal_index, m.actions);
    if ($('status').textContent.startsWith('on the graph')) status('');
  },
  skeleton(m) {
    if (state.rig && state.skeletonId === m.id) return; // posed already (the standing avatar's)
    state.skeletonId = m.id;
    state.rig = new Rig(m.hierarchy, m.pelvis);
    state.lastPose = null; // the frames of this skeleton from here
    state.framed = false;
    state.character = null;
    stage.setCharacter(null);
    stage.showSkeleton(true); // until the character has loaded, or where the skeleton has none
    loadCharacter(m.id, m.hierarchy.translated).then((character) => {
      if (state.rig === null || state.rig.joints !== m.hierarchy.joints) return; // a newer skeleton came
      state.character = character;
      // posed as the rig now stands (the standing avatar waits for a click: no frame may come soon)
      if (state.lastPose) character.pose(...state.lastPose);
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
    state.lastPose = [m.rotations, m.translations];
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
    // (with the pose as sent: a check's own kinematics)
    state.poses.push({ t: performance.now(), index: m.index, positions, rotations: m.rotations, translations: m.translations });
    if (state.poses.length > KEEP_POSES) state.poses.shift();
  },
  choice(m) {
    state.choices.push(m);
    if (state.choices.length > KEEP_CHOICES) state.choices.shift();
    tuning.showReadout(m);
    showGoals(m.goals, m.goal_index);
    if ($('status').textContent.startsWith('click')) status('');
  },
  goals(m) { showGoals(m.goals, m.goal_index, m.actions); },
  settings(m) {
    state.settings = m.settings;
    tuning.show(m.settings);
    showGoals(state.goals, state.goalIndex);
  },
  refused(m) {
    status(m.message, true);
    if (m.settings) tuning.show(m.settings);
    if (m.mode) showMode(m.mode); // a mode refused: the one in force goes on
  },
  stopped(m) { status(m.message, true); },
};

socket.addEventListener('message', (event) => {
  const message = JSON.parse(event.data);
  if (message.type !== 'frame') state.messages.push(Object.assign(message, { receivedAt: performance.now() }));
  if (state.messages.length > KEEP_MESSAGES) state.messages.splice(0, state.messages.length - KEEP_MESSAGES / 2);
  handlers[message.type](message);
});
socket.addEventListener('close', (event) => {
  state.connected = false;
  state.closed = { code: event.code, reason: event.reason };
  status(`disconnected from the server${event.reason ? `: ${event.reason}` : ''}; reload to reconnect`, true);
  resolveReady(false);
});

// A click (not a drag of the view) on the ground sets the goal; with shift, adds a waypoint after the others, or, with
// an action chosen (on a graph of models), that action with its target above the point at the target height.
let pressed = null;
const canvas = stage.renderer.domElement;
canvas.addEventListener('pointerdown', (e) => { pressed = [e.clientX, e.clientY]; });
canvas.addEventListener('click', (e) => {
  if (!state.connected || !pressed || Math.hypot(e.clientX - pressed[0], e.clientY - pressed[1]) > CLICK_SLOP_PX) return;
  const point = stage.groundPointAt(e.clientX, e.clientY);
  if (!point) return;
  const action = e.shiftKey && state.mode.models !== null ? $('action').value : '';
  if (action) {
    const y = Number($('target-height').value);
    const seconds = repeatedActions.includes(action) ? Number($('action-seconds').value) : 0;
    state.clicks.push({ t: performance.now(), x: point.x, z: point.z, add: true, action, y });
    send({ type: 'action', primitive: action, x: point.x, y, z: point.z, ...(seconds > 0 ? { seconds } : {}) });
    return;
  }
  state.clicks.push({ t: performance.now(), x: point.x, z: point.z, add: e.shiftKey });
  send({ type: 'goal', x: point.x, z: point.z, add: e.shiftKey });
});

$('mode').addEventListener('change', chooseMode);
$('action').addEventListener('change', showSecondsChoice);
$('seed').addEventListener('change', () => { if (state.mode.models !== null) chooseMode(); });
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
  send, // a message to the server, on this page's socket
  stage,
  course,
  ready,
  trail: () => course.trail,
  // Where the ground point (x, z) shows, in pixels from the canvas centre (for a pointer to click it).
  offsetOf: (x, z) => stage.offsetOf(x, 0, z),
};
