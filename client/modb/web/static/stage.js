// The three.js stage: ground grid, camera that orbits or follows, and the figure drawn as bones and joints.
import * as THREE from 'three';
import { OrbitControls } from 'three/addons/controls/OrbitControls.js';

const JOINT_RADIUS = 0.02; // metres
const MAX_BONES = 256;

// Ground lines every `step` metres out to `half` metres, cut into step-long pieces: a line whose ends lie
// behind the camera can vanish whole on software renderers (headless Chromium's SwiftShader did).
function groundGrid(half, step) {
  const points = [];
  for (let a = -half; a <= half; a += step) {
    for (let b = -half; b < half; b += step) points.push(a, 0, b, a, 0, b + step, b, 0, a, b + step, 0, a);
  }
  const geometry = new THREE.BufferGeometry();
  geometry.setAttribute('position', new THREE.Float32BufferAttribute(points, 3));
  return new THREE.LineSegments(geometry, new THREE.LineBasicMaterial({ color: 0xb0b0b0 }));
}

export class Stage {
  constructor(container) {
    this.container = container;
    this.renderer = new THREE.WebGLRenderer({ antialias: true });
    this.renderer.setPixelRatio(window.devicePixelRatio);
    container.appendChild(this.renderer.domElement);
    this.scene = new THREE.Scene();
    this.scene.background = new THREE.Color(0xf4f4f4);
    this.scene.add(groundGrid(20, 1));
    this.camera = new THREE.PerspectiveCamera(45, 1, 0.01, 500);
    this.camera.position.set(2.5, 1.8, 3.5);
    this.controls = new OrbitControls(this.camera, this.renderer.domElement);
    this.controls.target.set(0, 0.9, 0);
    this.controls.update();

    const lines = new THREE.BufferGeometry();
    lines.setAttribute('position', new THREE.BufferAttribute(new Float32Array(MAX_BONES * 6), 3));
    this.bones = new THREE.LineSegments(lines, new THREE.LineBasicMaterial({ color: 0x1f4e8c }));
    this.bones.frustumCulled = false;
    this.scene.add(this.bones);
    this.jointMesh = null;
    const axes = new THREE.BufferGeometry();
    axes.setAttribute('position', new THREE.BufferAttribute(new Float32Array(MAX_BONES * 6), 3));
    axes.setAttribute('color', new THREE.BufferAttribute(new Float32Array(MAX_BONES * 6), 3));
    this.axes = new THREE.LineSegments(axes, new THREE.LineBasicMaterial({ vertexColors: true, depthTest: false }));
    this.axes.frustumCulled = false;
    this.axes.renderOrder = 1; // over the character: the axes sit inside its limbs
    this.axes.visible = false;
    this.scene.add(this.axes);
    this.highlight = new THREE.Mesh(new THREE.SphereGeometry(JOINT_RADIUS * 2, 16, 12),
                                    new THREE.MeshBasicMaterial({ color: 0xe0402a, depthTest: false }));
    this.highlight.renderOrder = 2; // seen through the character: the joint selected sits inside it
    this.highlight.visible = false;
    this.scene.add(this.highlight);
    this.followed = null; // the last followed point, so the camera moves by the figure's travel
    this.character = null; // a skinned mesh (character.js) shown beside or instead of the bones
    const light = new THREE.HemisphereLight(0xffffff, 0x8a8a8a, 2.2);
    const sun = new THREE.DirectionalLight(0xffffff, 1.6);
    sun.position.set(3, 6, 2);
    this.scene.add(light, sun);

    new ResizeObserver(() => this.resize()).observe(container);
    this.resize();
  }

  resize() {
    const { clientWidth: w, clientHeight: h } = this.container;
    if (!w || !h) return;
    this.renderer.setSize(w, h);
    this.camera.aspect = w / h;
    this.camera.updateProjectionMatrix();
  }

  // A new figure: joint spheres sized to its joint count; the camera frames it unless keepView.
  setFigure(jointCount, at, keepView = false) {
    if (this.jointMesh) {
      this.scene.remove(this.jointMesh);
      this.jointMesh.geometry.dispose();
      this.jointMesh.material.dispose();
      this.jointMesh.dispose();
    }
    this.jointMesh = new THREE.InstancedMesh(new THREE.SphereGeometry(JOINT_RADIUS, 10, 8),
                                             new THREE.MeshBasicMaterial({ color: 0x333333 }), jointCount);
    this.jointMesh.frustumCulled = false;
    this.jointMesh.visible = this.skeletonShown !== false;
    this.scene.add(this.jointMesh);
    const target = new THREE.Vector3(at[0], Math.max(at[1], 0.5), at[2]);
    if (!keepView) {
      this.camera.position.copy(target).add(new THREE.Vector3(2.5, 0.9, 3.5));
      this.controls.target.copy(target);
      this.controls.update();
    }
    this.followed = target.clone();
  }

