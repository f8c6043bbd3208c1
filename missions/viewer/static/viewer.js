// The FlyCrane plan viewer: draws the document that missions/viewer/document.py builds.
// Every pose comes from that document, computed in Python with the project's kinematics;
// this script only places objects, shows the frame at the slider's time, and plots.
import * as THREE from 'three';
import { OrbitControls } from 'three/addons/controls/OrbitControls.js';
import uPlot from 'uplot';

const doc = JSON.parse(document.getElementById('flycrane-view').textContent);
const planned = doc.planned;
const flown = doc.flown;
THREE.Object3D.DEFAULT_UP.set(0, 0, 1); // the world is ENU, z up

const DRONE_COLORS = ['#d62728', '#2ca02c', '#1f77b4'];
const CABLE_COLORS = ['#e377c2', '#ff7f0e', '#8c564b', '#17becf', '#bcbd22', '#9467bd'];
const LIMIT_COLOR = '#000000';
const last = (array) => array[array.length - 1];

// ---- header -----------------------------------------------------------------------------
for (const fact of doc.facts) {
  const row = document.createElement('div');
  row.append(Object.assign(document.createElement('dt'), { textContent: fact.label }));
  row.append(Object.assign(document.createElement('dd'), { textContent: fact.value }));
  document.getElementById('facts').append(row);
}
for (const note of doc.notes) {
  document.getElementById('notes').append(Object.assign(document.createElement('li'), { textContent: note }));
}

// ---- 3-D scene ----------------------------------------------------------------------------
function geometryOf(shape) {
  switch (shape.kind) {
    case 'box': return new THREE.BoxGeometry(...shape.size);
    case 'sphere': return new THREE.SphereGeometry(shape.radius, 32, 16);
    // three.js builds cylinders along y; the scene's cylinders stand along their own z.
    case 'cylinder': return new THREE.CylinderGeometry(shape.radius, shape.radius, shape.height, 32).rotateX(Math.PI / 2);
    case 'mesh': {
      const geometry = new THREE.BufferGeometry();
      geometry.setAttribute('position', new THREE.Float32BufferAttribute(shape.vertices.flat(), 3));
      geometry.setIndex(shape.faces.flat());
      geometry.computeVertexNormals();
      return geometry;
    }
    default: throw new Error(`unknown shape kind ${shape.kind}`);
  }
}

function shapeObject(shape, material, edges) {
  const geometry = geometryOf(shape);
  const object = new THREE.Group();
  object.add(new THREE.Mesh(geometry, material));
  object.add(new THREE.LineSegments(new THREE.EdgesGeometry(geometry, 20), new THREE.LineBasicMaterial({ color: edges })));
  object.position.fromArray(shape.center);
  object.quaternion.fromArray(shape.quaternion);
  object.name = shape.name;
  return object;
}

function lambert(color, opacity = 1) {
  return new THREE.MeshLambertMaterial({ color, transparent: opacity < 1, opacity, side: THREE.DoubleSide });
}

const scene = new THREE.Scene();
scene.background = new THREE.Color('#eef1f4');
scene.add(new THREE.HemisphereLight('#ffffff', '#8a9a8a', 2.2));
const sun = new THREE.DirectionalLight('#ffffff', 1.6);
sun.position.set(-30, -40, 60);
scene.add(sun);
for (const obstacle of doc.scene.obstacles) scene.add(shapeObject(obstacle, lambert('#9aa3ad', 0.85), '#4a525a'));

function line(points, material) {
  const geometry = new THREE.BufferGeometry().setFromPoints(points.map((p) => new THREE.Vector3(...p)));
  const object = new THREE.Line(geometry, material);
  if (material.isLineDashedMaterial) object.computeLineDistances();
  return object;
}

