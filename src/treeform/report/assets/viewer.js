/* treeform's 3D viewer for report pages: GLBs side by side in one canvas, orbit controls.
   Classic script (works from file://): the GLBs come as scripts that set
   window.__tf_glb[key] = base64, loaded when a case is shown. Needs three-modules.js first. */
(function () {
  'use strict';
  const THREE = __tf_require('three');
  const { GLTFLoader } = __tf_require('three/addons/loaders/GLTFLoader.js');
  const { OrbitControls } = __tf_require('three/addons/controls/OrbitControls.js');
  const glbs = (window.__tf_glb = window.__tf_glb || {});
  let view = null;

  function setup(canvas) {
    const renderer = new THREE.WebGLRenderer({ canvas: canvas, antialias: true, preserveDrawingBuffer: true });
    renderer.setPixelRatio(window.devicePixelRatio || 1);
    renderer.setSize(canvas.clientWidth, canvas.clientHeight, false);
    const scene = new THREE.Scene();
    scene.background = new THREE.Color(0xf3f5f7);
    scene.add(new THREE.HemisphereLight(0xffffff, 0x5a6650, 1.6));
    const sun = new THREE.DirectionalLight(0xffffff, 2.2);
    sun.position.set(4, 10, 6);
    scene.add(sun);
    const camera = new THREE.PerspectiveCamera(30, canvas.clientWidth / canvas.clientHeight, 0.05, 5000);
    const controls = new OrbitControls(camera, canvas);
    const draw = function () { renderer.render(scene, camera); };
    controls.addEventListener('change', draw);
    return { renderer: renderer, scene: scene, camera: camera, controls: controls, draw: draw, group: null };
  }

  function loadScript(src) {
    return new Promise(function (ok, fail) {
      const s = document.createElement('script');
      s.src = src;
      s.onload = ok;
      s.onerror = function () { fail(new Error('cannot load ' + src)); };
      document.head.appendChild(s);
    });
  }

  function decode(b64) {
    const bin = atob(b64), out = new Uint8Array(bin.length);
    for (let i = 0; i < bin.length; i++) out[i] = bin.charCodeAt(i);
    return out.buffer;
  }

  function dispose(obj) {
    obj.traverse(function (o) {
      if (o.geometry) o.geometry.dispose();
      const mats = o.material ? (Array.isArray(o.material) ? o.material : [o.material]) : [];
      mats.forEach(function (m) { if (m.map) m.map.dispose(); if (m.normalMap) m.normalMap.dispose(); m.dispose(); });
    });
  }

  /* items: [{key, src, label}]; the models stand side by side, left to right, on one ground line */
  async function show(title, items) {
    const canvas = document.getElementById('tf-viewer');
    if (!view) view = setup(canvas);
    window.treeformViewerState = { title: title, loaded: 0, expected: items.length, error: null };
    if (view.group) { view.scene.remove(view.group); dispose(view.group); }
    const group = new THREE.Group();
    const loader = new GLTFLoader();
    let x = 0;
    const labels = [];
    try {
      for (const it of items) {
        if (!(it.key in glbs)) await loadScript(it.src);
        const gltf = await new Promise(function (ok, fail) { loader.parse(decode(glbs[it.key]), '', ok, fail); });
        const obj = gltf.scene;
        const box = new THREE.Box3().setFromObject(obj);
        const w = Math.max(box.max.x - box.min.x, 1e-3);
        obj.position.x = x - box.min.x;
        obj.position.y = -box.min.y;
        x += w * 1.1;
        group.add(obj);
        labels.push(it.label);
        window.treeformViewerState.loaded += 1;
      }
    } catch (e) {
      window.treeformViewerState.error = String(e);
      throw e;
    }
    view.scene.add(group);
    view.group = group;
    const box = new THREE.Box3().setFromObject(group);
    const c = box.getCenter(new THREE.Vector3()), size = box.getSize(new THREE.Vector3());
    const r = 0.5 * Math.max(size.x / view.camera.aspect, size.y) / Math.tan(THREE.MathUtils.degToRad(view.camera.fov / 2));
    view.camera.position.set(c.x, c.y + 0.1 * size.y, c.z + 1.05 * r + 0.5 * size.z);
    view.camera.near = Math.max(0.01, r / 100);
    view.camera.far = 10 * (r + size.z + size.x);
    view.camera.updateProjectionMatrix();
    view.controls.target.copy(c);
    view.controls.update();
    view.draw();
    document.getElementById('tf-viewer-title').textContent = title + ': ' + labels.join('  |  ') + ' (left to right; drag to turn)';
    window.treeformViewerState.done = true;
  }

  window.treeformShow = show;
})();
