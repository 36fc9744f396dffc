// Batteur live view: draws the drummer and the kit from the graphics node's WebSocket stream.
// Frame: metres, z up, the drummer at the origin facing +y, +x to the drummer's right.
// Messages from the node (JSON): kit (with its hardware), hardware, skeleton, view, frame, status, poser, saved,
// saving (at connect: whether the node can save; a node that does not send it is taken to save).
import * as THREE from "three";
import { OrbitControls } from "three/examples/jsm/controls/OrbitControls.js";

const state = {
  kit: null, names: [], parents: [], view: null, status: null, frames: 0, fps: 0, lastFpsT: performance.now(),
  connected: false, ws: null, retry: 0, lastFrame: null, trails: new Map(), plot: [], hits: [],
  poser: null, editing: false, nodeKit: null, pendingKit: null,
  drawn: 0, // frames drawn (a received frame shown by the render loop): "view N fps" counts these
  saving: { enabled: true, reason: null },
  editorAllowed: true, // false: this page shows the view only (the node's --editor; its "editor" message)
  shells: {}, // kit object id -> its drum shell's colour (0xRRGGBB) as last drawn
};
window.batteur = state; // for tests and the console

// ---------------------------------------------------------------- scene
const canvas = document.getElementById("view");
const renderer = new THREE.WebGLRenderer({ canvas, antialias: true, preserveDrawingBuffer: true });
renderer.setPixelRatio(1);
const scene = new THREE.Scene();
scene.background = new THREE.Color(0x1b1d22);
const camera = new THREE.PerspectiveCamera(45, 1, 0.05, 100);
camera.up.set(0, 0, 1);
const controls = new OrbitControls(camera, canvas);
controls.target.set(0, 0.35, 0.75);
Object.assign(state, { camera, controls, renderer }); // for tests and the console: the view's eye, GPU memory
controls.addEventListener("start", () => { if (state.view) state.view.camera.preset = "free"; syncPresetSelect(); });
window.addEventListener("resize", placePanels);
scene.add(new THREE.HemisphereLight(0xffffff, 0x303040, 1.6));
const sun = new THREE.DirectionalLight(0xffffff, 1.8);
sun.position.set(1.5, 2.5, 4);
scene.add(sun);

const layers = {
  body: new THREE.Group(), sticks: new THREE.Group(), kit: new THREE.Group(), contacts: new THREE.Group(),
  trails: new THREE.Group(), floor: new THREE.Group(),
};
for (const g of Object.values(layers)) scene.add(g);
state.layers = layers; // for tests and the console: what is drawn
const grid = new THREE.GridHelper(4, 16, 0x555a66, 0x33363d);
grid.rotation.x = Math.PI / 2;
layers.floor.add(grid);

function resize() {
  const w = window.innerWidth, h = window.innerHeight;
  renderer.setSize(w, h, false);
  camera.aspect = w / h;
  camera.updateProjectionMatrix();
}
window.addEventListener("resize", resize);
resize();

// ---------------------------------------------------------------- kit
const MAT = {
  shell: (c) => new THREE.MeshStandardMaterial({ color: c, roughness: 0.6 }),
  head: () => new THREE.MeshStandardMaterial({ color: 0xe8e4d8, roughness: 0.8, emissive: 0xffcc55,
    emissiveIntensity: 0 }),
  cymbal: () => new THREE.MeshStandardMaterial({ color: 0xc9a23a, metalness: 0.6, roughness: 0.35,
    emissive: 0xffdd66, emissiveIntensity: 0, side: THREE.DoubleSide }),
  metal: new THREE.MeshStandardMaterial({ color: 0x999ba0, metalness: 0.7, roughness: 0.4 }),
  dark: new THREE.MeshStandardMaterial({ color: 0x2a2a30, roughness: 0.9 }),
};
const SHELL_COLOURS = { kick: 0x8c1c24, snare: 0x9aa0aa, hightom: 0x8c1c24, midtom: 0x8c1c24, floortom: 0x8c1c24 };
const EVENT_DRUMS = { BASS: "kick", SNARE: "snare", RIM: "snare", HIGHTOM: "hightom", MIDTOM: "midtom",
  FLOORTOM: "floortom" };
function shellColour(kit, obj) { // by what the kit plays on the drum (a designer's "bd" is the kick), as the sound
  // service's drum_role: its id when the kit plays nothing on it or events of different drums
  const drums = new Set(Object.entries(kit.events ?? {}).filter(([, spec]) => spec.object === obj.id)
    .map(([event]) => EVENT_DRUMS[event] ?? event));
  return SHELL_COLOURS[drums.size === 1 ? [...drums][0] : obj.id] ?? 0x7a1f2b;
}
let kitParts = []; // per kit object: {obj, group, swing, flashMats, extra}

function eulerOf(deg) { // kit rotation: roll pitch yaw, extrinsic x-y-z == intrinsic Z-Y-X
  const r = deg.map((d) => (d * Math.PI) / 180);
  return new THREE.Euler(r[0], r[1], r[2], "ZYX");
}
function cylinderZ(radiusTop, radiusBottom, height, mat, segments = 40) {
  const g = new THREE.CylinderGeometry(radiusTop, radiusBottom, height, segments, 1, false);
  g.rotateX(Math.PI / 2); // three's cylinders run along y; ours along local z
  return new THREE.Mesh(g, mat);
}

const SHARED_MATS = new Set([MAT.metal, MAT.dark]);
function disposeKit() { // the kit is redrawn on every slider step: free the old one's GPU buffers, not just drop it
  layers.kit.traverse((o) => {
    if (!o.isMesh) return;
    o.geometry.dispose();
    if (!SHARED_MATS.has(o.material)) o.material.dispose();
  });
  layers.kit.clear();
}
function buildKit(kit) {
  disposeKit();
  kitParts = [];
  state.shells = {};
  for (const obj of kit.objects) {
    const group = new THREE.Group();
    group.position.set(...obj.position);
    group.rotation.copy(eulerOf(obj.rotation_deg));
    const swing = new THREE.Group(); // cymbal swing / pedal tilt happens here
    group.add(swing);
    const part = { obj, group, swing, flashMats: [], extra: null };
    const r = obj.radius;
    if (obj.kind === "membrane") {
      const depth = Math.max(obj.depth, 0.05);
      state.shells[obj.id] = shellColour(kit, obj);
      const shell = cylinderZ(r, r, depth, MAT.shell(state.shells[obj.id]));
      shell.position.z = -depth / 2 - 0.002;
      const headMat = MAT.head();
      const head = cylinderZ(r * 0.995, r * 0.995, 0.004, headMat);
      swing.add(shell, head);
      part.flashMats.push(headMat);
    } else if (obj.kind === "cymbal" || obj.kind === "hihat") {
      const mat = MAT.cymbal();
      const disc = cylinderZ(Math.max(obj.bell_radius, 0.02), r, 0.012, mat);
      swing.add(disc);
      part.flashMats.push(mat);
      if (obj.kind === "hihat") {
        const bottom = cylinderZ(r, Math.max(obj.bell_radius, 0.02), 0.012, mat);
        bottom.position.z = -0.012;
        group.add(bottom);
        part.extra = (gap) => { swing.position.z = gap; };
      }
    } else if (obj.kind === "bell") {
      const mat = MAT.cymbal();
      const box = new THREE.Mesh(new THREE.BoxGeometry(r * 2, r * 1.4, Math.max(obj.depth, 0.08)), mat);
      swing.add(box);
      part.flashMats.push(mat);
    } else if (obj.kind === "pedal") {
      const board = new THREE.Mesh(new THREE.BoxGeometry(0.09, 0.28, 0.015), MAT.metal);
      board.position.set(0, 0.12, 0.0);
      swing.add(board);
      swing.position.y = -0.02;
      part.extra = (press) => { swing.rotation.x = ((18 - 16 * press) * Math.PI) / 180; };
    } else if (obj.kind === "throne") {
      const seat = cylinderZ(r, r, 0.08, MAT.dark);
      seat.position.z = -0.04;
      swing.add(seat);
      if (obj.position[2] > 0.1) { // its post, from the floor to just under the seat (world vertical)
        const h = obj.position[2] - 0.02;
        const pole = cylinderZ(0.008, 0.008, h, MAT.metal, 8);
        pole.position.set(obj.position[0], obj.position[1], h / 2);
        layers.kit.add(pole);
      }
    }
    layers.kit.add(group);
    kitParts.push(part);
  }
  buildHardware(hardwareOf(kit));
}

