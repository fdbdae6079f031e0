// The side panels: the collection hierarchy, a collection's clips, and the skeleton's joint tree.
import { token } from './token.js';

export async function getJSON(url) {
  const response = await fetch(url, { headers: token.headers() }); // a server with --require-token needs it
  const body = await response.json();
  if (!response.ok) throw new Error(body.error || `${url}: HTTP ${response.status}`);
  return body;
}

// The motion models (/api/motion-models), asked for once per page: the Models panel and the Graphs of models
// panel share the answer (one request; its first answer can take the server a moment).
let motionModelsAsked = null;
export function motionModels() {
  motionModelsAsked ??= getJSON('/api/motion-models');
  return motionModelsAsked;
}

function item(label, title, id, onSelect) {
  const li = document.createElement('li');
  const span = document.createElement('span');
  span.textContent = label;
  span.dataset.id = id;
  if (title) span.title = title;
  span.addEventListener('click', () => {
    span.closest('aside > section').querySelectorAll('span.selected').forEach((s) => s.classList.remove('selected'));
    span.classList.add('selected');
    onSelect();
  });
  li.appendChild(span);
  return li;
}

// Nested lists from rows that name their parent (parentOf(row) is null at the top).
function tree(root, rows, idOf, parentOf, render) {
  root.replaceChildren();
  const children = new Map();
  rows.forEach((r) => { const p = parentOf(r); if (!children.has(p)) children.set(p, []); children.get(p).push(r); });
  const grow = (ul, parent) => (children.get(parent) || []).forEach((r) => {
    const li = render(r);
    if (children.has(idOf(r))) { const sub = document.createElement('ul'); grow(sub, idOf(r)); li.appendChild(sub); }
    ul.appendChild(li);
  });
  grow(root, null);
}

export function showCollections(root, collections, onSelect) {
  tree(root, collections, (c) => c.id, (c) => c.parent_id,
       (c) => item(`${c.name} (${c.clips})`, c.path, c.id, () => onSelect(c)));
}

export function showClips(root, counter, clips, onSelect) {
  root.replaceChildren(...clips.map((c) => item(c.name, `${c.n_frames} frames at ${c.fps} fps`, c.id, () => onSelect(c))));
  counter.textContent = `(${clips.length})`;
}

export function showSkeleton(root, joints, onSelect) {
  const rows = joints.map((j, i) => ({ ...j, index: i }));
  tree(root, rows, (j) => j.index, (j) => (j.parent < 0 ? null : j.parent),
       (j) => item(j.name, `joint ${j.index}`, j.index, () => onSelect(j.index)));
}

// Marks the entry with this id as selected (as a click would, without acting on it).
export function markSelected(root, id) {
  root.querySelectorAll('span.selected').forEach((s) => s.classList.remove('selected'));
  const span = root.querySelector(`span[data-id="${id}"]`);
  if (span) { span.classList.add('selected'); span.scrollIntoView({ block: 'nearest' }); }
}
