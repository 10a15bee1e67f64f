// A three.js view of calf-frame geometry (z up the leg), rendered on demand: a frame is
// drawn when the camera moves or the content changes, so a 100k-triangle surface turns
// smoothly without a busy loop.
let threePromise;
function loadThree() {
  threePromise ??= Promise.all([import('/web/vendor/three/three.module.js'), import('/web/vendor/three/OrbitControls.js')]);
  return threePromise;
}

export const colormaps = {
  // error: dark blue (0) -> teal -> amber -> red (top), saturated everywhere so that small
  // errors stay visible on the grey background (a white start vanished there);
  // pressure: viridis-like ramp; diverging: blue - white - red
  error: [[0, [0.10, 0.20, 0.70]], [0.35, [0.05, 0.60, 0.60]], [0.7, [0.98, 0.72, 0.10]], [1, [0.80, 0.08, 0.08]]],
  pressure: [[0, [0.27, 0.0, 0.33]], [0.25, [0.23, 0.32, 0.55]], [0.5, [0.13, 0.57, 0.55]], [0.75, [0.37, 0.79, 0.38]], [1, [0.99, 0.91, 0.14]]],
  diverging: [[0, [0.23, 0.30, 0.75]], [0.5, [0.87, 0.87, 0.87]], [1, [0.71, 0.02, 0.15]]],
};

export function colour(map, t) {
  const stops = colormaps[map];
  t = Math.min(1, Math.max(0, t));
  for (let k = 1; k < stops.length; k++) {
    if (t <= stops[k][0]) {
      const [t0, c0] = stops[k - 1], [t1, c1] = stops[k], f = (t - t0) / (t1 - t0 || 1);
      return [0, 1, 2].map((i) => c0[i] + f * (c1[i] - c0[i]));
    }
  }
  return stops[stops.length - 1][1];
}

export function legendRamp(map) {
  const stops = colormaps[map].map(([t, c]) => `rgb(${c.map((x) => Math.round(255 * x)).join(',')}) ${100 * t}%`);
  return `linear-gradient(to right, ${stops.join(', ')})`;
}

export async function createViewer(container) {
  const [THREE, { OrbitControls }] = await loadThree();
  const renderer = new THREE.WebGLRenderer({ antialias: true, preserveDrawingBuffer: true });
  renderer.setPixelRatio(Math.min(window.devicePixelRatio || 1, 2));
  container.append(renderer.domElement);
  renderer.domElement.setAttribute('role', 'img');
  renderer.domElement.setAttribute('aria-label', container.dataset.label || '3D view');
  const scene = new THREE.Scene();
  scene.background = new THREE.Color(0xeef1f5);
  const camera = new THREE.PerspectiveCamera(35, 1, 1, 5000);
  camera.up.set(0, 0, 1);
  scene.add(new THREE.HemisphereLight(0xffffff, 0x667788, 2.2));
  const sun = new THREE.DirectionalLight(0xffffff, 1.6);
  sun.position.set(300, 500, 400);
  scene.add(sun);
  const controls = new OrbitControls(camera, renderer.domElement);
  controls.enableDamping = false;
  const objects = new Map();
  const tags = [];
  let frame = 0;

  function resize() {
    const w = container.clientWidth || 600, h = container.clientHeight || 400;
    renderer.setSize(w, h, false);
    camera.aspect = w / h;
    camera.updateProjectionMatrix();
    render();
  }
  function placeTags() {
    const v = new THREE.Vector3();
    for (const tag of tags) {
      v.copy(tag.anchor).project(camera);
      tag.el.style.left = `${(v.x * 0.5 + 0.5) * container.clientWidth}px`;
      tag.el.style.top = `${(-v.y * 0.5 + 0.5) * container.clientHeight}px`;
      tag.el.hidden = v.z > 1;
    }
  }
  function render() {
    cancelAnimationFrame(frame);
    frame = requestAnimationFrame(() => { renderer.render(scene, camera); placeTags(); });
  }
  controls.addEventListener('change', render);
  new ResizeObserver(resize).observe(container);

  function put(name, object) {
    const old = objects.get(name);
    if (old) { scene.remove(old); old.geometry?.dispose(); }
    objects.set(name, object);
    scene.add(object);
    render();
    return object;
  }
  const api = {
    THREE,
    renderer,
    surface(name, positions, index, colors, opacity = 1) {
      const geometry = new THREE.BufferGeometry();
      geometry.setAttribute('position', new THREE.BufferAttribute(positions, 3));
      if (colors) geometry.setAttribute('color', new THREE.BufferAttribute(colors, 3));
      geometry.setIndex(new THREE.BufferAttribute(index, 1));
      geometry.computeVertexNormals();
      const material = new THREE.MeshStandardMaterial({ color: colors ? 0xffffff : 0xc9a88f, vertexColors: !!colors,
        roughness: 0.75, side: THREE.DoubleSide, transparent: opacity < 1, opacity });
      return put(name, new THREE.Mesh(geometry, material));
    },
    points(name, positions, colors, size = 2) {
      const geometry = new THREE.BufferGeometry();
      geometry.setAttribute('position', new THREE.BufferAttribute(positions, 3));
      if (colors) geometry.setAttribute('color', new THREE.BufferAttribute(colors, 3));
      const material = new THREE.PointsMaterial({ size, sizeAttenuation: false, vertexColors: !!colors, color: colors ? 0xffffff : 0x1d2430 });
      return put(name, new THREE.Points(geometry, material));
    },
    ring(name, points, label, color = 0x0b62c4) {
      const geometry = new THREE.BufferGeometry().setFromPoints(points.map((p) => new THREE.Vector3(...p)));
      const line = put(name, new THREE.LineLoop(geometry, new THREE.LineBasicMaterial({ color })));
      const el = document.createElement('span');
      el.className = 'tag ring';
      el.textContent = label;
      container.append(el);
      const far = points.reduce((best, p) => (p[0] > best[0] ? p : best), points[0]);
      tags.push({ el, anchor: new THREE.Vector3(...far) });
      return line;
    },
    marker(name, position, color = 0xd00000, radius = 4, label = null) {
      const mesh = new THREE.Mesh(new THREE.SphereGeometry(radius, 16, 12), new THREE.MeshBasicMaterial({ color }));
      mesh.position.set(...position);
      if (label) {
        const el = document.createElement('span');
        el.className = 'tag point';
        el.textContent = label;
        container.append(el);
        tags.push({ el, anchor: new THREE.Vector3(...position) });
      }
      return put(name, mesh);
    },
    visible(name, on) { const o = objects.get(name); if (o) { o.visible = on; render(); } },
    frameAll() {
      const box = new THREE.Box3();
      for (const o of objects.values()) box.expandByObject(o);
      const centre = box.getCenter(new THREE.Vector3()), size = box.getSize(new THREE.Vector3());
      const reach = Math.max(size.x, size.y, size.z);
      camera.position.set(centre.x + reach * 0.9, centre.y - reach * 1.6, centre.z + reach * 0.25);
      controls.target.copy(centre);
      camera.near = reach / 100; camera.far = reach * 20; camera.updateProjectionMatrix();
      controls.update();
      render();
    },
    render,
  };
  resize();
  return api;
}
