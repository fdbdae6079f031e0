// Browse the motion database and play a clip at its own rate. The page opens playing the clip its address
// names (?clip=ID), else the first clip (firstClip below), else says how to load data. window.modbViewer is
// what tests (and the console) use to read the page's state; the page itself only uses the JSON endpoints.
import { loadCharacter } from './character.js';
import { Rig } from './rig.js';
import { Stage } from './stage.js';
import { getJSON, markSelected, showClips, showCollections, showSkeleton } from './panels.js';
import { AnnotationEditor } from './annotations.js';
import { PoseEditor } from './pose_editor.js';
import { token, tokenPanel } from './token.js';
import { uploadPanel } from './uploads.js';
import { jobsPanel } from './jobs.js';

const $ = (id) => document.getElementById(id);
const stage = new Stage($('view'));
const editor = new AnnotationEditor({
  bar: $('segments'), plot: $('plot'), plotRange: $('plot-range'), name: $('segment-name'), tags: $('tags'),
  status: $('annotation-status'), joint: $('plot-joint'), quantity: $('plot-quantity'),
  buttons: Object.fromEntries([...document.querySelectorAll('#annotations [data-action]')].map((b) => [b.dataset.action, b])),
}, {
  frame: () => state.frame,
  setFrame: (i) => { pause(); setFrame(i); },
  positions: () => (state.frames ? state.frames.positions : null),
  jointNames: () => (state.rig ? state.rig.joints.map((j) => j.name) : []),
  plotJoint: () => (state.jointMap ? state.jointMap.left_ankle : null), // a foot: where it plants
  // the pose editor's: the stored motion (dashed) while an edit shows, and the next edit's blend range
  originalPositions: () => poseEditor.originalPositions(),
  blendRange: () => poseEditor.blendRange(),
  revision: () => poseEditor.revision,
});
const poseEditor = new PoseEditor({
  mode: $('pose-mode'), before: $('pose-before'), after: $('pose-after'), chain: $('pose-chain'), undo: $('pose-undo'),
  save: $('pose-save'), discard: $('pose-discard'), status: $('pose-status'), notes: $('pose-notes'),
}, {
  state: () => state,
  setFrame: (i) => setFrame(i),
  pause: () => pause(),
  reload: (clipId) => loadClip(clipId, false),
  redrawPlot: () => editor.drawPlot(),
  plotJoint: (index) => { $('plot-joint').value = String(index); editor.drawPlot(); },
}, stage);
const state = { clip: null, fps: 0, frames: null, frame: 0, playing: false, time: 0, highlighted: null, rig: null,
                character: null };

function status(text, isError = false) {
  $('status').textContent = text;
  $('status').classList.toggle('error', isError);
}

async function allFrames(clipId, nFrames) {
  // Pages as large as the endpoint gives (most clips are one page).
  const pages = [];
  for (let start = 0; start < nFrames; start += pages[pages.length - 1].count) {
    pages.push(await getJSON(`/api/clips/${clipId}/frames?start=${start}`));
  }
  return {
    rotations: pages.flatMap((p) => p.rotations),
    translations: pages.flatMap((p) => p.translations), // the rig poses itself from these
    positions: pages.flatMap((p) => p.positions), // the server's, for the annotation editor's plot
  };
}

let latestLoad = 0; // only the clip asked for last is shown, however the answers arrive

