// The Models panel: the statistical motion models (`modb model build`) per collection. Choosing one shows
// its summary and the share of variance each spatial PCA component keeps, and plays N samples in a row in
// front of N of its training examples (the DFKI paper's figure of training data beside samples) on the
// clip's stage, which it borrows while shown: the clip pauses, and its controls bring it back.
// window.modbModels is what tests (and the console) read.
import * as THREE from 'three';
import { loadCharacter } from './character.js';
import { getJSON, motionModels } from './panels.js';

const SPACING = 0.8; // metres between figures in a row: shoulders are ~0.4 m wide, a step swings in z
const ROW_GAP = 3.5; // metres between the rows: a step travels up to ~0.8 m forward (+Z)
const ROWS = { // the back row shows higher on the screen: the data above, the model's samples below
  examples: { z: -ROW_GAP, colour: 0x7d93b2, label: 'training examples' },
  samples: { z: 0, colour: 0xe8892b, label: 'samples' },
};
const LABEL_WIDTH = 3; // metres: a row's name, left of it
const MARGIN = 0.1; // of the view's half width and height, left free around the figures
const VIEW_FROM = new THREE.Vector3(0, 0.75, 1).normalize(); // in front, above

const $ = (id) => document.getElementById(id);
const say = (error) => { $('model-status').textContent = error.message; };
const viewer = window.modbViewer; // viewer.js runs first: module scripts run in document order
const stage = viewer.stage;
const NONE = { samples: 0, examples: 0 };
const state = { model: null, figures: [], group: null, time: 0, shown: NONE, variancePlotted: 0 };
let latest = 0; // only the last request shown, however the answers arrive

// One figure, `offset` from where its motion starts: the skeleton's skinned character, tinted; without one
// (no bone long enough to draw) its bones as lines from the server's positions.
class Figure {
  constructor(motion, character, colour, offset) {
    Object.assign(this, { motion, character, offset, frame: 0 });
    if (character) {
      character.object.traverse((o) => {
        if (o.isMesh) { o.material = o.material.clone(); o.material.color.setHex(colour); } // the clones share one
      });
      this.object = character.object;
    } else {
      const geometry = new THREE.BufferGeometry();
      const ends = new Float32Array(motion.positions[0].length * 6);
      geometry.setAttribute('position', new THREE.BufferAttribute(ends, 3));
      this.object = new THREE.LineSegments(geometry, new THREE.LineBasicMaterial({ color: colour }));
      this.object.frustumCulled = false;
    }
    this.object.position.copy(offset);
  }

  show(frame, parents) {
    this.frame = frame;
    const m = this.motion;
    if (this.character) return this.character.pose(m.rotations[frame], m.translations[frame]);
    const buffer = this.object.geometry.attributes.position;
    const p = m.positions[frame];
    let n = 0;
    parents.forEach((up, j) => { if (up >= 0) { buffer.setXYZ(n++, ...p[up]); buffer.setXYZ(n++, ...p[j]); } });
    buffer.needsUpdate = true;
    this.object.geometry.setDrawRange(0, n);
  }

  // Joint world positions as drawn (the character's bones, else the joints the lines join).
  joints() {
    if (this.character) return this.character.bones.map((b) => b.getWorldPosition(new THREE.Vector3()).toArray());
    return this.motion.positions[this.frame].map((p) => new THREE.Vector3(...p).add(this.offset).toArray());
  }
}

function label(text, colour, at) {
  const canvas = document.createElement('canvas');
  canvas.width = 1024;
  canvas.height = 128;
  const g = canvas.getContext('2d');
  g.font = 'bold 84px system-ui, sans-serif';
  g.fillStyle = new THREE.Color(colour).multiplyScalar(0.8).getStyle(); // darker: legible on the grid
  g.textAlign = 'right';
  g.fillText(text, 1010, 96);
  const material = new THREE.SpriteMaterial({ map: new THREE.CanvasTexture(canvas), depthTest: false });
  const sprite = new THREE.Sprite(material);
  sprite.scale.set(LABEL_WIDTH, LABEL_WIDTH / 8, 1);
  sprite.position.copy(at);
  // where the text starts (the camera frames the text, not the canvas's empty left)
  sprite.userData.left = at.x + LABEL_WIDTH / 2 - (g.measureText(text).width / canvas.width) * LABEL_WIDTH;
  return sprite;
}