// ---------------------------------------------------------------- hardware (beaters, stands)
// The beaters and stand rods physics builds around the kit, as numbers the node computes (common/kit.py's
// kit_hardware, world metres): sent with every kit, and asked for a kit this page edits, so the live view draws the
// hardware physics and the glTF export have. Cached by the kit's JSON (the page's kit-equality test).
const HARDWARE_CACHE = 32;
const hardware = { numbers: null, group: null, beaters: [], stands: [], cache: new Map(), waiting: null };
state.hardware = hardware; // for tests and the console: what is drawn
function rememberHardware(key, numbers) {
  hardware.cache.delete(key);
  hardware.cache.set(key, numbers);
  if (hardware.cache.size > HARDWARE_CACHE) hardware.cache.delete(hardware.cache.keys().next().value);
}
function hardwareOf(kit) { // an edited kit's are asked of the node: the last drawn stay until the answer
  const key = JSON.stringify(kit);
  const known = hardware.cache.get(key);
  if (known) return known;
  askHardware(kit, key);
  return hardware.numbers;
}
function askHardware(kit, key) { // one request at a time: a slider drag asks again when the answer comes
  if (hardware.waiting === null && send({ type: "hardware", kit })) hardware.waiting = key;
}
function onHardware(m) {
  const key = hardware.waiting;
  hardware.waiting = null;
  if (key === null || !m.hardware) return; // an error (the node logs it): the hardware drawn stays
  rememberHardware(key, m.hardware);
  if (!state.kit) return;
  const now = JSON.stringify(state.kit);
  const current = hardware.cache.get(now);
  buildHardware(current ?? m.hardware); // an older edit's are nearer than those drawn
  if (!current) askHardware(state.kit, now);
}
function buildHardware(numbers) {
  if (hardware.group?.parent) { // not freed with the kit (disposeKit): free it here
    hardware.group.traverse((o) => { if (o.isMesh) o.geometry.dispose(); });
    hardware.group.removeFromParent();
  }
  Object.assign(hardware, { numbers, group: new THREE.Group(), beaters: [], stands: [] });
  layers.kit.add(hardware.group);
  for (const s of numbers?.stands ?? []) { // vertical, from the floor to under the object's centre
    const pole = cylinderZ(s.radius, s.radius, s.height, MAT.metal, 8);
    pole.position.set(s.top[0], s.top[1], s.height / 2);
    hardware.group.add(pole);
    hardware.stands.push(pole);
  }
  for (const b of numbers?.beaters ?? []) { // a rod along +z from the axle to the ball, turning about world x
    const group = new THREE.Group();
    group.position.set(...b.axle);
    const rod = cylinderZ(b.rod_radius, b.rod_radius, b.rod_length, MAT.metal, 8);
    rod.position.z = b.rod_length / 2;
    const ball = new THREE.Mesh(new THREE.SphereGeometry(b.ball_radius, 12, 8), MAT.dark);
    ball.position.z = b.rod_length;
    group.add(rod, ball);
    const beater = { pedal: b.pedal, index: kitParts.findIndex((p) => p.obj.id === b.pedal), group, rod, ball,
      rest: b.rest_rad, lean: b.lean_rad };
    turnBeater(beater, 0);
    hardware.group.add(group);
    hardware.beaters.push(beater);
  }
}
function turnBeater(b, press) { // geared to its footboard: rest_rad back from the head at rest, 0 pressed flat
  b.group.rotation.x = b.rest * (1 - press) - b.lean;
}

function applyKitState(k) {
  for (let i = 0; i < kitParts.length; i++) {
    const p = kitParts[i];
    const flash = k[i * 4], sx = k[i * 4 + 1], sy = k[i * 4 + 2], extra = k[i * 4 + 3];
    for (const m of p.flashMats) m.emissiveIntensity = 1.2 * flash;
    if (p.obj.kind !== "pedal") {
      const angle = Math.hypot(sx, sy);
      if (angle > 1e-6) p.swing.quaternion.setFromAxisAngle(new THREE.Vector3(sx / angle, sy / angle, 0), angle);
      else p.swing.quaternion.identity();
    }
    if (p.extra) p.extra(extra);
  }
  for (const b of hardware.beaters) if (b.index >= 0) turnBeater(b, k[b.index * 4 + 3]);
}

// ---------------------------------------------------------------- body
let links = []; // per link: {name, sphere, bone, kind}
const BODY = new THREE.MeshStandardMaterial({ color: 0x4f86c6, roughness: 0.7 });
const JOINT = new THREE.MeshStandardMaterial({ color: 0xd9d9e0, roughness: 0.6 });
const STICK = new THREE.MeshStandardMaterial({ color: 0xd8b27a, roughness: 0.6 });
const TIP = new THREE.MeshStandardMaterial({ color: 0xfff2c0, roughness: 0.5 });
const OTHER = new THREE.MeshStandardMaterial({ color: 0x888888 });
const unitBone = new THREE.CylinderGeometry(1, 1, 1, 10);
unitBone.translate(0, 0.5, 0); // base at the origin, along +y

function linkKind(name) {
  const n = name.toLowerCase();
  if (n.includes("stick")) return n.includes("tip") ? "tip" : "stick";
  if (n.includes("head") || n.includes("skull")) return "head";
  return "body";
}

