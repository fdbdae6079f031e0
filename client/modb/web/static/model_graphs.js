// The Graphs of models panel: the graphs of motion models (modb.graphs kind 'models', `modb model graph`).
// One opened is drawn (its nodes as boxes, coloured by type, the transitions as arrows) and listed, and is
// edited here: a motion model of the graph's skeleton added as a node, a node's type set (start, end, idle,
// standard, action: one performed from idle, issue 63), a node removed (with its transitions), a transition added or removed. Save replaces the graph
// by PUT with the ETag it was read with (If-Match) and this tab's token; the database checks every graph
// (modb.model_graph_problem), so a refused save shows the database's reason here and stores nothing. A new
// graph starts from one model: its skeleton, and a start node playing it.
// window.modbModelGraphs is what tests (and the console) read.
import { getJSON, motionModels } from './panels.js';
import { token } from './token.js';

const TYPES = ['start', 'standard', 'end', 'idle', 'action'];
const COLOURS = { start: '#3b9c4a', standard: '#2f6fc4', end: '#c0392b', idle: '#7d8590', action: '#8e44ad' };
const SVG = 'http://www.w3.org/2000/svg';
const W = 280; // the drawing's size (its viewBox; it scales to the panel's width)
const H = 230;
const BOX_H = 22;
const CHAR_W = 6.6; // px per character of the 11px labels: boxes fit their names without measuring
const $ = (id) => document.getElementById(id);
const state = { graphs: [], models: [], graph: null, etag: null, data: null, dirty: false, selected: null };
let latest = 0; // only the last graph asked for is shown, however the answers arrive

function say(text, isError = false) {
  $('graph-status').textContent = text;
  $('graph-status').classList.toggle('error', isError);
}

const typeOf = (node) => node.type || 'standard';
const modelOf = (id) => state.models.find((m) => m.id === id);
const modelLabel = (id) => { const m = modelOf(id); return m ? `${m.name} v${m.version}` : `model ${id}`; };

function option(value, text) {
  const o = document.createElement('option');
  o.value = value;
  o.textContent = text;
  return o;
}

function button(text, title, onClick) {
  const b = document.createElement('button');
  b.textContent = text;
  b.title = title;
  b.setAttribute('aria-label', title);
  b.addEventListener('click', onClick);
  return b;
}

function svg(tag, attributes) {
  const e = document.createElementNS(SVG, tag);
  Object.entries(attributes).forEach(([k, v]) => e.setAttribute(k, v));
  return e;
}

// Where the segment from a box's centre toward (dx, dy) leaves the box.
function edge(box, dx, dy) {
  const t = Math.min(dx ? box.w / 2 / Math.abs(dx) : Infinity, dy ? BOX_H / 2 / Math.abs(dy) : Infinity);
  return [box.x + dx * t, box.y + dy * t];
}

// Nodes on a circle (start nodes first, then standard, end, idle, action; by name), transitions as arrows between
// the boxes' edges: a pair both ways drawn side by side, a transition to itself as a loop above the box.
function draw() {
  const drawing = $('graph-drawing');
  drawing.replaceChildren();
  const { nodes, transitions = [] } = state.data;
  const names = Object.keys(nodes).sort((a, b) => TYPES.indexOf(typeOf(nodes[a])) - TYPES.indexOf(typeOf(nodes[b]))
                                                  || (a < b ? -1 : a > b ? 1 : 0));
  const defs = svg('defs', {});
  const marker = svg('marker', { id: 'graph-arrow', viewBox: '0 0 10 10', refX: 10, refY: 5, markerWidth: 7,
                                 markerHeight: 7, orient: 'auto-start-reverse' });
  marker.append(svg('path', { d: 'M0,0 L10,5 L0,10 z', fill: '#444' }));
  defs.append(marker);
  drawing.append(defs);
  const radius = names.length > 1 ? Math.min(W / 2 - 50, H / 2 - 30) : 0;
  const boxes = {};
  names.forEach((name, k) => {
    const angle = Math.PI + (2 * Math.PI * k) / names.length; // two nodes: left and right
    boxes[name] = { x: W / 2 + radius * Math.cos(angle), y: H / 2 + 6 + radius * Math.sin(angle),
                    w: Math.max(44, name.length * CHAR_W + 14) };
  });
  const pairs = new Set(transitions.map((t) => `${t.from}\u0000${t.to}`));
  transitions.forEach((t) => {
    const a = boxes[t.from];
    const b = boxes[t.to];
    if (!a || !b) return;
    let path;
    if (t.from === t.to) {
      const top = a.y - BOX_H / 2;
      path = `M${a.x - 10},${top} C${a.x - 26},${top - 30} ${a.x + 26},${top - 30} ${a.x + 10},${top}`;
    } else {
      const length = Math.hypot(b.x - a.x, b.y - a.y) || 1;
      const [dx, dy] = [(b.x - a.x) / length, (b.y - a.y) / length];
      const shift = pairs.has(`${t.to}\u0000${t.from}`) ? 6 : 0; // each of a pair on its own right side
      const [sx, sy] = [-dy * shift, dx * shift];
      const [x0, y0] = edge(a, dx, dy);
      const [x1, y1] = edge(b, -dx, -dy);
      path = `M${x0 + sx},${y0 + sy} L${x1 + sx},${y1 + sy}`;
    }
    const arrow = svg('path', { d: path, fill: 'none', stroke: '#444', 'stroke-width': 1.5,
                                'marker-end': 'url(#graph-arrow)' });
    Object.assign(arrow.dataset, { from: t.from, to: t.to });
    drawing.append(arrow);
  });
  names.forEach((name) => {
    const box = boxes[name];
    const type = typeOf(nodes[name]);
    const g = svg('g', { class: `graph-node${state.selected === name ? ' selected' : ''}` });
    Object.assign(g.dataset, { node: name, type });
    const title = svg('title', {});
    title.textContent = `${name}: ${type}, ${modelLabel(nodes[name].model_id)}`;
    g.append(title,
             svg('rect', { x: box.x - box.w / 2, y: box.y - BOX_H / 2, width: box.w, height: BOX_H, rx: 4,
                           fill: COLOURS[type] || COLOURS.standard }),
             Object.assign(svg('text', { x: box.x, y: box.y + 4, 'text-anchor': 'middle' }), { textContent: name }));
    g.addEventListener('click', () => { state.selected = name; $('graph-from').value = name; render(); });
    drawing.append(g);
  });
  state.drawn = { nodes: names.length, arrows: drawing.querySelectorAll('path[data-from]').length };
}

