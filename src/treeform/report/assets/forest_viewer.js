/* treeform's forest viewer: relief-mapped RDM impostors far away, clipped billboard clouds near
   (Argudo et al. 2016 §4.1-4.2), as three.js RawShaderMaterials whose GLSL is the renderer's own
   (sent by forest_data.js: window.__tf_forest). Classic script (works from file://); needs
   three-modules.js first. State for tests: window.treeformViewerState. */
(function () {
  'use strict';
  const THREE = __tf_require('three');
  const { GLTFLoader } = __tf_require('three/addons/loaders/GLTFLoader.js');
  const { OrbitControls } = __tf_require('three/addons/controls/OrbitControls.js');
  const D = window.__tf_forest;
  window.treeformViewerState = { done: false, error: null, near: 0, far: 0, cards: 0, billboards: 0, culled: 0 };

  function bytes(b64) {
    const bin = atob(b64), out = new Uint8Array(bin.length);
    for (let i = 0; i < bin.length; i++) out[i] = bin.charCodeAt(i);
    return out;
  }
  const floats = (b64) => new Float32Array(bytes(b64).buffer);

  function volume(O) {  // the opacity grid: half floats, x fastest, linearly filtered, clamped to its edge
    const n = O ? O.res : 1;
    const t = new THREE.Data3DTexture(O ? new Uint16Array(bytes(O.sigma).buffer) : new Uint16Array(1), n, n, n);
    t.format = THREE.RedFormat; t.type = THREE.HalfFloatType;
    t.minFilter = t.magFilter = O ? THREE.LinearFilter : THREE.NearestFilter;
    t.wrapS = t.wrapT = t.wrapR = THREE.ClampToEdgeWrapping;
    t.generateMipmaps = false; t.unpackAlignment = 1; t.flipY = false;
    t.needsUpdate = true;
    return t;
  }

  function vec4s(flat, n) {  // a uniform vec4[n] array from its flat floats (zeros without them)
    const out = [];
    for (let i = 0; i < n; i++) out.push(flat ? new THREE.Vector4().fromArray(flat, 4 * i) : new THREE.Vector4());
    return out;
  }

  function cube(faces, res, format, type) {  // six DataTextures, OpenGL face order, rows as stored
    const tex = new THREE.CubeTexture(faces.map(function (f) {
      const t = new THREE.DataTexture(f, res, res, format, type);
      t.needsUpdate = true;
      return t;
    }));
    tex.format = format; tex.type = type;
    tex.minFilter = tex.magFilter = type === THREE.FloatType ? THREE.NearestFilter : THREE.LinearFilter;
    tex.generateMipmaps = false;
    tex.flipY = false;
    tex.needsUpdate = true;
    return tex;
  }

  function rgbaTexture(b64, size, nearest) {
    const t = new THREE.DataTexture(bytes(b64), size, size, THREE.RGBAFormat, THREE.UnsignedByteType);
    t.minFilter = nearest ? THREE.NearestFilter : THREE.LinearMipmapLinearFilter;
    t.magFilter = nearest ? THREE.NearestFilter : THREE.LinearFilter;
    t.generateMipmaps = !nearest;
    t.flipY = false;
    t.needsUpdate = true;
    return t;
  }

  const yawRotate = (x, y, z, yaw) => [Math.cos(yaw) * x + Math.sin(yaw) * z, y, -Math.sin(yaw) * x + Math.cos(yaw) * z];

  function lightUniforms() {
    const L = D.lighting;
    return {
      u_light: { value: new THREE.Vector3().fromArray(L.direction) }, u_key: { value: new THREE.Vector3().fromArray(L.key) },
      u_sky: { value: new THREE.Vector3().fromArray(L.sky) }, u_ground: { value: new THREE.Vector3().fromArray(L.ground) },
    };
  }

  function species(S, k, scene, shared) {
    const res = S.rdm.res, per = res * res;
    const radii = floats(S.rdm.radii);
    const rdm = cube([0, 1, 2, 3, 4, 5].map((f) => radii.subarray(f * per, (f + 1) * per)), res, THREE.RedFormat, THREE.FloatType);
    const cf = S.color.face, rgb = bytes(S.color.rgb), cper = cf * cf;
    const color = cube([0, 1, 2, 3, 4, 5].map(function (f) {
      const out = new Uint8Array(cper * 4);
      for (let i = 0; i < cper; i++) {
        out[4 * i] = rgb[3 * (f * cper + i)]; out[4 * i + 1] = rgb[3 * (f * cper + i) + 1];
        out[4 * i + 2] = rgb[3 * (f * cper + i) + 2]; out[4 * i + 3] = 255;
      }
      return out;
    }), cf, THREE.RGBAFormat, THREE.UnsignedByteType);
    const lo = S.box[0], hi = S.box[1], c = S.rdm.center;
    // relief: the RDM's box, drawn once per far tree (its far faces: THREE.BackSide)
    const corners = [];
    for (const x of [lo[0], hi[0]]) for (const y of [lo[1], hi[1]]) for (const z of [lo[2], hi[2]]) corners.push(x, y, z);
    const box = new THREE.InstancedBufferGeometry();
    box.setAttribute('in_pos', new THREE.BufferAttribute(new Float32Array(corners), 3));
    box.setAttribute('position', box.getAttribute('in_pos'));
    box.setIndex([0, 1, 3, 0, 3, 2, 4, 6, 7, 4, 7, 5, 0, 4, 5, 0, 5, 1, 2, 3, 7, 2, 7, 6, 0, 2, 6, 0, 6, 4, 1, 5, 7, 1, 7, 3]);
    const relief = new THREE.RawShaderMaterial(Object.assign({
      glslVersion: THREE.GLSL3, vertexShader: D.shaders.relief_vs, fragmentShader: D.shaders.relief_fs,
      side: THREE.BackSide,
      uniforms: Object.assign({
        u_view: shared.view, u_proj: shared.proj, u_eye: shared.eye, u_rdm: { value: rdm }, u_color: { value: color },
        u_front: { value: shared.blank }, u_planar: { value: 0 }, u_center: { value: new THREE.Vector3().fromArray(c) },
        u_lo: { value: new THREE.Vector3().fromArray(lo) }, u_hi: { value: new THREE.Vector3().fromArray(hi) },
        u_rmin: { value: S.rmin }, u_rmax: { value: S.rmax },
        u_steps: { value: D.relief_steps }, u_refine: { value: D.relief_refine },
        u_eps: { value: 0.5 * Math.max(hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]) / res }, u_id: { value: 2001 + k },
        u_right: { value: new THREE.Vector3() }, u_up: { value: new THREE.Vector3() }, u_front_px: { value: new THREE.Vector2() },
        u_front_size: { value: new THREE.Vector2(1, 1) }, u_front_scale: { value: 1 },
        // the porous crown (render/impostor.py): Beer-Lambert through the opacity grid when the species has one
        u_opacity: { value: volume(S.opacity) }, u_use_opacity: { value: S.opacity ? 1 : 0 },
        u_olo: { value: new THREE.Vector3().fromArray(S.opacity ? S.opacity.origin : [0, 0, 0]) },
        u_oext: { value: S.opacity ? S.opacity.extent : 1 }, u_osteps: { value: D.relief_steps },
        u_ovox: { value: S.opacity ? S.opacity.extent / S.opacity.res : 1 },
        // its capsules of wood (the trunk and thick limbs a grid of its voxel would fade), bark-coloured
        u_nwood: { value: S.opacity ? S.opacity.nwood : 0 },
        u_wa: { value: vec4s(S.opacity ? S.opacity.wood_a : null, D.max_wood) },
        u_wb: { value: vec4s(S.opacity ? S.opacity.wood_b : null, D.max_wood) },
        u_wg: { value: vec4s(S.opacity ? S.opacity.wood_g : null, D.wood_groups) },
        u_bark: { value: new THREE.Vector3().fromArray(S.opacity ? S.opacity.bark : [0.35, 0.28, 0.22]) },
      }, lightUniforms()),
    }));
    const reliefMesh = new THREE.Mesh(box, relief);
    reliefMesh.frustumCulled = false;
    scene.add(reliefMesh);
    // clipped billboard cloud: one quad per billboard of every near tree (WebGL has no geometry shader)
    const quad = new THREE.InstancedBufferGeometry();
    quad.setAttribute('in_corner', new THREE.BufferAttribute(new Float32Array([-1, -1, 1, -1, 1, 1, -1, 1]), 2));
    quad.setAttribute('position', new THREE.BufferAttribute(new Float32Array(12), 3));
    quad.setIndex([0, 1, 2, 0, 2, 3]);
    const L = S.leaflet;
    const cloud = new THREE.RawShaderMaterial({
      glslVersion: THREE.GLSL3, vertexShader: D.shaders.cloud_vs, fragmentShader: D.shaders.cloud_fs,
      side: THREE.DoubleSide,
      uniforms: Object.assign({
        u_view: shared.view, u_proj: shared.proj, u_eye: shared.eye,
        u_rgba: { value: rgbaTexture(L.rgba, L.size, false) }, u_shade: { value: rgbaTexture(L.shade, L.size, false) },
        u_geo: { value: rgbaTexture(L.geo, L.size, true) }, u_rdm: { value: rdm }, u_color: { value: color },
        u_center: { value: new THREE.Vector3().fromArray(c) }, u_clip: { value: 1 }, u_tint: { value: 1 },
        u_leaf_luma: { value: L.luma }, u_cutoff: { value: 0.5 }, u_id: { value: 1001 + k }, u_ao: { value: D.cloud_ao },
      }, lightUniforms()),
    });
    const cloudMesh = new THREE.Mesh(quad, cloud);
    cloudMesh.frustumCulled = false;
    scene.add(cloudMesh);
    const sp = { S: S, points: floats(S.cloud.points), box: box, quad: quad, reliefMesh: reliefMesh, cloudMesh: cloudMesh,
      wood: null, cards: null };
    // the instanced meshes of a GLB (the wood of near trees; the impostor cards of the farthest crowns)
    function instanced(b64, key) {
      new GLTFLoader().parse(bytes(b64).buffer, '', function (gltf) {
        const meshes = [];
        gltf.scene.traverse(function (o) { if (o.isMesh) meshes.push(o); });
        sp[key] = meshes.map(function (m) {
          // display colours, as the renderer shows them: the GLB's textures are not decoded from sRGB
          for (const t of ['map', 'normalMap']) if (m.material[t]) { m.material[t].colorSpace = THREE.NoColorSpace; m.material[t].needsUpdate = true; }
          const im = new THREE.InstancedMesh(m.geometry, m.material, D.trees_count);
          im.count = 0; im.frustumCulled = false;
          scene.add(im);
          return im;
        });
        shared.loaded += 1;
        shared.update();
      }, function (e) { window.treeformViewerState.error = String(e); });
    }
    instanced(S.wood, 'wood');
    if (S.cards && D.card_px > 0) instanced(S.cards, 'cards');
    return sp;
  }

  function main() {
    const canvas = document.getElementById('tf-viewer');
    // colours are display colours, as in treeform's renderer (the shaders write them as they are)
    THREE.ColorManagement.enabled = false;
    const renderer = new THREE.WebGLRenderer({ canvas: canvas, antialias: false, preserveDrawingBuffer: true });
    renderer.outputColorSpace = THREE.LinearSRGBColorSpace;
    renderer.setPixelRatio(1);
    renderer.setSize(canvas.clientWidth, canvas.clientHeight, false);
    const scene = new THREE.Scene();
    scene.background = new THREE.Color().fromArray(D.sky);
    const L = D.lighting;
    scene.add(new THREE.HemisphereLight(new THREE.Color().fromArray(L.sky), new THREE.Color().fromArray(L.ground), Math.PI));
    const sun = new THREE.DirectionalLight(new THREE.Color().fromArray(L.key), Math.PI);
    sun.position.fromArray(L.direction);
    scene.add(sun);
    const ground = new THREE.Mesh(new THREE.PlaneGeometry(D.area[0] + 100, D.area[1] + 100).rotateX(-Math.PI / 2),
      new THREE.MeshLambertMaterial({ color: new THREE.Color().fromArray(D.ground) }));
    scene.add(ground);
    const cam = D.camera;
    const camera = new THREE.PerspectiveCamera(cam.fov, canvas.clientWidth / canvas.clientHeight, cam.near, cam.far);
    camera.position.fromArray(cam.position);
    const controls = new OrbitControls(camera, canvas);
    controls.target.fromArray(cam.target);
    controls.update();
    const shared = {
      view: { value: new THREE.Matrix4() }, proj: { value: new THREE.Matrix4() }, eye: { value: new THREE.Vector3() },
      blank: new THREE.DataTexture(new Uint8Array(4), 1, 1), loaded: 0, update: null,
    };
    shared.blank.needsUpdate = true;
    const trees = floats(D.trees);  // (N, 7): x, y, z, scale, yaw, 0, species
    const list = D.species.map((S, k) => species(S, k, scene, shared));
    const toLoad = D.species.reduce((n, S) => n + 1 + (S.cards && D.card_px > 0 ? 1 : 0), 0);
    const tmp = new THREE.Matrix4(), q = new THREE.Quaternion(), sv = new THREE.Vector3(), tv = new THREE.Vector3();
    const up = new THREE.Vector3(0, 1, 0);

    function update() {  // the LoD switch for the camera where it is now, then one frame
      camera.updateMatrixWorld();
      shared.view.value.copy(camera.matrixWorldInverse);
      shared.proj.value.copy(camera.projectionMatrix);
      shared.eye.value.copy(camera.position);
      const focal = 0.5 * canvas.clientHeight / Math.tan(THREE.MathUtils.degToRad(camera.fov / 2));
      const fwd = new THREE.Vector3(); camera.getWorldDirection(fwd);
      // frustum culling: a tree whose bounding sphere (crown and trunk) misses the view is not drawn
      const frustum = new THREE.Frustum().setFromProjectionMatrix(
        new THREE.Matrix4().multiplyMatrices(camera.projectionMatrix, camera.matrixWorldInverse));
      const sphere = new THREE.Sphere();
      let near = 0, far = 0, cards = 0, billboards = 0, culled = 0;
      for (let k = 0; k < list.length; k++) {
        const sp = list[k], S = sp.S, c = S.rdm.center, P = sp.points.length / 3;
        const farRows = [], bb = [], inst = [], extra = [], wood = [], card = [];
        for (let i = 0; i < D.trees_count; i++) {
          if (trees[7 * i + 6] !== k) continue;
          const x = trees[7 * i], y = trees[7 * i + 1], z = trees[7 * i + 2], s = trees[7 * i + 3], yaw = trees[7 * i + 4];
          const w = yawRotate(c[0] * s, c[1] * s, c[2] * s, yaw);
          const dx = x + w[0] - camera.position.x, dy = y + w[1] - camera.position.y, dz = z + w[2] - camera.position.z;
          const along = dx * fwd.x + dy * fwd.y + dz * fwd.z, r = S.radius * s;
          sphere.center.set(x + w[0], y + w[1], z + w[2]);
          sphere.radius = r + Math.hypot(c[0], c[1], c[2]) * s;  // the crown's reach plus its height over the foot
          if (!frustum.intersectsSphere(sphere)) { culled++; continue; }
          const px = 2 * r * focal / Math.max(along, camera.near);
          if (Math.hypot(dx, dy, dz) >= D.switch_distance) {
            // a crown a few pixels wide: its impostor cards (as treeform's renderer draws it), else the relief march
            if (sp.cards && px < D.card_px) {
              card.push(tmp.compose(tv.set(x, y, z), q.setFromAxisAngle(up, yaw), sv.set(s, s, s)).clone()); cards++;
            } else { farRows.push(x, y, z, s, yaw, 0); far++; }
            continue;
          }
          near++;
          const count = Math.max(16, Math.min(144, Math.round(144 * Math.pow(px / D.full_px, 2))));
          const edge = S.cloud.size * s * Math.sqrt(P / Math.min(count, P));
          for (let j = 0; j < Math.min(count, P); j++) {
            const p = yawRotate(sp.points[3 * j] * s, sp.points[3 * j + 1] * s, sp.points[3 * j + 2] * s, yaw);
            const h = Math.sin(j * 12.9898 + 4.1414) * 43758.5453;
            bb.push(x + p[0], y + p[1], z + p[2], edge); inst.push(x, y, z, s); extra.push(yaw, (h - Math.floor(h)) * 6.2831853);
          }
          billboards += Math.min(count, P);
          wood.push(tmp.compose(tv.set(x, y, z), q.setFromAxisAngle(up, yaw), sv.set(s, s, s)).clone());
        }
        const fr = new Float32Array(farRows);
        sp.box.setAttribute('in_inst', new THREE.InstancedBufferAttribute(fr.filter((_, i) => i % 6 < 4), 4));
        sp.box.setAttribute('in_extra', new THREE.InstancedBufferAttribute(fr.filter((_, i) => i % 6 >= 4), 2));
        sp.box.instanceCount = fr.length / 6;
        sp.quad.setAttribute('in_bb', new THREE.InstancedBufferAttribute(new Float32Array(bb), 4));
        sp.quad.setAttribute('in_inst', new THREE.InstancedBufferAttribute(new Float32Array(inst), 4));
        sp.quad.setAttribute('in_extra', new THREE.InstancedBufferAttribute(new Float32Array(extra), 2));
        sp.quad.instanceCount = bb.length / 4;
        for (const [ims, mats] of [[sp.wood, wood], [sp.cards, card]]) if (ims) for (const im of ims) {
          mats.forEach((m, i) => im.setMatrixAt(i, m));
          im.count = mats.length;
          im.instanceMatrix.needsUpdate = true;
        }
      }
      renderer.render(scene, camera);
      Object.assign(window.treeformViewerState, { near: near, far: far, cards: cards, billboards: billboards,
        culled: culled, done: shared.loaded === toLoad, calls: renderer.info.render.calls });
    }
    shared.update = update;
    controls.addEventListener('change', update);
    update();
  }

  try { main(); } catch (e) { window.treeformViewerState.error = String(e); throw e; }
})();