const STICK_GRIP = 0.13, STICK_TIP = 0.2695; // physics' 5A stick: butt and tip bead along the stick link's +y
function buildSkeleton(names, parents) {
  layers.body.clear();
  layers.sticks.clear();
  layers.trails.clear();
  state.trails.clear();
  links = names.map((name, i) => {
    const kind = name.startsWith("kit.") ? "kit" : (parents[i] < 0 && !isBodyName(name) ? "other" : linkKind(name));
    const link = { name, kind, sphere: null, bone: null, stick: null, parent: parents[i] };
    if (kind === "kit") return link; // kit links animate the kit (the node's kit state), nothing to draw here
    const group = kind === "stick" || kind === "tip" ? layers.sticks : layers.body;
    const radius = kind === "head" ? 0.1 : kind === "tip" ? 0.012 : kind === "stick" ? 0.008 : 0.028;
    link.sphere = new THREE.Mesh(new THREE.SphereGeometry(radius, 14, 10),
      kind === "head" ? BODY : kind === "tip" ? TIP : kind === "other" ? OTHER : JOINT);
    group.add(link.sphere);
    if (parents[i] >= 0) {
      const thick = kind === "tip" ? 0.007 : kind === "stick" ? 0.009 : 0.03;
      link.bone = new THREE.Mesh(unitBone, kind === "tip" || kind === "stick" ? STICK : BODY);
      link.bone.userData.thick = thick;
      group.add(link.bone);
    }
    const hasTip = names.some((n, j) => parents[j] === i && linkKind(n) === "tip");
    if (kind === "stick" && !hasTip) { // no tip link published: draw the stick along the link's +y
      const geom = new THREE.CylinderGeometry(0.007, 0.007, STICK_GRIP + STICK_TIP, 10);
      geom.translate(0, (STICK_TIP - STICK_GRIP) / 2, 0);
      link.stick = new THREE.Mesh(geom, STICK);
      const bead = new THREE.Mesh(new THREE.SphereGeometry(0.012, 12, 8), TIP);
      bead.position.y = STICK_TIP;
      link.stick.add(bead);
      layers.sticks.add(link.stick);
    }
    if (kind === "tip" || (kind === "stick" && !hasTip) || /(toe|foot)$/.test(name)) {
      const geom = new THREE.BufferGeometry();
      geom.setAttribute("position", new THREE.BufferAttribute(new Float32Array(3 * 600), 3));
      const line = new THREE.Line(geom, new THREE.LineBasicMaterial({ color: /(toe|foot)$/.test(name) ? 0x70c0ff : 0xffd070 }));
      line.frustumCulled = false;
      layers.trails.add(line);
      state.trails.set(i, { line, points: [], tipOffset: kind === "stick" ? STICK_TIP : 0 });
    }
    return link;
  });
  state.plot = [];
}
function isBodyName(name) {
  return /(pelvis|root|hips|abdomen|spine|torso|chest|neck|head|arm|hand|wrist|elbow|shoulder|stick|thigh|hip|shin|knee|leg|foot|ankle|toe)/i
    .test(name);
}

const tmpA = new THREE.Vector3(), tmpB = new THREE.Vector3(), tmpD = new THREE.Vector3();
const tmpQ = new THREE.Quaternion();
const Y = new THREE.Vector3(0, 1, 0);
function applyPose(p, t) {
  for (let i = 0; i < links.length; i++) {
    const L = links[i];
    const o = i * 7;
    if (L.kind === "kit") continue;
    if (L.sphere) {
      L.sphere.position.set(p[o], p[o + 1], p[o + 2]);
      if (L.kind === "head") L.sphere.position.z += 0.09;
    }
    if (L.stick) {
      L.stick.position.set(p[o], p[o + 1], p[o + 2]);
      L.stick.quaternion.set(p[o + 3], p[o + 4], p[o + 5], p[o + 6]);
    }
    if (L.bone) {
      const q = L.parent * 7;
      tmpA.set(p[q], p[q + 1], p[q + 2]);
      tmpB.set(p[o], p[o + 1], p[o + 2]);
      tmpD.subVectors(tmpB, tmpA);
      const len = tmpD.length();
      L.bone.visible = len > 1e-4;
      if (len > 1e-4) {
        L.bone.position.copy(tmpA);
        L.bone.quaternion.setFromUnitVectors(Y, tmpD.divideScalar(len));
        const th = L.bone.userData.thick;
        L.bone.scale.set(th, len, th);
      }
    }
  }
  // trails and the tip-height plot
  const seconds = state.view?.trails ?? 1.0;
  for (const [i, tr] of state.trails) {
    const o = i * 7;
    tmpA.set(0, tr.tipOffset, 0).applyQuaternion(tmpQ.set(p[o + 3], p[o + 4], p[o + 5], p[o + 6]));
    tr.points.push([t, p[o] + tmpA.x, p[o + 1] + tmpA.y, p[o + 2] + tmpA.z]);
    while (tr.points.length && (tr.points[0][0] < t - seconds || tr.points.length > 600)) tr.points.shift();
    // time went back (a looping preview, physics restarted): the trail starts again from the new point
    if (tr.points[tr.points.length - 1][0] < tr.points[0][0]) tr.points = tr.points.slice(-1);
    const arr = tr.line.geometry.attributes.position.array;
    tr.points.forEach((pt, j) => { arr[j * 3] = pt[1]; arr[j * 3 + 1] = pt[2]; arr[j * 3 + 2] = pt[3]; });
    tr.line.geometry.setDrawRange(0, tr.points.length);
    tr.line.geometry.attributes.position.needsUpdate = true;
  }
  const tips = [...state.trails.entries()].filter(([i]) => links[i].kind !== "body");
  // time went back: the points after it go (all of them when a preview loops or physics restarts). The view
  // clock also steps back a little on a loaded rig: emptying the plot then left a second or so of its window.
  while (state.plot.length && state.plot[state.plot.length - 1][0] > t) state.plot.pop();
  state.plot.push([t, tips.map(([, tr]) => tr.points[tr.points.length - 1][3]), tips.map(([i]) => links[i].name)]);
  const window_ = state.view?.plot?.window ?? 4;
  while (state.plot.length && state.plot[0][0] < t - window_) state.plot.shift();
}

// ---------------------------------------------------------------- contacts
const hitGeom = new THREE.SphereGeometry(1, 12, 8);
const UNIT_SCALE = new THREE.Vector3(1, 1, 1);
function objectMatrix(obj) { // kit object frame -> world, as buildKit draws it
  return new THREE.Matrix4().compose(new THREE.Vector3(...obj.position),
    new THREE.Quaternion().setFromEuler(eulerOf(obj.rotation_deg)), UNIT_SCALE);
}
// The node places a strike's marker on its own kit; a page with unsaved edits draws that object elsewhere, so the
// marker is carried onto the object as drawn: the same point of its surface (object frame, scaled by the radius).
function onDrawnKit(x, y, z, id) {
  const from = (state.pendingKit ?? state.nodeKit)?.objects.find((o) => o.id === id);
  const to = state.kit?.objects.find((o) => o.id === id);
  if (!from || !to || sameKit(from, to)) return [x, y, z];
  const p = new THREE.Vector3(x, y, z).applyMatrix4(objectMatrix(from).invert());
  const scale = to.radius / from.radius;
  p.x *= scale; p.y *= scale;
  return p.applyMatrix4(objectMatrix(to)).toArray();
}
function applyHits(hits) {
  layers.contacts.clear();
  for (const [x, y, z, age, id] of hits) {
    const s = 0.02 + 0.06 * age;
    const m = new THREE.Mesh(hitGeom, new THREE.MeshBasicMaterial({ color: 0xff5533, transparent: true,
      opacity: Math.max(0, 1 - age / 0.5) }));
    m.position.set(...onDrawnKit(x, y, z, id));
    m.scale.setScalar(s);
    layers.contacts.add(m);
  }
  state.hits = hits;
}