function render() {
  const { nodes, transitions = [] } = state.data;
  const g = state.graph;
  $('graph-summary').textContent = `${g.name}: ${Object.keys(nodes).length} nodes, ${transitions.length}`
    + ` transitions, skeleton ${g.skeleton_id}${state.dirty ? ' (unsaved changes)' : ''}`;
  draw();
  const names = Object.keys(nodes).sort();
  $('graph-nodes').replaceChildren(...names.map((name) => {
    const li = document.createElement('li');
    li.dataset.node = name;
    const label = document.createElement('span');
    label.textContent = `${name} · ${modelLabel(nodes[name].model_id)}`;
    label.title = label.textContent;
    const type = document.createElement('select');
    type.className = 'node-type';
    type.setAttribute('aria-label', `type of ${name}`);
    type.append(...TYPES.map((t) => option(t, t)));
    type.value = typeOf(nodes[name]);
    type.addEventListener('change', () => change(() => { nodes[name].type = type.value; }));
    li.append(label, type, button('×', `remove ${name} and its transitions`, () => removeNode(name)));
    return li;
  }));
  $('graph-transitions').replaceChildren(...transitions.map((t, i) => {
    const li = document.createElement('li');
    Object.assign(li.dataset, { from: t.from, to: t.to });
    const label = document.createElement('span');
    label.textContent = `${t.from} → ${t.to}`;
    const remove = () => change(() => state.data.transitions.splice(i, 1));
    li.append(label, button('×', `remove ${t.from} → ${t.to}`, remove));
    return li;
  }));
  for (const id of ['graph-from', 'graph-to']) {
    const select = $(id);
    const was = select.value;
    select.replaceChildren(...names.map((n) => option(n, n)));
    if (names.includes(was)) select.value = was;
  }
  const mine = state.models.filter((m) => m.skeleton_id === g.skeleton_id);
  const was = $('graph-add-model').value;
  $('graph-add-model').replaceChildren(...mine.map((m) => option(m.id, `${m.name} v${m.version} · ${m.primitive}`
                                                                    + (m.stale ? ' (stale)' : ''))));
  if (mine.some((m) => String(m.id) === was)) $('graph-add-model').value = was;
}

function change(edit) {
  edit();
  state.dirty = true;
  say('');
  render();
}

function removeNode(name) {
  change(() => {
    delete state.data.nodes[name];
    state.data.transitions = (state.data.transitions || []).filter((t) => t.from !== name && t.to !== name);
    if (state.selected === name) state.selected = null;
  });
}

// A node playing the chosen model: named as typed, else after the model's primitive (made unique).
function addNode() {
  const model = modelOf(Number($('graph-add-model').value));
  if (!model) return say('choose a motion model of the graph\'s skeleton to add', true);
  const nodes = state.data.nodes;
  let name = $('graph-add-name').value.trim();
  if (name && nodes[name]) return say(`there is a node "${name}" already`, true);
  if (!name) {
    const base = model.primitive || model.name;
    name = base;
    for (let k = 2; nodes[name]; k += 1) name = `${base}_${k}`;
  }
  const action = Object.values(nodes).find((n) => n.action)?.action;
  change(() => {
    nodes[name] = { model_id: model.id, model: model.name, version: model.version, type: 'standard',
                    ...(action ? { action } : {}) };
    state.selected = name;
  });
  $('graph-add-name').value = '';
}

