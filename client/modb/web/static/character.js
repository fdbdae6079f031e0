// The skeleton's character: a skinned mesh the server makes from the skeleton itself (capsule limbs,
// /api/skeletons/ID/character.glb, the same file `modb export --format gltf` writes), posed from the
// frames the rig is posed from. Its bones are the glTF's joints in skeleton order.
import { GLTFLoader } from 'three/addons/loaders/GLTFLoader.js';
import { clone } from 'three/addons/utils/SkeletonUtils.js';
import { token } from './token.js';

const loaded = new Map(); // skeleton id -> Promise of the glTF (each skeleton's file is fetched once)

export class Character {
  constructor(gltf, translated) {
    this.object = gltf.scene;
    this.mesh = null;
    this.object.traverse((o) => { if (o.isSkinnedMesh) this.mesh = o; });
    this.mesh.frustumCulled = false; // its bounds are the rest pose's; the character walks away from them
    this.bones = this.mesh.skeleton.bones;
    this.translated = translated;
  }

  // One frame, as Rig.pose takes it: rotations[j] = [w, x, y, z]; translations[k] for joint translated[k].
  pose(rotations, translations) {
    rotations.forEach((q, i) => this.bones[i].quaternion.set(q[1], q[2], q[3], q[0]));
    this.translated.forEach((j, k) => this.bones[j].position.fromArray(translations[k]));
    this.object.updateMatrixWorld(true);
  }
}

export async function loadCharacter(skeletonId, translated) {
  if (!loaded.has(skeletonId)) loaded.set(skeletonId, new GLTFLoader().setRequestHeader(token.headers()).loadAsync(`/api/skeletons/${skeletonId}/character.glb`));
  const gltf = await loaded.get(skeletonId);
  // a fresh copy of the scene each time (a clip and the next of the same skeleton do not share bones)
  return new Character({ scene: clone(gltf.scene) }, translated);
}

// A file the server sent (base64) saved by the browser under its name.
export function saveFile(name, mediaType, base64) {
  const bytes = Uint8Array.from(atob(base64), (c) => c.charCodeAt(0));
  const link = document.createElement('a');
  link.href = URL.createObjectURL(new Blob([bytes], { type: mediaType }));
  link.download = name;
  document.body.appendChild(link);
  link.click();
  link.remove();
  setTimeout(() => URL.revokeObjectURL(link.href), 10000);
}