// The bars: the share of variance per spatial component (scaled to the first), on whole pixels and at
// least one pixel tall (every component kept shows); the line: the cumulative share on a 0-100% scale.
// Returns how many bars it drew.
function plotVariance(canvas, shares) {
  const scale = Math.max(1, devicePixelRatio); // a low-density screen still gets a pixel per bar and gap
  const w = (canvas.width = Math.round(canvas.clientWidth * scale));
  const h = (canvas.height = Math.round(canvas.clientHeight * scale));
  const g = canvas.getContext('2d');
  g.clearRect(0, 0, w, h);
  if (!shares.length) return 0;
  const step = w / shares.length;
  const top = Math.max(...shares);
  g.fillStyle = '#2f6fc4';
  shares.forEach((s, i) => {
    const height = Math.max(1, Math.round((h * s) / top));
    g.fillRect(Math.round(i * step), h - height, Math.max(1, Math.round(step * 0.7)), height);
  });
  g.strokeStyle = '#e8892b';
  g.lineWidth = 2 * scale;
  g.beginPath();
  let sum = 0;
  shares.forEach((s, i) => { sum += s; g[i ? 'lineTo' : 'moveTo']((i + 0.35) * step, h * (1 - sum)); });
  g.stroke();
  return shares.length;
}

function summary(m) {
  return [
    `${m.primitive} of ${m.collection}: ${m.examples} examples (${m.mirrored_examples} mirrored)`,
    `${m.n_frames} frames at ${m.fps} fps; ${m.spatial_explained.length} spatial`
      + ` + ${m.temporal_explained.length} temporal components keep`
      + ` ${Math.round(100 * m.settings.variance_kept)}% of the variance`,
    `${m.mixture.components} ${m.mixture.covariance} Gaussians`
      + (m.tree ? `; tree of ${m.tree.leaves} leaves` : ''),
  ].join('\n');
}

function staleMark(reason, text) {
  const mark = document.createElement('em');
  mark.className = 'stale';
  mark.textContent = text;
  mark.title = reason;
  return mark;
}

async function choose(entry) {
  const load = ++latest;
  $('model-detail').hidden = false;
  $('model-summary').textContent = `loading ${entry.name} v${entry.version}…`;
  const model = await getJSON(`/api/motion-models/${encodeURIComponent(entry.name)}?version=${entry.version}`);
  if (load !== latest) return;
  state.model = model;
  $('model-summary').textContent = summary(model);
  if (model.stale) $('model-summary').append(staleMark(model.stale, `\nstale: ${model.stale}`));
  state.variancePlotted = plotVariance($('model-variance'), model.spatial_explained);
  await showMotions();
}

// The model's samples (n, seed) in the front row and n of its training examples behind, all looping.
async function showMotions() {
  const m = state.model;
  if (!m) return;
  const load = ++latest;
  const n = Math.max(1, Math.min(50, Number($('model-n').value) || 10));
  const seed = Math.max(0, Number($('model-seed').value) || 0);
  const name = encodeURIComponent(m.name);
  $('model-status').textContent = 'sampling…';
  const [samples, examples] = await Promise.all([
    getJSON(`/api/motion-models/${name}/samples?n=${n}&seed=${seed}&version=${m.version}`),
    getJSON(`/api/motion-models/${name}/examples?n=${n}&version=${m.version}`),
  ]);
  const figures = [];
  for (const [kind, answer] of [['samples', samples], ['examples', examples]]) {
    const row = ROWS[kind];
    for (const [k, motion] of answer[kind].entries()) {
      const offset = new THREE.Vector3((k - (answer[kind].length - 1) / 2) * SPACING, 0, row.z);
      const character = await loadCharacter(m.skeleton_id, answer.translated).catch(() => null);
      figures.push(Object.assign(new Figure(motion, character, row.colour, offset), { kind, index: k }));
    }
  }
  if (load !== latest) return;
  enter(figures, samples);
  $('model-status').textContent = `${samples.samples.length} samples (seed ${seed}),`
    + ` ${examples.examples.length} training examples`;
}