// ---------------------------------------------------------------- plot (tip heights, 2009 paper fig. 5)
const plotCanvas = document.getElementById("plot");
const pctx = plotCanvas.getContext("2d");
const PLOT_COLOURS = ["#ffb347", "#7ec8ff", "#b0ff8a", "#ff7eb6"];
const PLOT_LEGEND_TOP = 22, PLOT_LINE = 11; // the legend's first baseline and line height (canvas px, 10 px font)
function plotNotice(text) { // what the plot says it lacks ("" with data), also for screen readers and tests
  if (state.plotNotice === text) return;
  state.plotNotice = text;
  plotCanvas.setAttribute("aria-label", text ? `stick tip height plot: ${text}` : "stick tip height plot");
}
function drawPlot() {
  const w = plotCanvas.width, h = plotCanvas.height;
  pctx.clearRect(0, 0, w, h);
  pctx.fillStyle = "rgba(20,22,28,0.85)";
  pctx.fillRect(0, 0, w, h);
  const pl = state.view?.plot ?? { window: 4, z_min: 0.5, z_max: 1.6 };
  const empty = !state.plot.length ? "no strokes yet" : !state.plot[0][1].length ? "no stick tips in the poses" : "";
  plotNotice(empty);
  if (empty) { // say so, as the view does when it has nothing to draw, rather than show an empty box
    pctx.fillStyle = "#999"; pctx.font = "10px sans-serif";
    pctx.fillText("stick tip height (m)", 30, 10);
    pctx.font = "13px sans-serif"; pctx.textAlign = "center";
    pctx.fillText(empty, w / 2, h / 2 + 4);
    pctx.textAlign = "start";
    return;
  }
  const tEnd = state.plot[state.plot.length - 1][0];
  const nTips = state.plot[0][1].length;
  // the traces keep under the title and the legend (a stick tip near z_max was drawn through the names)
  const top = PLOT_LEGEND_TOP + PLOT_LINE * nTips;
  const x = (t) => ((t - (tEnd - pl.window)) / pl.window) * (w - 30) + 26;
  const y = (z) => h - 14 - ((z - pl.z_min) / (pl.z_max - pl.z_min)) * (h - 14 - top);
  pctx.strokeStyle = "#444"; pctx.fillStyle = "#999"; pctx.font = "10px sans-serif";
  for (let z = Math.ceil(pl.z_min * 5) / 5; z <= pl.z_max; z += 0.2) {
    pctx.beginPath(); pctx.moveTo(26, y(z)); pctx.lineTo(w, y(z)); pctx.stroke();
    pctx.fillText(z.toFixed(1), 2, y(z) + 3);
  }
  pctx.fillText("stick tip height (m) over the last " + pl.window + " s", 30, 10);
  for (let k = 0; k < nTips; k++) {
    pctx.strokeStyle = PLOT_COLOURS[k % PLOT_COLOURS.length];
    pctx.save();
    pctx.beginPath(); // a tip outside z_min..z_max is cut at the edge, not drawn over the legend or the labels
    pctx.rect(26, top, w - 26, h - 14 - top);
    pctx.clip();
    pctx.beginPath();
    state.plot.forEach(([t, zs], j) => { if (j) pctx.lineTo(x(t), y(zs[k])); else pctx.moveTo(x(t), y(zs[k])); });
    pctx.stroke();
    pctx.restore();
    pctx.fillStyle = pctx.strokeStyle;
    pctx.fillText(state.plot[0][2][k], w - 90, PLOT_LEGEND_TOP + PLOT_LINE * k);
  }
}

// ---------------------------------------------------------------- camera
// The presets are the node's (services/graphics/camera.py, in every view message), so the page frames each one as
// the video and the Pd panel do. A preset is an orbit about its target, or a fixed eye (drummer); orbit turns.
function placeCamera(cam, now) {
  const c = state.view?.presets?.[cam.preset] ?? cam; // free: the message's own numbers
  const target = new THREE.Vector3(...(c.target ?? [0, 0.35, 0.75]));
  if (state.orbitSince === null) state.orbitSince = now; // a turning preset turns from its own azimuth when picked
  if (c.eye) {
    camera.position.set(...c.eye);
  } else {
    const turned = (c.turn_deg_per_s ?? 0) * ((now - (state.orbitSince ?? now)) / 1000);
    const az = c.azimuth_deg + turned, el = c.elevation_deg, dist = c.distance;
    const a = (az * Math.PI) / 180, e = (el * Math.PI) / 180;
    camera.position.set(target.x + dist * Math.sin(a) * Math.cos(e), target.y + dist * Math.cos(a) * Math.cos(e),
      target.z + dist * Math.sin(e));
  }
  controls.target.copy(target);
  controls.update();
}
const presetSelect = document.getElementById("camera-preset");
function syncPresetSelect() { if (state.view) presetSelect.value = state.view.camera.preset; }
function pickCamera(cam) { // the page shows ``cam`` from now on (an orbit starts turning now)
  state.view.camera = { ...cam };
  state.orbitSince = null;
  placeCamera(state.view.camera, performance.now());
}
presetSelect.addEventListener("change", () => {
  if (!state.view) return;
  if (presetSelect.value === "free") state.view.camera.preset = "free"; // stay where the view is, mouse-driven
  else pickCamera({ ...state.view.camera, preset: presetSelect.value });
});

// state.view is the view as this page shows it: the node's, except the camera and layers picked on this page,
// which hold until the node is sent that setting (its view message names it in ``control``) or changes it.
function applyView(view) {
  const before = state.nodeView, shown = state.view;
  state.nodeView = JSON.parse(JSON.stringify(view));
  const fromNode = (key, now, was) => !before || view.control === key || JSON.stringify(now) !== JSON.stringify(was);
  const layersShown = { ...view.layers };
  if (shown) {
    for (const name of Object.keys(layersShown)) {
      if (!fromNode(`layer:${name}`, view.layers[name], before.layers[name])) layersShown[name] = shown.layers[name];
    }
  }
  const newCamera = fromNode("camera", view.camera, before?.camera);
  state.view = { ...view, camera: newCamera ? { ...view.camera } : shown.camera, layers: layersShown };
  if (newCamera) pickCamera(view.camera);
  showPreviewRate(view);
  showPreviewBars(view);
  if (view.control === "preview_bars" || view.control === "preview_rate" || view.mode !== "preview") showPreviewMsg("");
  showLayers();
}
// The preview's speed (motion seconds per second), shown while a preview plays: the node's rate, changed for every
// page from any page (the view message names it); a rate given on the command line that the list lacks is added.
const rateSelect = document.getElementById("preview-rate");
function showPreviewRate(view) {
  const rate = view.preview_rate ?? null, shown = rate !== null && view.mode === "preview";
  document.getElementById("preview-rate-box").classList.toggle("hidden", !shown);
  if (rate === null) return;
  const rates = [...new Set([...(view.preview_rates ?? []), rate])].sort((a, b) => a - b);
  // by value, not count: a rate sent over OSC replaces another one the list lacked (0.6 then 0.7)
  if ([...rateSelect.options].map((o) => o.value).join() !== rates.map(String).join()) {
    rateSelect.replaceChildren(...rates.map((r) => new Option(`\u00D7${r}`, String(r))));
  }
  rateSelect.value = String(rate);
}
rateSelect.addEventListener("change", () => sendPreview({ type: "preview_rate", rate: Number(rateSelect.value) }));
// A rate or range the node refuses (bars past the score's end): why, beside the boxes (the editor's line is hidden
// while it is closed), and the node's view with it, so the boxes show what plays again. It stays until the next
// range or rate is sent or the node changes them.
const previewMsg = document.getElementById("preview-msg");
function showPreviewMsg(text) {
  previewMsg.textContent = text;
  previewMsg.classList.toggle("hidden", !text);
}
function sendPreview(msg) { showPreviewMsg(""); send(msg); }
function onRefused(m) {
  if (m.view) applyView(m.view);
  showPreviewMsg(`${m.control === "preview_rate" ? "speed" : "bars"} refused: ${m.error}`);
}
// The bars a score preview loops (view.preview_bars: [first, last], "all", or null with no score to count bars by),
// changed for every page from any page or over OSC (/batteur/graphics/preview_bars).
const firstBar = document.getElementById("preview-first"), lastBar = document.getElementById("preview-last");
function showPreviewBars(view) {
  const bars = view.preview_bars ?? null;
  document.getElementById("preview-bars-box").classList.toggle("hidden", bars === null || view.mode !== "preview");
  if (bars === null) return;
  [firstBar.value, lastBar.value] = bars === "all" ? ["", ""] : bars.map(String);
}
function sendBars(changed) { // an empty last bar: the first one alone
  let first = Math.max(1, Math.floor(Number(firstBar.value) || 1));
  let last = Math.max(1, Math.floor(Number(lastBar.value) || first));
  if (last < first) { // a range ending before it starts: the other end follows the one changed
    if (changed === firstBar) last = first; else first = last;
  }
  sendPreview({ type: "preview_bars", first, last });
}
firstBar.addEventListener("change", () => sendBars(firstBar));
lastBar.addEventListener("change", () => sendBars(lastBar));
document.getElementById("preview-all").addEventListener("click", (e) => {
  e.preventDefault(); // inside the label: a click must not also focus an input
  sendPreview({ type: "preview_bars", first: 0, last: 0 });
});
function showLayers() {
  const shown = state.view.layers;
  for (const [name, group] of Object.entries(layers)) group.visible = shown[name] !== false;
  plotCanvas.classList.toggle("hidden", shown.plot === false);
  document.getElementById("status").classList.toggle("hidden", shown.status === false);
  syncPresetSelect();
  for (const name of Object.keys(shown)) layerTick(name).checked = shown[name];
  placePanels();
}
// The toolbar's tick of each layer, made once and then only updated: rebuilding the ticks on every change sent the
// keyboard focus to <body> (Space on a tick, or any view message from the node, lost the user's place).
const layerTicks = new Map();
function layerTick(name) {
  let cb = layerTicks.get(name);
  if (cb) return cb;
  const label = document.createElement("label");
  cb = document.createElement("input");
  cb.type = "checkbox";
  const tick = cb;
  tick.addEventListener("change", () => { state.view.layers[name] = tick.checked; showLayers(); });
  label.append(tick, name);
  document.getElementById("layers").append(label);
  layerTicks.set(name, tick);
  return tick;
}