function addTransition() {
  const from = $('graph-from').value;
  const to = $('graph-to').value;
  if (!from || !to) return say('choose the nodes the transition joins', true);
  const transitions = state.data.transitions || [];
  if (transitions.some((t) => t.from === from && t.to === to)) return say(`${from} → ${to} is there already`, true);
  change(() => { state.data.transitions = [...transitions, { from, to }]; });
}

async function open(id) {
  const load = ++latest;
  const response = await fetch(`/api/graphs/${id}`, { headers: token.headers() });
  const body = await response.json();
  if (!response.ok) throw new Error(body.error || `HTTP ${response.status}`);
  if (load !== latest) return;
  const data = structuredClone(body.data);
  data.transitions = data.transitions || [];
  Object.assign(state, { graph: body, etag: response.headers.get('ETag'), data, dirty: false, selected: null });
  $('graph-editor').hidden = false;
  $('model-graphs').querySelectorAll('span.selected').forEach((s) => s.classList.remove('selected'));
  $('model-graphs').querySelector(`span[data-id="${body.id}"]`)?.classList.add('selected');
  say('');
  render();
}

async function save() {
  if (!state.graph) return;
  if (!token.get()) return say('saving needs a loader token: paste one under "Access token"', true);
  const id = state.graph.id;
  say('saving…');
  const response = await fetch(`/api/graphs/${id}`, {
    method: 'PUT',
    headers: { 'Content-Type': 'application/json', 'If-Match': state.etag, ...token.headers() },
    body: JSON.stringify({ data: state.data }),
  });
  const body = await response.json();
  if (response.status === 409) {
    return say('someone saved this graph since you opened it: open it again to see theirs (yours is not saved)',
               true);
  }
  if (!response.ok) return say(`not saved: ${body.error || `HTTP ${response.status}`}`, true);
  Object.assign(state, { etag: response.headers.get('ETag'), dirty: false });
  state.graph.data = structuredClone(state.data);
  render();
  say('saved');
  await list();
}

// A new graph of one node, the chosen model as a start node, on that model's skeleton.
async function create() {
  const name = $('graph-new-name').value.trim();
  const model = modelOf(Number($('graph-new-model').value));
  if (!name) return say('name the new graph', true);
  if (!model) return say('choose the model it starts with', true);
  if (!token.get()) return say('creating a graph needs a loader token: paste one under "Access token"', true);
  const node = model.primitive || model.name;
  const data = { nodes: { [node]: { model_id: model.id, model: model.name, version: model.version, type: 'start' } },
                 transitions: [] };
  const response = await fetch('/api/graphs', {
    method: 'POST',
    headers: { 'Content-Type': 'application/json', ...token.headers() },
    body: JSON.stringify({ name, kind: 'models', skeleton_id: model.skeleton_id, data }),
  });
  const body = await response.json();
  if (!response.ok) return say(`not created: ${body.error || `HTTP ${response.status}`}`, true);
  $('graph-new-name').value = '';
  await list();
  await open(body.id);
  say(`created ${name}: add nodes and transitions, then save`);
}

async function list(asked = getJSON('/api/graphs?kind=models')) {
  state.graphs = await asked;
  $('model-graphs').replaceChildren(...state.graphs.map((g) => {
    const li = document.createElement('li');
    const span = document.createElement('span');
    span.textContent = `${g.name} · ${g.nodes} nodes · ${g.transitions} transitions`;
    Object.assign(span.dataset, { id: g.id, graph: g.name });
    span.title = `skeleton ${g.skeleton_id}; made ${g.created_at}`;
    if (state.graph?.id === g.id) span.classList.add('selected');
    span.addEventListener('click', () => open(g.id).catch((e) => say(e.message, true)));
    li.append(span);
    return li;
  }));
  $('graph-count').textContent = `(${state.graphs.length})`;
  $('graphs-panel').hidden = !state.graphs.length && !state.models.length;
}

// Both listings asked for at once, as the page loads (the motion models with the Models panel).
async function start() {
  const graphs = getJSON('/api/graphs?kind=models');
  graphs.catch(() => {}); // (its failure is list()'s to say)
  state.models = await motionModels().catch(() => []);
  $('graph-new-model').replaceChildren(...state.models.map((m) => option(
    m.id, `${m.name} v${m.version} · ${m.primitive} · skeleton ${m.skeleton_id}`)));
  await list(graphs);
}

$('graph-add-node').addEventListener('click', addNode);
$('graph-add-transition').addEventListener('click', addTransition);
$('graph-save').addEventListener('click', () => save().catch((e) => say(e.message, true)));
$('graph-revert').addEventListener('click', () => state.graph
  && open(state.graph.id).catch((e) => say(e.message, true)));
$('graph-create').addEventListener('click', () => create().catch((e) => say(e.message, true)));

window.modbModelGraphs = {
  get opened() { return state.graph && { id: state.graph.id, name: state.graph.name }; },
  get data() { return state.data && structuredClone(state.data); },
  get etag() { return state.etag; },
  get dirty() { return state.dirty; },
  get drawn() { return state.drawn && { ...state.drawn }; },
  open,
  ready: start().then(() => true, (e) => { say(e.message, true); return true; }),
};
