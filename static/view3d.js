// The 3D view of a solved 3d scene: its scene.glb (vertex colours, unlit) in three.js, seen
// first from the camera of image.png (the glb's camera node, its target in `extras.look_at`),
// then turned around with the mouse or a finger (OrbitControls). Drawn only when something
// changes. The drawing buffer is kept, so that the picture can be read back (tests, saving).
import * as THREE from "three";
import { GLTFLoader } from "/static/vendor/three/examples/jsm/loaders/GLTFLoader.js";
import { OrbitControls } from "/static/vendor/three/examples/jsm/controls/OrbitControls.js";

let view = null;

export function hasWebGL() {
  try {
    const c = document.createElement("canvas");
    return !!(window.WebGLRenderingContext && (c.getContext("webgl2") || c.getContext("webgl")));
  } catch (e) {
    return false;
  }
}

export function clear() {
  if (!view) return;
  view.controls.dispose();
  view.renderer.dispose();
  view.renderer.domElement.remove();
  window.removeEventListener("resize", view.resize);
  view = null;
}

// Loads `url` (a scene.glb) into a canvas appended to `container`.
export async function show(container, url) {
  clear();
  const gltf = await new GLTFLoader().loadAsync(url);
  const scene = new THREE.Scene();
  scene.background = new THREE.Color(0x000000);
  scene.add(gltf.scene);
  scene.updateMatrixWorld(true);

  const given = gltf.cameras[0];
  const aspect = (given && given.aspect) || 1;
  const camera = new THREE.PerspectiveCamera(given ? given.fov : 40, aspect, 0.1, 1e7);
  const target = new THREE.Vector3();
  const bounds = new THREE.Box3().setFromObject(gltf.scene);
  const size = bounds.getSize(new THREE.Vector3()).length() || 1;
  if (given) {
    given.getWorldPosition(camera.position);
    given.getWorldQuaternion(camera.quaternion);
    const lookAt = given.userData && given.userData.look_at;
    if (lookAt) target.fromArray(lookAt);
    else camera.getWorldDirection(target).multiplyScalar(size).add(camera.position);
  } else {
    bounds.getCenter(target);
    camera.position.copy(target).add(new THREE.Vector3(0, 0, -1.5 * size));
  }
  camera.near = size * 1e-3;
  camera.far = size * 100;
  camera.updateProjectionMatrix();

  const renderer = new THREE.WebGLRenderer({ antialias: true, preserveDrawingBuffer: true });
  renderer.setPixelRatio(window.devicePixelRatio || 1);
  renderer.domElement.id = "view3d-canvas";
  renderer.domElement.setAttribute("aria-label", "the solved scene in 3D; drag to turn it");
  container.appendChild(renderer.domElement);

  const controls = new OrbitControls(camera, renderer.domElement);
  controls.target.copy(target);
  controls.update();
  const render = () => renderer.render(scene, camera);
  controls.addEventListener("change", render);
  const resize = () => {
    const width = container.clientWidth || 400;
    renderer.setSize(width, Math.round(width / aspect));
    render();
  };
  window.addEventListener("resize", resize);
  view = { renderer, controls, camera, scene, render, resize };
  resize();
  return view;
}

// For the page's tests: the current view.
export function current() {
  return view;
}