// The toolbar (and the editor under it) sits right of the status panel, or below it when the window is too
// narrow for both side by side; the editor ends above the plot (scrolling), or, in a window too short to leave it
// EDITOR_MIN_PX there, the plot moves left of the editor: a panel never covers another. The plot shrinks (never
// grows) to fit under the panels above it and beside the editor: in a phone held sideways it lay over the toolbar,
// and, moved left of the editor, ran off the window.
const EDITOR_MIN_PX = 160, PLOT_MIN_SCALE = 0.3;
// A phone held upright: the status panel and the toolbar's layer ticks above the drummer and the plot below took
// nearly half the window, over the head and the feet. There the status panel starts folded to its first line, the
// ticks fold behind a button and the plot is at most PLOT_COMPACT_SHARE of the window's height. A fold the user
// taps holds (null: as the window suggests); a laptop's window starts with everything open, as before.
const COMPACT = window.matchMedia("(orientation: portrait) and (max-width: 540px)");
const PLOT_COMPACT_SHARE = 0.2;
const folds = { status: null, layers: null }; // true: open
state.folds = folds; // for tests and the console
function applyFolds() {
  const compact = COMPACT.matches;
  document.body.classList.toggle("compact", compact);
  const statusOpen = folds.status ?? !compact, layersOpen = folds.layers ?? !compact;
  const status = document.getElementById("status"), statusToggle = document.getElementById("status-toggle");
  status.classList.toggle("folded", !statusOpen);
  statusToggle.textContent = statusOpen ? "\u25BE" : "\u25B8"; // down or right-pointing triangle
  statusToggle.setAttribute("aria-expanded", String(statusOpen));
  statusToggle.title = statusOpen ? "fold the details" : "show the details";
  document.getElementById("toolbar").classList.toggle("folded", !layersOpen);
  const layersToggle = document.getElementById("layers-toggle");
  layersToggle.setAttribute("aria-expanded", String(layersOpen));
  layersToggle.title = layersOpen ? "hide the layer ticks" : "show the layer ticks";
  placePanels();
}
document.getElementById("status-toggle").addEventListener("click", () => {
  folds.status = document.getElementById("status").classList.contains("folded");
  applyFolds();
});
document.getElementById("layers-toggle").addEventListener("click", () => {
  folds.layers = document.getElementById("toolbar").classList.contains("folded");
  applyFolds();
});
COMPACT.addEventListener("change", applyFolds);
function fitPlot(right, room, panels) { // the plot's CSS size at ``right`` px from the window's right edge
  const w = plotCanvas.width, h = plotCanvas.height, border = plotCanvas.offsetWidth - plotCanvas.clientWidth;
  let scale = Math.min(1, (room - border) / w, COMPACT.matches ? (window.innerHeight * PLOT_COMPACT_SHARE) / h : 1);
  const left = window.innerWidth - right - w * scale - border;
  const above = panels.filter((r) => r.left < window.innerWidth - right && left < r.right) // in its columns
    .reduce((low, r) => Math.max(low, r.bottom + 8), 0);
  scale = Math.max(PLOT_MIN_SCALE, Math.min(scale, (window.innerHeight - 8 - above - border) / h));
  Object.assign(plotCanvas.style, { right: `${right}px`, width: `${w * scale}px`, height: `${h * scale}px` });
}
function placePanels() {
  const status = document.getElementById("status"), toolbar = document.getElementById("toolbar");
  const editor = document.getElementById("editor");
  toolbar.style.top = "8px";
  const s = status.getBoundingClientRect(), t = toolbar.getBoundingClientRect();
  const besideStatus = status.classList.contains("hidden") || t.left >= s.right + 8;
  if (!besideStatus) toolbar.style.top = `${s.bottom + 8}px`;
  const top = toolbar.getBoundingClientRect().bottom + 8;
  editor.style.top = `${top}px`;
  const above = [toolbar.getBoundingClientRect()]; // the panels the plot must stay under
  if (!status.classList.contains("hidden")) above.push(status.getBoundingClientRect());
  fitPlot(8, window.innerWidth - 16, above); // its corner, bottom right
  let bottom = window.innerHeight - 8; // the editor's lowest edge (CSS pixels; its box is border-box)
  if (!editor.classList.contains("hidden") && !plotCanvas.classList.contains("hidden")) {
    const aboveplot = plotCanvas.getBoundingClientRect().top - 8;
    if (aboveplot - top >= EDITOR_MIN_PX) bottom = aboveplot;
    else {
      const edge = editor.getBoundingClientRect().left;
      fitPlot(window.innerWidth - edge + 8, edge - 16, above);
    }
  }
  editor.style.maxHeight = `${Math.max(EDITOR_MIN_PX, bottom - top)}px`;
}