// One FlyCrane: the platform group (platform and payload, posed per frame), drones, cables.
function crane(style) {
  const platform = new THREE.Group();
  const platformMaterial = style.outline ? new THREE.MeshBasicMaterial({ color: '#333', wireframe: true }) : lambert('#f28e2b');
  platform.add(shapeObject(doc.crane.platform, platformMaterial, '#7a3d00'));
  for (const shape of doc.crane.payload) {
    platform.add(shapeObject(shape, style.outline ? platformMaterial : lambert('#c8a165', 0.95), '#5a4520'));
  }
  const drones = DRONE_COLORS.map((color) => {
    const drone = new THREE.Group();
    drone.add(new THREE.Mesh(new THREE.SphereGeometry(doc.crane.drone_radius, 24, 12), style.outline
      ? new THREE.MeshBasicMaterial({ color, wireframe: true })
      : lambert(color, 0.35)));
    drone.add(new THREE.Mesh(new THREE.SphereGeometry(0.08, 12, 8), lambert(color)));
    return drone;
  });
  const cableGeometry = new THREE.BufferGeometry();
  cableGeometry.setAttribute('position', new THREE.Float32BufferAttribute(new Float32Array(6 * 2 * 3), 3));
  const cableColors = doc.crane.cable_drone.flatMap((k) => {
    const c = new THREE.Color(style.outline ? '#333' : DRONE_COLORS[k - 1]);
    return [c.r, c.g, c.b, c.r, c.g, c.b];
  });
  cableGeometry.setAttribute('color', new THREE.Float32BufferAttribute(cableColors, 3));
  const cables = new THREE.LineSegments(cableGeometry, new THREE.LineBasicMaterial({ vertexColors: true }));
  const group = new THREE.Group();
  group.add(platform, cables, ...drones);
  scene.add(group);
  return { group, platform, drones, cables };
}

// Place a crane at frame i of a frames record (None pose: the reconstruction failed there).
function pose(object, frames, i) {
  const position = frames.platform_position[i];
  object.platform.visible = position !== null;
  object.cables.visible = position !== null;
  if (position !== null) {
    object.platform.position.fromArray(position);
    object.platform.quaternion.fromArray(frames.platform_quaternion[i]);
    const attribute = object.cables.geometry.getAttribute('position');
    attribute.array.set(frames.cables[i].flat(2));
    attribute.needsUpdate = true;
    object.cables.geometry.computeBoundingSphere();
  }
  object.drones.forEach((drone, k) => drone.position.fromArray(frames.drones[i][k]));
}

const plannedCrane = crane({ outline: false });
const droneTrack = (frames, k) => frames.drones.map((d) => d[k]);
DRONE_COLORS.forEach((color, k) => {
  scene.add(line(droneTrack(planned, k), new THREE.LineBasicMaterial({ color })));
  const waypoints = planned.waypoint_frames.map((i) => new THREE.Vector3(...planned.drones[i][k]));
  scene.add(new THREE.Points(new THREE.BufferGeometry().setFromPoints(waypoints), new THREE.PointsMaterial({ color, size: 7, sizeAttenuation: false })));
});
scene.add(line(planned.platform_position, new THREE.LineDashedMaterial({ color: '#f28e2b', dashSize: 0.2, gapSize: 0.15 })));

let flownCrane = null;
const flownTracks = new THREE.Group();
if (flown) {
  flownCrane = crane({ outline: true });
  DRONE_COLORS.forEach((color, k) => {
    const dark = new THREE.Color(color).multiplyScalar(0.55);
    flownTracks.add(line(droneTrack(flown, k), new THREE.LineDashedMaterial({ color: dark, dashSize: 0.25, gapSize: 0.12 })));
  });
  scene.add(flownTracks);
}

// The camera looks at the motion (the tracks) from a distance that shows it whole; the
// extent of everything drawn sizes the ground and the clipping planes.
const extent = new THREE.Box3().setFromObject(scene);
const size = Math.max(extent.getSize(new THREE.Vector3()).length(), 1);
const motion = new THREE.Box3().setFromPoints([...planned.drones.flat(), ...planned.platform_position].map((p) => new THREE.Vector3(...p)));
const center = motion.getCenter(new THREE.Vector3());
const distance = Math.max(motion.getSize(new THREE.Vector3()).length(), 2) * 1.6;
if (doc.scene.ground) {
  const span = Math.ceil(size * 1.5);
  const grid = new THREE.GridHelper(span, span, '#9bb09b', '#c3d1c3').rotateX(Math.PI / 2);
  const middle = extent.getCenter(new THREE.Vector3());
  grid.position.set(Math.round(middle.x), Math.round(middle.y), 0.002);
  const ground = new THREE.Mesh(new THREE.PlaneGeometry(span, span), lambert('#d8e4d3'));
  ground.position.copy(grid.position).setZ(0);
  scene.add(ground, grid);
}

