// What the avatar page draws on the ground besides the figure: the trail the pelvis left and the goals, and in the
// air the targets of the actions asked for (a sphere on a thin post from the ground).
import * as THREE from 'three';

const MAX_TRAIL = 50000; // points; a 30 fps walk adds one per 5 cm, so this is a long walk
const TRAIL_STEP = 0.05; // metres between trail points

function ring(color, radius) {
  const mesh = new THREE.Mesh(new THREE.RingGeometry(radius * 0.8, radius, 48),
                              new THREE.MeshBasicMaterial({ color, side: THREE.DoubleSide }));
  mesh.rotation.x = -Math.PI / 2;
  mesh.visible = false;
  return mesh;
}

export class Course {
  constructor(scene) {
    this.scene = scene;
    const geometry = new THREE.BufferGeometry();
    geometry.setAttribute('position', new THREE.BufferAttribute(new Float32Array(MAX_TRAIL * 3), 3));
    geometry.setDrawRange(0, 0);
    this.trailLine = new THREE.Line(geometry, new THREE.LineBasicMaterial({ color: 0x2a9d4b }));
    this.trailLine.frustumCulled = false;
    scene.add(this.trailLine);
    this.trail = []; // [x, z] pelvis ground points, every TRAIL_STEP metres
    this.current = ring(0xd62828, 0.5);
    scene.add(this.current);
    this.waypoints = [];
    this.radius = 0.5;
    this.targets = []; // [x, y, z] of the actions not yet done
    this.targetMarks = [];
  }

  // actions: [{primitive, target: [x, y, z], goal}], those not yet done (the server says when one is).
  setActions(actions) {
    this.targetMarks.forEach((mark) => {
      this.scene.remove(mark);
      mark.traverse((o) => { if (o.geometry) { o.geometry.dispose(); o.material.dispose(); } });
    });
    this.targets = actions.map((a) => a.target);
    this.targetMarks = this.targets.map(([x, y, z]) => {
      const mark = new THREE.Group();
      const sphere = new THREE.Mesh(new THREE.SphereGeometry(0.04, 16, 12), new THREE.MeshBasicMaterial({ color: 0x7b2cbf }));
      sphere.position.set(0, y, 0);
      const post = new THREE.Line(new THREE.BufferGeometry().setFromPoints([new THREE.Vector3(0, 0, 0), new THREE.Vector3(0, y, 0)]),
                                  new THREE.LineBasicMaterial({ color: 0x7b2cbf }));
      mark.add(sphere, post);
      mark.position.set(x, 0, z);
      this.scene.add(mark);
      return mark;
    });
  }

  addTrail(x, z) {
    const last = this.trail[this.trail.length - 1];
    if (last && Math.hypot(x - last[0], z - last[1]) < TRAIL_STEP) return;
    if (this.trail.length === MAX_TRAIL) this.trail = this.trail.slice(MAX_TRAIL / 2); // the older half goes
    this.trail.push([x, z]);
    const buffer = this.trailLine.geometry.attributes.position;
    const from = this.trail.length === MAX_TRAIL / 2 + 1 ? 0 : this.trail.length - 1; // all after a cut
    for (let i = from; i < this.trail.length; i++) buffer.setXYZ(i, this.trail[i][0], 0.005, this.trail[i][1]);
    buffer.needsUpdate = true;
    this.trailLine.geometry.setDrawRange(0, this.trail.length);
  }

  // goals: [[x, z], ...]; index: the one being served (marked with a ring of the arrival radius).
  setGoals(goals, index, radius) {
    if (radius !== this.radius) {
      this.scene.remove(this.current);
      this.current.geometry.dispose();
      this.current.material.dispose();
      this.current = ring(0xd62828, radius);
      this.scene.add(this.current);
      this.radius = radius;
    }
    const goal = goals[index];
    this.current.visible = Boolean(goal);
    if (goal) this.current.position.set(goal[0], 0.01, goal[goal.length - 1]);
    this.waypoints.forEach((w) => { this.scene.remove(w); w.geometry.dispose(); w.material.dispose(); });
    this.waypoints = goals.slice(index + 1).map((g) => {
      const w = ring(0xf4a261, 0.25);
      w.visible = true;
      w.position.set(g[0], 0.01, g[g.length - 1]);
      this.scene.add(w);
      return w;
    });
  }
}