// ---------------------------------------------------------------- status panel
function renderStatus() {
  const s = state.status;
  const conn = document.getElementById("conn");
  conn.textContent = state.connected ? "connected" : `reconnecting (try ${state.retry})`;
  conn.className = state.connected ? "ok" : "bad";
  const body = document.getElementById("status-body");
  body.classList.toggle("stale", !state.connected); // what the node last said, not what the rig does now
  if (!s) { body.textContent = ""; return; }
  // a node stays listed 10 s after its last report (core.py): past NODE_QUIET_S its last rate is not shown as live
  const rows = s.nodes.map((n) => (n.age > NODE_QUIET_S
    ? `<tr class="quiet"><td>${n.role}</td><td class="bad" title="no report for ${n.age} s">quiet</td>`
    : `<tr><td>${n.role}</td><td>${n.rate_hz}/${n.target_hz} Hz</td>`) +
    `<td>late ${n.late}</td><td>${n.age}s</td></tr>`).join("");
  // beats counted in the meter's note value (beat_unit, quarter notes: 0.5 in 6/8, eighths 1 to 6 as a DAW and
  // batteur compare count them); the node's beat is in quarter notes, the tempo stays quarter notes a minute
  const score = s.score
    ? `bar ${s.score.bar + 1} beat ${(s.score.beat / (s.score.beat_unit ?? 1) + 1).toFixed(2)} @ ${s.score.tempo_bpm} bpm`
    : "–";
  // a figure and its unit never wrap apart in the narrow panel ("465" at the end of a line, "ms" on the next)
  const nw = (text) => `<span class="nw">${text}</span>`;
  // a preview receives no poses or impacts: its own numbers (strokes played of this lap's, its poses, its speed)
  const p = s.preview;
  const counts = p ? `${nw(`preview \u00D7${p.rate}`)} · ${nw(`strokes ${p.played}/${p.strokes}`)} · ` +
    `${nw(`lap ${p.laps + 1}`)} · ${nw(`${p.poses} poses`)}`
    : `${nw(`late strikes ${s.late}`)} · ${nw(`poses ${s.counters.poses}`)} · ${nw(`impacts ${s.counters.impacts}`)}`;
  body.innerHTML = `mode ${s.mode} · ${nw(`delay ${(s.latency * 1000).toFixed(0)} ms`)} · ` +
    `${nw(`view ${state.fps.toFixed(0)} fps`)}<br>` +
    `${nw(`rig time ${s.time.toFixed(2)} s`)} · score ${nw(score)}<br>` +
    counts +
    (s.pose_lag === null ? "" : ` · ${nw(`pose age ${(s.pose_lag * 1000).toFixed(0)} ms`)}`) +
    `<table>${rows || "<tr><td>no other nodes seen</td></tr>"}</table>`;
  showStalePoses(s);
  placePanels(); // the panel grows with the nodes seen
}

// Nodes report their Health once a second (common/messages/system.py): three missed, the node is quiet.
const NODE_QUIET_S = 3;

// The node holds the newest pose when poses stop (physics stopped or cannot reach it), so frames keep coming and
// the drummer just stands still: say so once the live poses are older than STALE_POSES_S.
const STALE_POSES_S = 2;
function showStalePoses(s) {
  const el = document.getElementById("stale-poses");
  const stale = state.connected && s.mode === "live" && s.pose_lag !== null && s.pose_lag > STALE_POSES_S;
  el.classList.toggle("hidden", !stale);
  if (stale) {
    el.textContent = `no poses from physics for ${s.pose_lag.toFixed(0)} s: the drummer is held at the last pose ` +
      "(physics stopped, or cannot reach this node)";
  }
}

// ---------------------------------------------------------------- WebSocket with auto-reconnect
function connect() {
  const proto = location.protocol === "https:" ? "wss" : "ws";
  const ws = new WebSocket(`${proto}://${location.host}/ws`);
  state.ws = ws;
  ws.onopen = () => { state.connected = true; state.retry = 0; applySaving({ enabled: true, reason: null }); state.connects = (state.connects ?? 0) + 1;
    state.connectedAt = performance.now(); renderStatus(); };
  ws.onmessage = (ev) => { try { onMessage(JSON.parse(ev.data)); } catch (e) { console.error(e); } };
  ws.onclose = () => {
    state.connected = false;
    hardware.waiting = null; // its answer is lost with the connection
    state.retry += 1;
    renderStatus();
    setTimeout(connect, Math.min(3000, 250 * 2 ** Math.min(state.retry, 4)));
  };
  ws.onerror = () => ws.close();
}
function send(msg) { // false when the node is not connected (the message is dropped)
  if (!state.ws || !state.connected) return false;
  state.ws.send(JSON.stringify(msg));
  return true;
}

function onMessage(m) {
  switch (m.type) {
    case "kit": if (m.hardware) rememberHardware(JSON.stringify(m.kit), m.hardware); onKit(m.kit); break;
    case "hardware": onHardware(m); break;
    case "skeleton": state.names = m.names; state.parents = m.parents; buildSkeleton(m.names, m.parents); break;
    case "view": applyView(m); break;
    case "frame":
      if (m.p.length !== links.length * 7) break;
      state.lastFrame = m; state.frames += 1; state.lastFrameAt = performance.now();
      state.peakFlash = Math.max(state.peakFlash ?? 0, ...m.k.filter((_, i) => i % 4 === 0));
      applyPose(m.p, m.t); applyKitState(m.k); applyHits(m.h);
      break;
    case "status": state.status = m; renderStatus(); break;
    case "poser": state.poser = m; buildEditorPose(); break; // the 57-DOF editor (buildEditorPose)
    case "saved": editorMsg(m.ok ? `saved ${m.path}` : `not saved: ${m.error}`, m.ok); break;
    case "saving": applySaving(m); break;
    case "editor": applyEditor(m); break;
    case "refused": onRefused(m); break;
    default: break;
  }
}