const view = document.getElementById('view');
let renderer;
try {
  renderer = new THREE.WebGLRenderer({ antialias: true });
} catch (error) {
  view.append(Object.assign(document.createElement('p'), { className: 'error', textContent: `No 3-D view: ${error.message}` }));
  throw error;
}
renderer.setPixelRatio(window.devicePixelRatio);
view.append(renderer.domElement);
const camera = new THREE.PerspectiveCamera(40, 1, size / 500, size * 20);
camera.position.copy(center).add(new THREE.Vector3(0.3, -1.0, 0.45).normalize().multiplyScalar(distance));
const controls = new OrbitControls(camera, renderer.domElement);
controls.target.copy(center);
controls.update();
const render = () => renderer.render(scene, camera);
controls.addEventListener('change', render);

// ---- profiles ------------------------------------------------------------------------------
const state = { t: 0, plannedFrame: 0, flownFrame: null };

function cursorHook(u) {
  const x = Math.round(u.valToPos(state.t, 'x', true));
  const ctx = u.ctx;
  ctx.save();
  ctx.strokeStyle = '#444';
  ctx.lineWidth = 1.5 * devicePixelRatio;
  ctx.beginPath();
  ctx.moveTo(x, u.bbox.top);
  ctx.lineTo(x, u.bbox.top + u.bbox.height);
  ctx.stroke();
  ctx.restore();
}

const column = (rows, j) => rows.map((row) => (row === null ? null : row[j]));
const extreme = (rows, pick) => rows.map((row) => (row === null ? null : pick(...row)));

// Series: {label, values (on planned or flown time), on: 'planned'|'flown', style}; limits are
// constant lines. Planned and flown times are joined into one x axis (uPlot.join).
function profile(element, series, limits, yLabel) {
  const plannedSeries = series.filter((s) => s.on === 'planned');
  const flownSeries = series.filter((s) => s.on === 'flown');
  const tables = [[planned.time, ...plannedSeries.map((s) => s.values)]];
  if (flownSeries.length) tables.push([flown.time, ...flownSeries.map((s) => s.values)]);
  const data = tables.length > 1 ? uPlot.join(tables) : tables[0];
  const ordered = [...plannedSeries, ...flownSeries];
  for (const limit of limits) {
    data.push(data[0].map(() => limit.value));
    ordered.push({ label: limit.label, style: { stroke: LIMIT_COLOR, width: 1.5, dash: [6, 4] }, limit: true });
  }
  const bands = [];
  ordered.forEach((s, j) => { if (s.bandWith !== undefined) bands.push({ series: [j + 1, ordered.indexOf(s.bandWith) + 1], fill: s.fill }); });
  const options = {
    width: element.clientWidth,
    height: 240,
    scales: { x: { time: false } },
    axes: [{ label: 'time [s]' }, { label: yLabel }],
    series: [{ label: 't [s]', value: (u, v) => (v == null ? '-' : v.toFixed(2)) },
      ...ordered.map((s) => ({ label: s.label, spanGaps: true, points: { show: false }, ...s.style }))],
    bands,
    legend: { live: false },
    hooks: { draw: [cursorHook] },
  };
  const plot = new uPlot(options, data, element);
  const hidden = new Set(ordered.filter((s) => s.hidden).map((s) => s.label));
  for (const row of plot.root.querySelectorAll('.u-legend .u-series')) {
    if (hidden.has(row.querySelector('.u-label').textContent)) row.style.display = 'none';
  }
  plot.over.addEventListener('click', () => { if (plot.cursor.left >= 0) setTime(plot.posToVal(plot.cursor.left, 'x')); });
  return plot;
}