function enter(figures, answer) {
  clear();
  viewer.pause();
  stage.setCharacter(null); // the clip's figure goes while the model's are shown
  stage.showSkeleton(false);
  stage.highlight.visible = false;
  stage.axes.visible = false;
  $('annotations').hidden = true; // the clip's editor, for a clip not shown: the stage takes its room
  stage.resize(); // now: the camera's aspect frames the figures below
  state.group = new THREE.Group();
  figures.forEach((f) => { state.group.add(f.object); f.show(0, answer.parents); });
  const left = Math.min(...figures.map((f) => f.offset.x)) - 0.5 - LABEL_WIDTH / 2;
  const labels = Object.values(ROWS).map((r) => label(r.label, r.colour, new THREE.Vector3(left, 1, r.z)));
  state.group.add(...labels);
  stage.scene.add(state.group);
  const count = (kind) => figures.filter((f) => f.kind === kind).length;
  Object.assign(state, { figures, parents: answer.parents, fps: answer.fps, time: 0,
                         shown: { samples: count('samples'), examples: count('examples') } });
  frame(figures, labels);
  $('model-close').hidden = false;
}

// The camera looks along VIEW_FROM and stands as near as shows every joint of every figure over every
// frame, and the row labels: on each screen axis a point p needs |p.axis - c| <= tan(half fov) *
// (D - p.VIEW_FROM) (D: the camera's distance along VIEW_FROM, c: its offset on that axis); the least D
// and its c follow from the largest p.VIEW_FROM +- p.axis / tan.
function frame(figures, labels) {
  const back = VIEW_FROM.clone().negate();
  const right = new THREE.Vector3().crossVectors(back, new THREE.Vector3(0, 1, 0)).normalize();
  const up = new THREE.Vector3().crossVectors(right, back);
  const tanV = Math.tan(THREE.MathUtils.degToRad(stage.camera.fov / 2)) * (1 - MARGIN);
  const tanH = tanV * stage.camera.aspect;
  const most = { h: [-Infinity, -Infinity], v: [-Infinity, -Infinity] };
  const fit = (p) => {
    const a = p.dot(VIEW_FROM);
    const x = p.dot(right) / tanH;
    const y = p.dot(up) / tanV;
    most.h = [Math.max(most.h[0], a + x), Math.max(most.h[1], a - x)];
    most.v = [Math.max(most.v[0], a + y), Math.max(most.v[1], a - y)];
  };
  const p = new THREE.Vector3();
  for (const f of figures) {
    f.motion.positions.forEach((pose) => pose.forEach((q) => fit(p.fromArray(q).add(f.offset))));
  }
  labels.forEach((l) => {
    fit(p.set(l.userData.left, l.position.y, l.position.z));
    fit(p.set(l.position.x + LABEL_WIDTH / 2, l.position.y, l.position.z));
  });
  const distance = Math.max(most.h[0] + most.h[1], most.v[0] + most.v[1]) / 2;
  const target = right.multiplyScalar((tanH * (most.h[0] - most.h[1])) / 2)
    .add(up.multiplyScalar((tanV * (most.v[0] - most.v[1])) / 2));
  stage.look(target.clone().addScaledVector(VIEW_FROM, distance).toArray(), target.toArray());
}