// ---------------------------------------------------------------- editor (2001 paper's poser GUI)
const editor = document.getElementById("editor");
function toggleEditor() {
  if (!state.editing && !state.editorAllowed) return; // a view-only page (the kit flag still shows a kit change)
  state.editing = !state.editing;
  editor.classList.toggle("hidden", !state.editing);
  if (!state.editing) state.poser = null;
  send({ type: state.editing ? "poser_on" : "poser_off" });
  showKitNotice(); // with the editor closed, the toolbar says the node's kit changed
}
document.getElementById("edit-toggle").addEventListener("click", toggleEditor);
document.getElementById("kit-flag").addEventListener("click", () => { if (!state.editing) toggleEditor(); });
// The node says whether this page may edit (graphics --editor: by default only pages opened on its own machine):
// a page from another machine shows the view without the editor button.
function applyEditor(m) {
  state.editorAllowed = m.enabled !== false;
  const button = document.getElementById("edit-toggle");
  button.classList.toggle("hidden", !state.editorAllowed);
  button.title = state.editorAllowed ? "" : (m.reason ?? "the editor is off for this page");
  if (!state.editorAllowed && state.editing) toggleEditor();
}
function editorMsg(text, ok) {
  const el = document.getElementById("editor-msg");
  el.textContent = text;
  el.className = ok ? "ok" : "bad";
}
// Arrow keys on a slider step its value by a unit a user of a 3D editor expects (1 mm, 1 degree; Shift: 10 x),
// not the browser's 1 % of the slider's span (3 cm of a position, 3.6 degrees of an angle).
const ARROWS = { ArrowRight: 1, ArrowUp: 1, ArrowLeft: -1, ArrowDown: -1 };
function arrowStep(e, step) { // the signed step an arrow key asks for; 0 for another key (its default stays)
  const dir = ARROWS[e.key];
  if (!dir || e.altKey || e.ctrlKey || e.metaKey) return 0;
  return dir * step * (e.shiftKey ? 10 : 1);
}
const KEY_STEP_M = 0.001, KEY_STEP_DEG = 1;
// A kit value's row: a slider to move it and a number field to type it. Showing the row never changes the kit:
// the field shows the value as loaded (every digit) and the slider reaches it (its span grows to take it). A drag
// puts the value on a ``step`` grid (1 mm, 0.1 degree: a pixel of slider is coarser); a typed value is kept
// exactly, within ``limits`` (the kit model's).
function kitSlider(parent, label, value, min, max, step, unit, onChange, limits = [-Infinity, Infinity],
  keyStep = unit === "degrees" ? KEY_STEP_DEG : KEY_STEP_M) {
  const row = document.createElement("div");
  row.className = "slider kit";
  const range = document.createElement("input");
  Object.assign(range, { type: "range", step: "any" });
  const field = document.createElement("input");
  Object.assign(field, { type: "number", step, title: unit });
  const decimals = Math.max(0, Math.round(-Math.log10(step)));
  let current = value;
  const show = (v) => { // bounds before the value, or the browser clamps it into the old ones
    Object.assign(range, { min: Math.min(min, v), max: Math.max(max, v) });
    range.value = v;
    field.value = String(v);
  };
  const set = (v) => { current = Math.min(limits[1], Math.max(limits[0], v)); onChange(current); };
  show(value);
  range.addEventListener("input", () => { // the slider keeps its own span while it is dragged
    set(Number(Number(range.value).toFixed(decimals)));
    field.value = String(current);
  });
  field.addEventListener("change", () => {
    const typed = Number(field.value);
    if (field.value !== "" && Number.isFinite(typed)) set(typed);
    show(current);
  });
  range.addEventListener("keydown", (e) => { // from the value as it is (0.1234 m -> 0.1244 m), float noise dropped
    const d = arrowStep(e, keyStep);
    if (!d) return;
    e.preventDefault();
    set(Number((current + d).toFixed(9)));
    show(current);
  });
  row.append(label, range, field);
  parent.append(row);
}
// state.kit is the kit the page draws and edits, state.nodeKit the node's kit it was loaded from. The node sends
// its kit on every (re)connect, after a restart and when a page saves: it replaces the page's only when that
// drops no edit; otherwise it waits (state.pendingKit) and the editor offers to load it.
const sameKit = (a, b) => JSON.stringify(a) === JSON.stringify(b);
function onKit(kit) {
  const edited = state.kit !== null && !sameKit(state.kit, state.nodeKit);
  if (sameKit(kit, state.kit)) { // already shown (this page's own save, a reconnect): nothing to redraw
    state.nodeKit = kit;
    state.pendingKit = null;
  } else if (edited) {
    state.pendingKit = sameKit(kit, state.nodeKit) ? null : kit; // the kit the edits started from: nothing new
  } else {
    loadKit(kit);
  }
  const drawn = JSON.stringify(state.kit);
  if (!hardware.cache.has(drawn)) askHardware(state.kit, drawn); // an edit's asked before a reconnect
  showKitNotice();
}
function loadKit(kit) { // show the node's kit, dropping the page's edits
  state.kit = kit;
  state.nodeKit = JSON.parse(JSON.stringify(kit)); // state.kit is edited in place
  state.pendingKit = null;
  buildKit(kit);
  buildEditorKit();
  if (state.names.length) buildSkeleton(state.names, state.parents);
  showKitNotice();
}
function showKitNotice() { // in the editor, or on the toolbar (opening the editor) while it is closed
  document.getElementById("kit-notice").classList.toggle("hidden", !state.pendingKit);
  document.getElementById("kit-flag").classList.toggle("hidden", !state.pendingKit || state.editing);
  placePanels(); // the toolbar's height may change
}
document.getElementById("kit-load").addEventListener("click", () => {
  if (state.pendingKit) loadKit(state.pendingKit);
});
const kitSelect = document.getElementById("kit-object");
function buildEditorKit() {
  if (!state.kit) return;
  const chosen = kitSelect.value;
  kitSelect.innerHTML = state.kit.objects.map((o) => `<option>${o.id}</option>`).join("");
  if (state.kit.objects.some((o) => o.id === chosen)) kitSelect.value = chosen; // else the first object
  buildKitSliders();
}
function buildKitSliders() {
  const box = document.getElementById("kit-sliders");
  box.innerHTML = "";
  const obj = state.kit?.objects.find((o) => o.id === kitSelect.value);
  if (!obj) return;
  const redraw = () => buildKit(state.kit); // the rows stay: rebuilding them would end a drag after one step
  ["x", "y", "z"].forEach((axis, i) => kitSlider(box, `pos ${axis}`, obj.position[i], i === 2 ? 0 : -1.5, 1.5,
    0.001, "metres", (v) => { obj.position[i] = v; redraw(); }));
  ["roll", "pitch", "yaw"].forEach((axis, i) => kitSlider(box, axis, obj.rotation_deg[i], -180, 180, 0.1,
    "degrees", (v) => { obj.rotation_deg[i] = v; redraw(); }));
  kitSlider(box, "radius", obj.radius, 0.02, 0.5, 0.001, "metres", (v) => { obj.radius = v; redraw(); },
    [0.001, 1.0]);
}
kitSelect.addEventListener("change", buildKitSliders);
// Kit.mirrored (common/kit.py), to the same numbers: the left-handed setup, x mirrored (pitch and yaw negated),
// hands and feet swapped, hit points mirrored (theta -> pi - theta), pair preferences negated. Mirroring twice gives
// the kit back: the name's suffix toggles, and an angle comes back to the digit (common.kit.mirrored_angle).
const OTHER_LIMB = {
  left_hand: "right_hand", right_hand: "left_hand", left_foot: "right_foot", right_foot: "left_foot",
};
const MIRRORED_SUFFIX = "-mirrored", ANGLE_DECIMALS = 12, ANGLE_NOISE_RAD = 1e-14;
// pi - theta (radians), except that a result within float noise of a 12-decimal value is that value: pi - (pi -
// theta) can miss theta by one rounding (-1.5708 -> -1.5708000000000002). toFixed rounds the exact double, as
// Python's round does (their tie rules differ only half a decimal away, far beyond the noise kept).
function mirroredAngle(theta) {
  const exact = Math.PI - theta;
  const written = Number(exact.toFixed(ANGLE_DECIMALS));
  return Math.abs(written - exact) <= ANGLE_NOISE_RAD ? written : exact;
}
function mirroredKit(kit) {
  const out = JSON.parse(JSON.stringify(kit));
  for (const o of out.objects) {
    o.position[0] = -o.position[0];
    o.rotation_deg = [o.rotation_deg[0], -o.rotation_deg[1], -o.rotation_deg[2]];
  }
  for (const spec of Object.values(out.events)) {
    spec.preferred = OTHER_LIMB[spec.preferred];
    spec.theta = mirroredAngle(spec.theta);
    if (spec.off_hand) spec.off_hand = [spec.off_hand[0], mirroredAngle(spec.off_hand[1])];
  }
  for (const key of Object.keys(out.pair_preference)) out.pair_preference[key] = -out.pair_preference[key];
  out.name = kit.name.endsWith(MIRRORED_SUFFIX) ? kit.name.slice(0, -MIRRORED_SUFFIX.length)
    : kit.name + MIRRORED_SUFFIX;
  out.handedness = kit.handedness === "right" ? "left" : "right";
  return out;
}
document.getElementById("kit-mirror").addEventListener("click", () => {
  if (!state.kit) return;
  state.kit = mirroredKit(state.kit); // an edit like any other: unsaved until save kit
  buildKit(state.kit);
  buildEditorKit();
});
// A node without a kit directory (as `batteur rig` starts it) cannot save: its save buttons are off and say why.
function applySaving(m) {
  state.saving = { enabled: m.enabled !== false, reason: m.reason ?? null };
  const why = state.saving.enabled ? "" : `saving is off: ${state.saving.reason ?? "the node has no kit directory"}`;
  for (const id of ["kit-save", "pose-save"]) {
    const button = document.getElementById(id);
    button.disabled = !state.saving.enabled;
    button.title = why;
    button.parentElement.title = why; // a disabled button shows no tooltip in every browser: its row does
  }
}
function savingOff() { // true (and the editor says why) when the node cannot save
  if (state.saving.enabled) return false;
  editorMsg(`not saved: ${state.saving.reason ?? "saving is off"}`, false);
  return true;
}
function saveKit() {
  if (savingOff()) return;
  const file = document.getElementById("kit-file").value;
  if (send({ type: "save_kit", file, kit: state.kit })) editorMsg(`saving ${file}...`, true);
  else editorMsg("not saved: the node is not connected (reconnecting)", false);
}
document.getElementById("kit-save").addEventListener("click", saveKit);
document.getElementById("kit-file").addEventListener("keydown", (e) => { // Enter saves, as the button does
  if (e.key === "Enter" && !e.isComposing) saveKit();
});
// The pose editor poses physics' 57-DOF body: 19 joints x (x, y, z) degrees, each DOF within physics' limits.
// The node does the forward kinematics (the frames show the edited body) and, with "drive physics", sends the
// posture to physics (/batteur/physics/posture).
const jointSelect = document.getElementById("pose-joint");
const driveBox = document.getElementById("pose-drive");
function buildEditorPose() {
  const p = state.poser;
  if (!p) return;
  for (const joint of Object.keys(p.angles)) p.angles[joint] = p.angles[joint].map(toAngleStep);
  p.initial = p.initial ?? JSON.parse(JSON.stringify(p.angles));
  const chosen = jointSelect.value;
  jointSelect.innerHTML = p.joints.map((j) => `<option>${j}</option>`).join("");
  if (chosen && p.joints.includes(chosen)) jointSelect.value = chosen;
  document.getElementById("pose-body").textContent = p.body === "live"
    ? "physics' body (live)" : "the default body (no physics seen)";
  buildPoseSliders();
}
let poseTimer = null, posePending = false;
function sendPose() { // at most every 50 ms, the last change always sent
  posePending = true;
  if (poseTimer) return;
  const flush = () => {
    poseTimer = null;
    if (!posePending || !state.poser) return;
    posePending = false;
    send({ type: "poser", angles: state.poser.angles, drive: driveBox.checked });
    poseTimer = setTimeout(flush, 50);
  };
  flush();
}
// A joint angle is set to ANGLE_STEP_DEG: what the number field shows is exactly what is sent, and a value
// physics reports or a user types is kept (to that step) instead of snapping to a coarse slider grid.
const ANGLE_STEP_DEG = 0.01;
const toAngleStep = (deg) => Number((Math.round(deg / ANGLE_STEP_DEG) * ANGLE_STEP_DEG).toFixed(2));
function angleSlider(parent, label, value, min, max, onChange) {
  const row = document.createElement("div");
  row.className = "slider";
  const range = document.createElement("input");
  Object.assign(range, { type: "range", min, max, step: "any", value });
  const field = document.createElement("input");
  Object.assign(field, { type: "number", min, max, step: ANGLE_STEP_DEG, value: value.toFixed(2),
    title: "degrees" });
  const set = (deg) => { // clamp into the joint's limits, on the step; show and send that very value
    const v = toAngleStep(Math.min(max, Math.max(min, deg)));
    range.value = v;
    field.value = v.toFixed(2);
    onChange(v);
  };
  range.addEventListener("input", () => set(Number(range.value)));
  range.addEventListener("keydown", (e) => {
    const d = arrowStep(e, KEY_STEP_DEG);
    if (!d) return;
    e.preventDefault();
    set(Number(range.value) + d);
  });
  field.addEventListener("change", () => { if (field.value !== "" && Number.isFinite(Number(field.value))) {
    set(Number(field.value)); } else field.value = Number(range.value).toFixed(2); });
  row.append(label, range, field);
  parent.append(row);
}
function buildPoseSliders() {
  const box = document.getElementById("pose-sliders");
  box.innerHTML = "";
  const p = state.poser;
  const joint = jointSelect.value;
  if (!p || !joint) return;
  p.dofs[joint].forEach(([dof, lo, hi], i) => {
    const value = p.angles[joint][i];
    angleSlider(box, dof, value, Math.min(lo, value), Math.max(hi, value), (v) => {
      p.angles[joint][i] = v;
      sendPose();
    });
  });
}
jointSelect.addEventListener("change", buildPoseSliders);
function savePose() {
  if (!state.poser || savingOff()) return;
  const name = document.getElementById("pose-name").value;
  if (send({ type: "save_pose", name, angles: state.poser.angles })) editorMsg(`saving ${name}...`, true);
  else editorMsg("not saved: the node is not connected (reconnecting)", false);
}
document.getElementById("pose-save").addEventListener("click", savePose);
document.getElementById("pose-name").addEventListener("keydown", (e) => { // Enter saves, as the button does
  if (e.key === "Enter" && !e.isComposing) savePose();
});
document.getElementById("pose-reset").addEventListener("click", () => {
  if (!state.poser) return;
  state.poser.angles = JSON.parse(JSON.stringify(state.poser.initial));
  buildPoseSliders();
  sendPose();
});

