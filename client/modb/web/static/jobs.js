// The Jobs panel: the newest jobs (graph builds, retargetings, edits, splits) with their progress, polled every 1.5 s while one
// is queued or running, a link to what each made, and cancel (with a loader token). Shown once there is
// a job (the database may have no job tables: then there is none).
import { token } from './token.js';

const SHOWN = 8;
const BUSY_MS = 1500;
const IDLE_MS = 6000;
const ACTIVE = ['waiting', 'queued', 'running'];
const MADE_SHOWN = 6;

function label(job) {
  const a = job.arguments || {};
  const what = a.name || a.script;
  const clips = a.clips ? `, ${a.clips.length} clip${a.clips.length === 1 ? '' : 's'}` : '';
  const waits = job.state === 'waiting' && job.waits_for ? ` (after job ${job.waits_for.join(', ')})` : '';
  return job.kind.replace(/^modb\./, '').replaceAll('_', ' ') + (what ? ` "${what}"` : '') + clips + waits;
}

function link(href, text) {
  const a = document.createElement('a');
  a.href = href;
  a.textContent = text;
  return a;
}

// What the job made so far (a cancelled job keeps what it finished): its graph, or its clips.
function madeLinks(job) {
  const r = job.result;
  if (!r) return [];
  if (r.graph_id !== undefined) return [link(`/api/graphs/${r.graph_id}`, `graph ${r.graph}`)];
  const clips = (r.clips || []).flatMap((c) => (c.cuts ? c.cuts : [c]));
  const shown = clips.slice(0, MADE_SHOWN).map((c) => link(`/api/clips/${c.clip_id}`, `clip ${c.clip_id}`));
  if (clips.length > MADE_SHOWN) shown.push(`+${clips.length - MADE_SHOWN} more`);
  return shown;
}

function item(job, onCancel) {
  const li = document.createElement('li');
  li.dataset.job = job.id;
  li.className = job.state;
  const head = document.createElement('div');
  head.textContent = `${job.id} ${label(job)}: ${job.state}`;
  head.title = `submitted by ${job.submitter}`;
  li.append(head);
  if (job.total) {
    const bar = document.createElement('progress');
    bar.max = job.total;
    bar.value = job.done || 0;
    bar.title = `${(job.done || 0).toLocaleString()} of ${job.total.toLocaleString()} ${job.unit || ''}`;
    li.append(bar);
  }
  const tail = document.createElement('div');
  tail.className = 'result';
  tail.append(...madeLinks(job));
  if (job.error) tail.append(job.error);
  if (ACTIVE.includes(job.state) && token.get()) {
    const cancel = document.createElement('button');
    cancel.textContent = 'cancel';
    cancel.addEventListener('click', () => onCancel(job.id, cancel));
    tail.append(cancel);
  }
  li.append(tail);
  return li;
}

export function jobsPanel(section, list) {
  let timer = null;
  async function refresh() {
    clearTimeout(timer);
    let jobs;
    try {
      const r = await fetch('/api/jobs', { headers: token.headers() });
      jobs = r.ok ? await r.json() : null;
    } catch { jobs = null; }
    if (jobs) {
      section.hidden = !jobs.length;
      list.replaceChildren(...jobs.slice(0, SHOWN).map((j) => item(j, cancel)));
    }
    const busy = jobs && jobs.some((j) => ACTIVE.includes(j.state));
    timer = setTimeout(refresh, busy ? BUSY_MS : IDLE_MS);
  }
  async function cancel(id, button) {
    button.disabled = true;
    const r = await fetch(`/api/jobs/${id}/cancel`, { method: 'POST', headers: token.headers() });
    if (!r.ok) button.title = (await r.json()).error;
    refresh();
  }
  refresh();
}
