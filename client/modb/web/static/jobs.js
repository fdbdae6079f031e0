// The Jobs panel: the newest jobs (graph builds, ...) with their progress, polled every 1.5 s while one
// is queued or running, a link to what each made, and cancel (with a loader token). Shown once there is
// a job (the database may have no job tables: then there is none).
import { token } from './token.js';

const SHOWN = 8;
const BUSY_MS = 1500;
const IDLE_MS = 6000;
const ACTIVE = ['queued', 'running'];

function label(job) {
  const a = job.arguments || {};
  return job.kind.replace(/^modb\./, '').replace('_', ' ') + (a.name ? ` "${a.name}"` : '');
}

function madeLink(job) {
  if (!job.result || job.result.graph_id === undefined) return null;
  const link = document.createElement('a');
  link.href = `/api/graphs/${job.result.graph_id}`;
  link.textContent = `graph ${job.result.graph}`;
  return link;
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
  const made = madeLink(job);
  if (made) tail.append(made);
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
