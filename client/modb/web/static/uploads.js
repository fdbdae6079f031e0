// Upload by drag and drop (or the file chooser): one request per motion file, so each file has its own
// progress bar and its own result. An .amc goes with every .asf given (the server pairs them as `modb load`
// does); X.annotations.json goes with X.bvh / X.amc.
import { token } from './token.js';

const motion = (f) => /\.(bvh|amc)$/i.test(f.name);
const stem = (name) => name.replace(/\.(bvh|amc|asf)$/i, '').replace(/\.annotations\.json$/i, '');

// Requests to make: [motion file, ...the files that go with it].
export function batches(files) {
  const all = [...files];
  const skeletons = all.filter((f) => /\.asf$/i.test(f.name));
  const sidecars = all.filter((f) => /\.annotations\.json$/i.test(f.name));
  const unknown = all.filter((f) => !motion(f) && !skeletons.includes(f) && !sidecars.includes(f));
  const groups = all.filter(motion).map((m) => [
    m,
    ...(/\.amc$/i.test(m.name) ? skeletons : []),
    ...sidecars.filter((s) => stem(s.name) === stem(m.name)),
  ]);
  return { groups, unknown };
}

function send(files, collection, onProgress) {
  return new Promise((resolve) => {
    const form = new FormData();
    form.append('collection', collection);
    files.forEach((f) => form.append('file', f, f.name));
    const xhr = new XMLHttpRequest();
    xhr.open('POST', '/api/uploads');
    Object.entries(token.headers()).forEach(([k, v]) => xhr.setRequestHeader(k, v));
    xhr.upload.onprogress = (e) => { if (e.lengthComputable) onProgress(e.loaded / e.total); };
    xhr.onload = () => {
      let body = null;
      try { body = JSON.parse(xhr.responseText); } catch { body = { error: xhr.responseText }; }
      resolve({ status: xhr.status, body });
    };
    xhr.onerror = () => resolve({ status: 0, body: { error: 'the server did not answer' } });
    xhr.send(form);
  });
}

function row(list, name) {
  const li = document.createElement('li');
  const label = document.createElement('span');
  label.textContent = name;
  const bar = document.createElement('progress');
  bar.max = 1;
  bar.value = 0;
  const result = document.createElement('div');
  result.className = 'result';
  li.append(label, bar, result);
  list.appendChild(li);
  return { li, bar, result };
}

// Uploads `files` into `collection`, showing each in `list`; calls onStored(clipId) for each stored clip.
export async function upload(files, collection, list, onStored) {
  const { groups, unknown } = batches(files);
  unknown.forEach((f) => {
    const r = row(list, f.name);
    r.li.classList.add('failed');
    r.result.textContent = 'not uploaded: .bvh, .amc (with its .asf) or .annotations.json only';
  });
  for (const group of groups) {
    const r = row(list, group[0].name);
    const { status, body } = await send(group, collection, (share) => { r.bar.value = share; });
    r.bar.value = 1;
    const result = (body.results || []).find((x) => x.file === group[0].name);
    if (result) {
      r.li.classList.add(result.status);
      r.li.dataset.status = result.status;
      r.result.textContent = result.status === 'failed' ? result.message
        : `${result.status}: clip ${result.clip_id}${result.version ? ` version ${result.version}` : ''}`
          + (result.message ? ` (${result.message})` : '');
      if (result.status !== 'failed') onStored(result.clip_id);
    } else {
      r.li.classList.add('failed');
      r.li.dataset.status = 'failed';
      r.result.textContent = `HTTP ${status}: ${body.error || 'no answer'}`;
    }
  }
}

// The drop zone and file chooser.
export function uploadPanel(zone, chooser, collectionInput, list, onStored) {
  const take = (files) => upload(files, collectionInput.value.trim() || 'uploads', list, onStored);
  zone.addEventListener('dragover', (e) => { e.preventDefault(); zone.classList.add('over'); });
  zone.addEventListener('dragleave', () => zone.classList.remove('over'));
  zone.addEventListener('drop', (e) => { e.preventDefault(); zone.classList.remove('over'); take(e.dataTransfer.files); });
  chooser.addEventListener('change', () => { take(chooser.files); chooser.value = ''; });
}