async function loadClip(clipId, autoplay = true) {
  const load = ++latestLoad;
  status(`loading clip ${clipId}…`);
  pause();
  let clip, skeleton, frames, character;
  try {
    clip = await getJSON(`/api/clips/${clipId}`);
    skeleton = await getJSON(`/api/skeletons/${clip.skeleton_id}`);
    frames = await allFrames(clipId, clip.n_frames);
    // the skinned character; without one (no bone long enough to draw) the skeleton shows
    character = await loadCharacter(clip.skeleton_id, skeleton.hierarchy.translated).catch(() => null);
  } catch (error) {
    if (load === latestLoad) status(`clip ${clipId}: ${error.message}`, true);
    return false;
  }
  if (load !== latestLoad) return false;
  Object.assign(state, { clip, fps: clip.fps, frames, frame: 0, time: 0, highlighted: null, character,
                         jointMap: skeleton.joint_map, jointAxes: skeleton.joint_axes,
                         rig: new Rig(skeleton.hierarchy, skeleton.joint_map.pelvis) });
  stage.setCharacter(character);
  $('download-bvh').href = `/api/clips/${clip.id}/download?format=bvh&version=${clip.version}`;
  $('download-glb').href = `/api/clips/${clip.id}/download?format=glb&version=${clip.version}`;
  $('skeleton-name').textContent = `(${skeleton.name || skeleton.id}, ${skeleton.hierarchy.joints.length} joints)`;
  showSkeleton($('skeleton'), skeleton.hierarchy.joints, (index) => poseEditor.select(index));
  $('timeline').max = String(clip.n_frames - 1);
  state.rig.pose(frames.rotations[0], frames.translations[0]);
  stage.setFigure(skeleton.hierarchy.joints.length, state.rig.worldPositions()[state.rig.pelvis]);
  stage.showSkeleton($('show-skeleton').checked || !character);
  poseEditor.open(clip, skeleton);
  setFrame(0);
  status('');
  document.title = `MoDB: ${clip.collection}/${clip.name}`;
  history.replaceState(null, '', `?clip=${clip.id}`); // reload and share open this clip
  await editor.open(clip);
  if (autoplay) play(); // a chosen clip plays: the page shows something that moves
  return true;
}

function setFrame(index) {
  if (!state.frames) return;
  const n = state.clip.n_frames;
  state.frame = ((index % n) + n) % n;
  state.rig.pose(state.frames.rotations[state.frame], state.frames.translations[state.frame]);
  if (state.character) state.character.pose(state.frames.rotations[state.frame], state.frames.translations[state.frame]);
  stage.draw(state.rig.boneSegments(), state.rig.worldPositions(), state.rig.pelvis, state.highlighted,
             $('follow').checked);
  stage.drawAxes($('show-axes').checked ? state.rig.axisSegments(state.jointAxes) : null);
  $('timeline').value = String(state.frame);
  poseEditor.frameChanged();
  editor.drawCursor();
  $('frame').textContent = `${state.frame} / ${n - 1}  ${(state.frame / state.fps).toFixed(2)} s`;
}

function play() {
  if (!state.frames) return;
  state.playing = true;
  state.time = state.frame / state.fps;
  $('play').textContent = 'pause';
}

function pause() {
  state.playing = false;
  $('play').textContent = 'play';
}

let last = performance.now();
function tick(now) {
  const dt = (now - last) / 1000;
  last = now;
  if (state.playing) {
    state.time += dt * Number($('speed').value);
    const next = Math.floor(state.time * state.fps + 1e-9);
    if (next !== state.frame) setFrame(next);
  }
  stage.render();
  requestAnimationFrame(tick);
}

$('play').addEventListener('click', () => (state.playing ? pause() : play()));
$('prev').addEventListener('click', () => { pause(); setFrame(state.frame - 1); });
$('next').addEventListener('click', () => { pause(); setFrame(state.frame + 1); });
$('timeline').addEventListener('input', (e) => { pause(); setFrame(Number(e.target.value)); });
window.addEventListener('keydown', (e) => {
  if (e.target.tagName === 'INPUT' || e.target.tagName === 'SELECT') return;
  if (e.key === ' ') { e.preventDefault(); state.playing ? pause() : play(); }
  if (e.key === 'ArrowLeft') { pause(); setFrame(state.frame - 1); }
  if (e.key === 'ArrowRight') { pause(); setFrame(state.frame + 1); }
});