  // The character to show (null: none); the previous one goes.
  setCharacter(character) {
    if (this.character) this.scene.remove(this.character.object);
    this.character = character;
    if (character) this.scene.add(character.object);
  }

  // The bones and joint spheres: shown, or hidden behind the character.
  showSkeleton(shown) {
    this.bones.visible = shown;
    if (this.jointMesh) this.jointMesh.visible = shown;
    this.skeletonShown = shown;
  }

  // follow: the camera moves with `positions[pelvis]` on the ground.
  draw(segments, positions, pelvis, highlighted, follow) {
    const buffer = this.bones.geometry.attributes.position;
    segments.slice(0, MAX_BONES).forEach(([a, b], i) => { buffer.setXYZ(2 * i, a.x, a.y, a.z); buffer.setXYZ(2 * i + 1, b.x, b.y, b.z); });
    buffer.needsUpdate = true;
    this.bones.geometry.setDrawRange(0, 2 * Math.min(segments.length, MAX_BONES));
    const m = new THREE.Matrix4();
    positions.forEach((p, i) => this.jointMesh.setMatrixAt(i, m.makeTranslation(p[0], p[1], p[2])));
    this.jointMesh.instanceMatrix.needsUpdate = true;
    this.highlight.visible = highlighted !== null;
    if (highlighted !== null) this.highlight.position.fromArray(positions[highlighted]);
    if (this.followed) { // the root's travel on the ground; the camera keeps its place relative to it
      const now = new THREE.Vector3(positions[pelvis][0], this.followed.y, positions[pelvis][2]);
      if (follow) {
        const travel = now.clone().sub(this.followed);
        this.camera.position.add(travel);
        this.controls.target.add(travel);
      }
      this.followed = now;
    }
  }

  // The joint axes (Rig.axisSegments), or none.
  drawAxes(segments) {
    const position = this.axes.geometry.attributes.position;
    const colour = this.axes.geometry.attributes.color;
    const shown = (segments || []).slice(0, MAX_BONES);
    const c = new THREE.Color();
    shown.forEach(([a, b, hex], i) => {
      position.setXYZ(2 * i, a.x, a.y, a.z);
      position.setXYZ(2 * i + 1, b.x, b.y, b.z);
      c.setHex(hex);
      colour.setXYZ(2 * i, c.r, c.g, c.b);
      colour.setXYZ(2 * i + 1, c.r, c.g, c.b);
    });
    position.needsUpdate = true;
    colour.needsUpdate = true;
    this.axes.geometry.setDrawRange(0, 2 * shown.length);
    this.axes.visible = shown.length > 0;
  }

  // The joint spheres' centres and the bone lines' end points, read back from the scene's buffers.
  drawn() {
    const m = new THREE.Matrix4();
    const p = new THREE.Vector3();
    const joints = [];
    for (let i = 0; this.jointMesh && i < this.jointMesh.count; i++) {
      this.jointMesh.getMatrixAt(i, m);
      joints.push(p.setFromMatrixPosition(m).toArray());
    }
    const buffer = this.bones.geometry.attributes.position;
    const ends = [];
    const shown = Math.min(this.bones.geometry.drawRange.count, buffer.count);
    for (let i = 0; i < shown; i++) ends.push([buffer.getX(i), buffer.getY(i), buffer.getZ(i)]);
    return { joints, boneEnds: ends };
  }

  // The point on the ground (y = 0) under a pointer at (clientX, clientY), or null (the sky).
  groundPointAt(clientX, clientY) {
    this.camera.updateMatrixWorld(); // the view may have moved since the last render
    const rect = this.renderer.domElement.getBoundingClientRect();
    const ndc = new THREE.Vector2(((clientX - rect.left) / rect.width) * 2 - 1, -((clientY - rect.top) / rect.height) * 2 + 1);
    const ray = new THREE.Raycaster();
    ray.setFromCamera(ndc, this.camera);
    const hit = new THREE.Vector3();
    return ray.ray.intersectPlane(new THREE.Plane(new THREE.Vector3(0, 1, 0), 0), hit) ? hit : null;
  }

  // Look from `eye` at `target` (world points).
  look(eye, target) {
    this.camera.position.fromArray(eye);
    this.controls.target.fromArray(target);
    this.controls.update();
  }

  // Where a world point shows on the canvas, in pixels from its centre (as WebDriver's pointer offsets are).
  offsetOf(x, y, z) {
    this.camera.updateMatrixWorld(); // the view may have moved since the last render
    const p = new THREE.Vector3(x, y, z).project(this.camera);
    const { clientWidth: w, clientHeight: h } = this.renderer.domElement;
    return { x: (p.x * w) / 2, y: (-p.y * h) / 2, visible: Math.abs(p.x) < 1 && Math.abs(p.y) < 1 && p.z < 1 };
  }

  render() {
    this.controls.update();
    this.renderer.render(this.scene, this.camera);
  }
}