const translucent = (hex, alpha) => `${hex}${Math.round(alpha * 255).toString(16).padStart(2, '0')}`;
const tensionSeries = [];
CABLE_COLORS.forEach((color, i) => {
  const nominal = { label: `cable ${i + 1}`, values: column(planned.tension, i), on: 'planned', style: { stroke: color, width: 1.5 } };
  const low = { label: `t_lo ${i + 1}`, values: column(planned.tension_low, i), on: 'planned', style: { stroke: translucent(color, 0.5), width: 0.5 }, hidden: true };
  const high = { label: `t_hi ${i + 1}`, values: column(planned.tension_high, i), on: 'planned', style: { stroke: translucent(color, 0.5), width: 0.5 }, hidden: true, fill: translucent(color, 0.12) };
  high.bandWith = low;
  tensionSeries.push(nominal, low, high);
});
const thrustSeries = [];
DRONE_COLORS.forEach((color, k) => {
  thrustSeries.push({ label: `drone ${k + 1} |T|`, values: column(planned.thrust, k), on: 'planned', style: { stroke: color, width: 1.5 } });
  thrustSeries.push({ label: `drone ${k + 1} m`, values: column(planned.thrust_bound, k), on: 'planned', style: { stroke: color, width: 1, dash: [4, 3] } });
});
if (flown) {
  const style = { stroke: '#333', width: 1.5, dash: [2, 2] };
  tensionSeries.push({ label: 'flown min t_lo', values: extreme(flown.tension_low, Math.min), on: 'flown', style });
  tensionSeries.push({ label: 'flown max t_hi', values: extreme(flown.tension_high, Math.max), on: 'flown', style });
  thrustSeries.push({ label: 'flown max m', values: extreme(flown.thrust_bound, Math.max), on: 'flown', style });
}
const plots = {
  tension: profile(document.getElementById('plot-tension'), tensionSeries, doc.limits.tension, 'tension [N]'),
  thrust: profile(document.getElementById('plot-thrust'), thrustSeries, doc.limits.thrust, 'thrust [N]'),
};

// ---- time ----------------------------------------------------------------------------------
const slider = document.getElementById('time');
const clock = document.getElementById('clock');
const showFlown = document.getElementById('show-flown');
const tStart = Math.min(planned.time[0], flown ? flown.time[0] : Infinity);
const tEnd = Math.max(last(planned.time), flown ? last(flown.time) : -Infinity);
slider.min = tStart;
slider.max = tEnd;

// The last frame at or before t (the first one before the track starts).
function frameAt(times, t) {
  let low = 0;
  let high = times.length - 1;
  while (low < high) {
    const mid = Math.ceil((low + high) / 2);
    if (times[mid] <= t) low = mid; else high = mid - 1;
  }
  return low;
}

function setTime(t) {
  state.t = Math.min(Math.max(t, tStart), tEnd);
  slider.value = state.t;
  clock.textContent = `${state.t.toFixed(2)} s`;
  state.plannedFrame = frameAt(planned.time, state.t);
  pose(plannedCrane, planned, state.plannedFrame);
  if (flown) {
    state.flownFrame = frameAt(flown.time, state.t);
    pose(flownCrane, flown, state.flownFrame);
    flownCrane.group.visible = showFlown.checked;
    flownTracks.visible = showFlown.checked;
  }
  for (const plot of Object.values(plots)) plot.redraw(false, false);
  render();
}

slider.addEventListener('input', () => setTime(Number(slider.value)));
if (flown) {
  document.getElementById('flown-toggle').hidden = false;
  showFlown.addEventListener('change', () => setTime(state.t));
}

const playButton = document.getElementById('play');
const speed = document.getElementById('speed');
let playing = false;
let previous = null;
function play(on) {
  playing = on;
  playButton.textContent = on ? 'Pause' : 'Play';
  previous = null;
  if (on) {
    if (state.t >= tEnd) setTime(tStart);
    requestAnimationFrame(tick);
  }
}
function tick(now) {
  if (!playing) return;
  const step = previous === null ? 0 : ((now - previous) / 1000) * Number(speed.value);
  previous = now;
  setTime(state.t + step);
  if (state.t >= tEnd) play(false); else requestAnimationFrame(tick);
}
playButton.addEventListener('click', () => play(!playing));

function resize() {
  renderer.setSize(view.clientWidth, view.clientHeight);
  camera.aspect = view.clientWidth / Math.max(view.clientHeight, 1);
  camera.updateProjectionMatrix();
  for (const plot of Object.values(plots)) plot.setSize({ width: plot.root.parentElement.clientWidth, height: 240 });
  render();
}
window.addEventListener('resize', resize);
resize();
setTime(tStart);

// For scripted use and the browser tests: the state this page shows.
window.flycraneViewer = {
  ready: true,
  setTime,
  play,
  plots,
  get time() { return state.t; },
  get playing() { return playing; },
  frames: () => ({ planned: state.plannedFrame, flown: state.flownFrame }),
  platformPosition: () => plannedCrane.platform.position.toArray(),
  dronePositions: () => plannedCrane.drones.map((d) => d.position.toArray()),
  flownPlatformVisible: () => (flownCrane ? flownCrane.group.visible && flownCrane.platform.visible : false),
  flownPlatformPosition: () => (flownCrane ? flownCrane.platform.position.toArray() : null),
};