async function showCollection(collectionId) {
  showClips($('clips'), $('clip-count'), await getJSON(`/api/clips?collection=${collectionId}`), (clip) => loadClip(clip.id));
}

// The clip the page opens on when the address names none: the first collection in the listing's order
// (/api/collections sorts by path, as the collection tree shows them) that holds clips, and the first of its
// clips in the clip list's order (by name, then id). Null when no collection holds a clip.
async function firstClip(collections) {
  for (const c of collections.filter((c) => c.clips > 0)) {
    const clips = await getJSON(`/api/clips?collection=${c.id}`);
    if (clips.length) return clips[0];
  }
  return null;
}

// An empty database: how to load data, where the view and its controls would be.
function showEmpty() {
  $('view').hidden = true;
  document.querySelector('main > footer').hidden = true;
  $('empty').hidden = false;
  status('');
}

async function showCollectionTree() {
  const collections = await getJSON('/api/collections');
  showCollections($('collections'), collections, (c) => showCollection(c.id));
  return collections;
}

// An uploaded clip: the panels show it, and it plays.
async function showUploaded(clipId) {
  await showCollectionTree();
  $('view').hidden = false;
  document.querySelector('main > footer').hidden = false;
  $('empty').hidden = true;
  if (await loadClip(clipId)) {
    markSelected($('collections'), state.clip.collection_id);
    await showCollection(state.clip.collection_id);
    markSelected($('clips'), state.clip.id);
  }
}

async function start() {
  const collections = await showCollectionTree();
  if (!collections.some((c) => c.clips > 0)) return showEmpty();
  const wanted = new URLSearchParams(location.search).get('clip');
  const clip = wanted ? { id: wanted } : await firstClip(collections);
  if (!clip) return status('choose a collection, then a clip');
  if (await loadClip(encodeURIComponent(clip.id))) { // it plays; the panels show where it is
    markSelected($('collections'), state.clip.collection_id);
    await showCollection(state.clip.collection_id);
    markSelected($('clips'), state.clip.id);
  }
}

$('show-skeleton').addEventListener('change', () => stage.showSkeleton($('show-skeleton').checked || !state.character));
$('show-axes').addEventListener('change', () => setFrame(state.frame));
// A link cannot carry the Authorization header: with a token set, a download is fetched with it and saved.
for (const link of [$('download-bvh'), $('download-glb')]) {
  link.addEventListener('click', async (e) => {
    if (!token.get()) return;
    e.preventDefault();
    const response = await fetch(link.href, { headers: token.headers() });
    if (!response.ok) { status(`download: HTTP ${response.status}`, true); return; }
    const named = /filename="([^"]+)"/.exec(response.headers.get('Content-Disposition') || '');
    const saved = document.createElement('a');
    saved.href = URL.createObjectURL(await response.blob());
    saved.download = named ? named[1] : 'clip';
    saved.click();
    URL.revokeObjectURL(saved.href);
  });
}

tokenPanel($('token'), $('token-use'), $('token-forget'), $('token-state'));
uploadPanel($('drop'), $('upload-files'), $('upload-collection'), $('uploads'), showUploaded);
jobsPanel($('jobs-panel'), $('jobs'));

window.modbViewer = {
  stage,
  state,
  editor,
  pose: poseEditor,
  loadClip,
  setFrame,
  play,
  pause,
  jointNames: () => (state.rig ? state.rig.joints.map((j) => j.name) : []),
  jointWorldPositions: () => (state.rig ? state.rig.worldPositions() : []),
  drawn: () => stage.drawn(), // what the scene shows: joint spheres and bone line ends
  stageAxesShown: () => stage.axes.visible,
  axes: () => (state.rig ? state.rig.axisSegments(state.jointAxes).map(([a, b, c]) => [a.toArray(), b.toArray(), c]) : []),
  ready: start().then(() => true, (error) => { status(error.message, true); throw error; }),
};
requestAnimationFrame(tick);
