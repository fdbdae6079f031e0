// A skeleton as a three.js Object3D hierarchy, posed from the stored frames. The browser does its own
// forward kinematics (three.js matrices), so the server's positions are an independent check of the page.
import * as THREE from 'three';

export class Rig {
  // pelvisName: the skeleton's joint map entry for pelvis (the body's travel); the joints above it, like
  // Bandai's joint_Root on the ground at the origin, are frames of reference, not bones.
  constructor(hierarchy, pelvisName) {
    this.joints = hierarchy.joints;
    const named = this.joints.findIndex((j) => j.name === pelvisName);
    this.pelvis = named >= 0 ? named : 0;
    this.abovePelvis = []; // its ancestors (frames of reference): indices
    for (let k = this.joints[this.pelvis].parent; k >= 0; k = this.joints[k].parent) this.abovePelvis.push(k);
    this.translated = hierarchy.translated;
    this.root = new THREE.Group();
    // Each joint sits at its offset in the parent's frame; joints with position channels replace it per frame.
    this.nodes = this.joints.map((j) => {
      const node = new THREE.Object3D();
      node.name = j.name;
      node.position.fromArray(j.offset);
      return node;
    });
    this.nodes.forEach((node, i) => (this.joints[i].parent < 0 ? this.root : this.nodes[this.joints[i].parent]).add(node));
    // End sites: drawn (the tips of head, hands, feet) but not joints of the data.
    this.ends = [];
    this.joints.forEach((j, i) => {
      if (!j.end_site) return;
      const tip = new THREE.Object3D();
      tip.position.fromArray(j.end_site);
      this.nodes[i].add(tip);
      this.ends.push({ parent: i, node: tip });
    });
  }

  // One frame: rotations[j] = [w, x, y, z] relative to the parent; translations[k] for joint translated[k].
  pose(rotations, translations) {
    rotations.forEach((q, i) => this.nodes[i].quaternion.set(q[1], q[2], q[3], q[0]));
    this.translated.forEach((j, k) => this.nodes[j].position.fromArray(translations[k]));
    this.root.updateMatrixWorld(true);
  }

  worldPositions() {
    return this.nodes.map((node) => node.getWorldPosition(new THREE.Vector3()).toArray());
  }

  // The joint coordinate systems (modb.skeletons.joint_axes: per mapped joint a twist and a swing axis in
  // its own frame) as world segments [from, to, colour] of `length` metres: twist red, swing green.
  axisSegments(jointAxes, length = 0.12) {
    const out = [];
    Object.values((jointAxes && jointAxes.joints) || {}).forEach((axes) => {
      const node = this.nodes[this.joints.findIndex((j) => j.name === axes.joint)];
      if (!node) return;
      const at = node.getWorldPosition(new THREE.Vector3());
      const turn = node.getWorldQuaternion(new THREE.Quaternion());
      [[axes.twist, 0xd03020], [axes.swing, 0x20a040]].forEach(([v, colour]) => {
        out.push([at, new THREE.Vector3().fromArray(v).applyQuaternion(turn).multiplyScalar(length).add(at), colour]);
      });
    });
    return out;
  }

  // Bone segments as pairs of world points: every joint to its parent (the pelvis aside), and every end
  // site to its joint.
  boneSegments() {
    const at = (node) => node.getWorldPosition(new THREE.Vector3());
    const pairs = [];
    this.joints.forEach((j, i) => { if (j.parent >= 0 && i !== this.pelvis) pairs.push([at(this.nodes[j.parent]), at(this.nodes[i])]); });
    this.ends.forEach((e) => pairs.push([at(this.nodes[e.parent]), at(e.node)]));
    return pairs;
  }
}