// ---------------------------------------------------------------- nothing to show
// Before any pose (no physics running, the preview mode asked of a node with no preview loaded) the view is an
// empty kit: the notice says why and how to get a drummer, once the node has sent no frame for NOTICE_AFTER_MS.
const NOTICE_AFTER_MS = 1000;
const notice = document.getElementById("notice");
function showNotice(now) {
  const idle = state.connected && now - Math.max(state.connectedAt ?? now, state.lastFrameAt ?? -Infinity)
    > NOTICE_AFTER_MS;
  if (notice.classList.contains("hidden") === idle) notice.classList.toggle("hidden", !idle);
}

// ---------------------------------------------------------------- render loop
function animate(now) {
  showNotice(now);
  if (state.view?.camera?.preset === "orbit") placeCamera(state.view.camera, now);
  controls.update();
  if (state.view?.layers?.plot !== false) drawPlot();
  renderer.render(scene, camera);
  state.rendered = (state.rendered ?? 0) + 1;
  // frames drawn, not received: a stalled tab catching up receives a burst of frames and draws only the last
  if (state.lastFrame !== state.drawnFrame) { state.drawnFrame = state.lastFrame; state.drawn += 1; }
  if (now - state.lastFpsT > 1000) {
    state.fps = (state.drawn - (state.drawnAtFps ?? 0)) * 1000 / (now - state.lastFpsT);
    state.drawnAtFps = state.drawn; state.lastFpsT = now;
  }
  requestAnimationFrame(animate);
}
applyFolds();
connect();
requestAnimationFrame(animate);
