// The avatar page's tuning panel: the settings this browser connection's selections use, and the live
// readouts the server sends after every selection. Every change is sent whole; the server checks it and
// answers with the settings in force (or refuses, saying why, and keeps the previous ones).

const THRESHOLDS = [
  ['position_threshold', 'position (m)'], ['angle_threshold', 'angle (rad)'],
  ['velocity_threshold', 'velocity (m/s)'], ['angular_velocity_threshold', 'angular velocity (rad/s)'],
];

function element(tag, props = {}, children = []) {
  const e = Object.assign(document.createElement(tag), props);
  e.append(...children);
  return e;
}

function options(select, values, labels = values) {
  select.replaceChildren(...values.map((v, i) => element('option', { value: v, textContent: labels[i] })));
}

function fixed(value, digits) {
  return value === null || value === undefined ? '-' : Number(value).toFixed(digits);
}

export class Tuning {
  constructor(root, send) {
    this.root = root;
    this.$ = (id) => root.querySelector(`#${id}`);
    this.send = send;
    this.profiles = new Map();
  }

  // ready: what the server offers (profiles, graphs, collections, joints) and the settings in force.
  build(ready) {
    ready.profiles.forEach((p) => this.profiles.set(p.name, p.settings));
    const $ = this.$;
    options($('profile'), ready.profiles.map((p) => p.name));
    options($('graph'), ['', 'none', ...ready.graphs], ['automatic: the newest current one over the data', 'none: every snippet (the plain rule)', ...ready.graphs]);
    options($('collection'), ['', ...ready.collections], ['all', ...ready.collections]);
    $('thresholds').replaceChildren(...THRESHOLDS.map(([knob, label]) => element('label', {}, [
      label, element('input', { id: knob, type: 'number', min: '0', step: 'any', placeholder: "profile's" })])));
    $('joints').replaceChildren(...ready.joints.map((j) => element('label', {}, [
      element('input', { type: 'checkbox', value: j, name: 'joint' }), j.replace('_', ' ')])));
    this.root.querySelectorAll('section input, section select').forEach((input) => input.addEventListener('change', (e) => this.changed(e.target)));
    $('profile-joints').addEventListener('click', () => { this.showJoints(this.profileJoints()); this.changed(null); });
    this.show(ready.settings);
  }

  profileJoints() {
    return (this.profiles.get(this.root.querySelector('#profile').value) || {}).joints || [];
  }

  showJoints(joints) {
    this.root.querySelectorAll('input[name=joint]').forEach((box) => { box.checked = joints.includes(box.value); });
  }

  // The settings in force, as the server says.
  show(settings) {
    const $ = this.$;
    $('profile').value = settings.profile;
    $('graph').value = settings.graph || '';
    $('collection').value = settings.collection || '';
    $('lead_time').value = settings.lead_time;
    $('arrival_radius').value = settings.arrival_radius;
    THRESHOLDS.forEach(([knob]) => { $(knob).value = settings.knobs[knob] || ''; });
    $('norm').value = settings.knobs.norm || '';
    $('velocity_terms').value = settings.knobs.velocity_terms || '';
    $('annotations').value = settings.knobs.annotations || '';
    this.showJoints(settings.knobs.joints ? settings.knobs.joints.split(',') : this.profileJoints());
    this.settings = settings;
  }

  changed(target) {
    const $ = this.$;
    if (target && target.id === 'profile') this.showJoints(this.profileJoints()); // its own joints, untouched
    const chosen = [...this.root.querySelectorAll('input[name=joint]:checked')].map((b) => b.value);
    const own = this.profileJoints();
    const sameJoints = chosen.length === own.length && own.every((j) => chosen.includes(j));
    const knobs = { norm: $('norm').value, velocity_terms: $('velocity_terms').value, joints: sameJoints ? '' : chosen.join(','),
                    annotations: $('annotations').value.trim() };
    THRESHOLDS.forEach(([knob]) => { knobs[knob] = $(knob).value; });
    const message = {
      type: 'settings', profile: $('profile').value, graph: $('graph').value || null,
      collection: $('collection').value || null, knobs,
    };
    ['lead_time', 'arrival_radius'].forEach((name) => { // an empty field keeps the value in force
      if ($(name).value !== '') message[name] = Number($(name).value);
    });
    this.send(message);
  }

  // After every selection: the chosen snippet and the figures over the last selections.
  showReadout(choice) {
    const r = choice.readout;
    const $ = this.$;
    $('latency').textContent = `${fixed(r.latency_p50_ms, 1)} / ${fixed(r.latency_p99_ms, 1)} ms`;
    $('selections').textContent = String(r.selections);
    $('candidates').textContent = choice.candidates === null ? '-' : String(choice.candidates);
    $('relax').textContent = `${choice.relax_level ?? '-'} (relaxed ${fixed(100 * (r.relaxed_share || 0), 0)}%)`;
    $('seams').textContent = `r median ${fixed(r.seam_ratio_median, 2)}, max ${fixed(r.seam_ratio_max, 2)}; ${fixed(100 * (r.seam_rough_share || 0), 0)}% over 1`;
    $('snippet').textContent = `${choice.snippet_id} (clip ${choice.clip_id}${choice.mirrored ? ', mirrored' : ''})`;
    $('node').textContent = choice.node ?? '-'; // a standby's name, or "primary"
    // where the snippet's motion was captured (a retargeted clip's origin) and under which terms
    const source = choice.source;
    $('source').textContent = source ? source.collection : '-';
    $('source').title = source ? (source.licence || 'licence not recorded') : '';
  }
}