// The model's figures off the stage (their tinted materials and label textures are theirs alone).
function clear() {
  if (!state.group) return;
  stage.scene.remove(state.group);
  state.group.traverse((o) => { if (o.material) { o.material.map?.dispose(); o.material.dispose(); } });
  Object.assign(state, { group: null, figures: [], shown: NONE });
  $('model-close').hidden = true;
  $('annotations').hidden = false;
  stage.resize();
}

// Back to the clip: its figure, its skeleton setting and a view of it (play=true also plays it).
function leave(play) {
  if (!state.group) return;
  clear();
  const v = viewer.state;
  stage.setCharacter(v.character);
  stage.showSkeleton($('show-skeleton').checked || !v.character);
  if (v.rig) {
    const at = viewer.jointWorldPositions()[v.rig.pelvis];
    stage.look([at[0] + 2.5, Math.max(at[1], 0.5) + 0.9, at[2] + 3.5], [at[0], Math.max(at[1], 0.5), at[2]]);
    viewer.setFrame(v.frame);
    if (play) viewer.play();
  }
}

let last = performance.now();
function tick(now) {
  const dt = (now - last) / 1000;
  last = now;
  if (state.group && stage.character) clear(); // a clip loaded meanwhile (chosen, uploaded) has the stage
  if (state.group) {
    state.time += dt * Number($('speed').value); // the footer's speed applies to these too
    const frame = Math.floor(state.time * state.fps);
    // each loops at its own length (the examples' differ; samples' too, by their time warping)
    state.figures.forEach((f) => f.show(frame % f.motion.n_frames, state.parents));
  }
  requestAnimationFrame(tick);
}

function listModels(models) {
  const byCollection = new Map();
  models.forEach((m) => byCollection.set(m.collection, [...(byCollection.get(m.collection) || []), m]));
  $('models').replaceChildren(...[...byCollection.keys()].sort().map((collection) => {
    const li = document.createElement('li');
    li.textContent = collection;
    const ul = document.createElement('ul');
    ul.append(...byCollection.get(collection).map((m) => {
      const item = document.createElement('li');
      const span = document.createElement('span');
      span.textContent = `${m.name} v${m.version} · ${m.primitive} · ${m.examples} examples`;
      Object.assign(span.dataset, { model: m.name, version: m.version });
      span.title = `built ${m.created_at}; ${m.components} mixture components`
        + (m.has_tree ? ', with a tree' : '');
      span.addEventListener('click', () => {
        $('models').querySelectorAll('span.selected').forEach((s) => s.classList.remove('selected'));
        span.classList.add('selected');
        choose(m).catch(say);
      });
      if (m.stale) span.append(' ', staleMark(m.stale, 'stale'));
      item.append(span);
      return item;
    }));
    li.append(ul);
    return li;
  }));
  $('model-count').textContent = `(${models.length})`;
  $('models-panel').hidden = !models.length; // none in the database (or it is too old for them)
}

$('model-show').addEventListener('click', () => showMotions().catch(say));
$('model-close').addEventListener('click', () => leave(true));
// The clip's playback controls bring the clip back (capture: before they act on it).
['play', 'prev', 'next'].forEach((id) => $(id).addEventListener('click', () => leave(false), true));
$('timeline').addEventListener('input', () => leave(false), true);
window.addEventListener('keydown', (e) => {
  const playback = [' ', 'ArrowLeft', 'ArrowRight'].includes(e.key); // viewer.js's keys
  if (playback && !['INPUT', 'SELECT'].includes(e.target.tagName)) leave(false);
}, true);

window.modbModels = {
  get shown() { return { ...state.shown }; },
  get variancePlotted() { return state.variancePlotted; },
  // per figure: its row, its index, the frame shown, its offset and the joints' world positions as drawn
  figures: () => state.figures.map((f) => ({ kind: f.kind, index: f.index, frame: f.frame,
                                             offset: f.offset.toArray(), joints: f.joints() })),
  ready: motionModels().then(listModels, () => listModels([])).then(() => true),
};
requestAnimationFrame(tick);
