// dexaug's 3D grasp viewer: draws the scene that dexaug/viewer/scene.py wrote into the page
// (element #scene-data) with WebGL2. No library and no server: the page is one file that
// works from the dashboard, from a report folder and from a file:// URL.
//
// Frames: everything is in the object frame, metres, z up. The hand is one mesh per body;
// grasp i places body b at body_pose[i][b] (x y z qw qx qy qz), computed in Python by the
// hand model's forward kinematics. window.dexaugViewer is the page's API (tests use it).
"use strict";
(function () {
  const scene = JSON.parse(document.getElementById("scene-data").textContent);
  const G = scene.grasps;
  const COLORS = { passed: [0.13, 0.62, 0.25], failed: [0.85, 0.18, 0.15],
                   "not validated": [0.45, 0.45, 0.45] };

  function decode(text, Type) {
    const bin = atob(text), bytes = new Uint8Array(bin.length);
    for (let i = 0; i < bin.length; i++) bytes[i] = bin.charCodeAt(i);
    return new Type(bytes.buffer);
  }
  const bodyPose = decode(G.body_pose, Float32Array);
  const palms = decode(G.palm, Float32Array);
  const contactPoints = decode(G.contact_points, Float32Array);
  const contactNormals = decode(G.contact_normals, Float32Array);
  const nBodies = scene.hand.meshes.length;

  // ------------------------------------------------------------------ 4x4 matrices (column-major)
  function mul(a, b) {
    const o = new Float32Array(16);
    for (let c = 0; c < 4; c++) for (let r = 0; r < 4; r++) {
      let s = 0;
      for (let k = 0; k < 4; k++) s += a[k * 4 + r] * b[c * 4 + k];
      o[c * 4 + r] = s;
    }
    return o;
  }
  function poseMatrix(p, q) {            // p: xyz, q: wxyz
    const [w, x, y, z] = q;
    return new Float32Array([
      1 - 2 * (y * y + z * z), 2 * (x * y + w * z), 2 * (x * z - w * y), 0,
      2 * (x * y - w * z), 1 - 2 * (x * x + z * z), 2 * (y * z + w * x), 0,
      2 * (x * z + w * y), 2 * (y * z - w * x), 1 - 2 * (x * x + y * y), 0,
      p[0], p[1], p[2], 1]);
  }
  const IDENTITY = poseMatrix([0, 0, 0], [1, 0, 0, 0]);
  function perspective(fovy, aspect, near, far) {
    const f = 1 / Math.tan(fovy / 2), nf = 1 / (near - far);
    return new Float32Array([f / aspect, 0, 0, 0, 0, f, 0, 0, 0, 0, (far + near) * nf, -1,
                             0, 0, 2 * far * near * nf, 0]);
  }
  const sub = (a, b) => [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
  const cross = (a, b) => [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2],
                           a[0] * b[1] - a[1] * b[0]];
  const norm = (a) => { const l = Math.hypot(a[0], a[1], a[2]) || 1; return [a[0] / l, a[1] / l, a[2] / l]; };
  const dot = (a, b) => a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
  function lookAt(eye, target, up) {
    const f = norm(sub(target, eye)), s = norm(cross(f, up)), u = cross(s, f);
    return new Float32Array([s[0], u[0], -f[0], 0, s[1], u[1], -f[1], 0, s[2], u[2], -f[2], 0,
                             -dot(s, eye), -dot(u, eye), dot(f, eye), 1]);
  }

  // ------------------------------------------------------------------------------------ WebGL
  const canvas = document.getElementById("view");
  const gl = canvas.getContext("webgl2", { antialias: true, preserveDrawingBuffer: true });
  if (!gl) {
    document.getElementById("status").textContent =
      "This browser has no WebGL2: the 3D view cannot be drawn (the report's images still show the grasps).";
    window.dexaugViewer = { ready: false, error: "no WebGL2" };
    return;
  }
  function program(vs, fs) {
    const p = gl.createProgram();
    for (const [kind, src] of [[gl.VERTEX_SHADER, vs], [gl.FRAGMENT_SHADER, fs]]) {
      const s = gl.createShader(kind);
      gl.shaderSource(s, src);
      gl.compileShader(s);
      if (!gl.getShaderParameter(s, gl.COMPILE_STATUS)) throw new Error(gl.getShaderInfoLog(s));
      gl.attachShader(p, s);
    }
    gl.bindAttribLocation(p, 0, "aPos");
    gl.bindAttribLocation(p, 1, "aCol");
    gl.linkProgram(p);
    if (!gl.getProgramParameter(p, gl.LINK_STATUS)) throw new Error(gl.getProgramInfoLog(p));
    const u = {};
    for (let i = 0; i < gl.getProgramParameter(p, gl.ACTIVE_UNIFORMS); i++) {
      const name = gl.getActiveUniform(p, i).name;
      u[name] = gl.getUniformLocation(p, name);
    }
    return { p, u };
  }
  // Flat shading from screen-space derivatives: no normals to ship, both faces lit.
  const meshProg = program(`#version 300 es
    layout(location=0) in vec3 aPos; layout(location=1) in vec3 aCol;
    uniform mat4 uModel, uViewProj; out vec3 vWorld; out vec3 vCol;
    void main() { vec4 w = uModel * vec4(aPos, 1.0); vWorld = w.xyz; vCol = aCol;
                  gl_Position = uViewProj * w; }`, `#version 300 es
    precision highp float; in vec3 vWorld; in vec3 vCol; uniform vec3 uEye; uniform float uAlpha;
    out vec4 outColor;
    void main() { vec3 n = normalize(cross(dFdx(vWorld), dFdy(vWorld)));
      float head = abs(dot(n, normalize(uEye - vWorld)));
      float key = abs(dot(n, normalize(vec3(0.3, 0.2, 1.0))));
      vec3 base = max(vCol, vec3(0.16));   // a black material still shows its shape
      outColor = vec4(base * (0.30 + 0.50 * head + 0.25 * key), uAlpha); }`);
  const lineProg = program(`#version 300 es
    layout(location=0) in vec3 aPos; layout(location=1) in vec3 aCol;
    uniform mat4 uViewProj; uniform float uPointSize; out vec3 vCol;
    void main() { vCol = aCol; gl_Position = uViewProj * vec4(aPos, 1.0);
                  gl_PointSize = uPointSize; }`, `#version 300 es
    precision highp float; in vec3 vCol; uniform bool uRound; out vec4 outColor;
    void main() { if (uRound && length(gl_PointCoord - 0.5) > 0.5) discard;
                  outColor = vec4(vCol, 1.0); }`);

  function buffers(positions, colors, indices) {
    const vao = gl.createVertexArray();
    gl.bindVertexArray(vao);
    const attrib = (loc, data, type, normalized) => {
      const b = gl.createBuffer();
      gl.bindBuffer(gl.ARRAY_BUFFER, b);
      gl.bufferData(gl.ARRAY_BUFFER, data, gl.STATIC_DRAW);
      gl.enableVertexAttribArray(loc);
      gl.vertexAttribPointer(loc, 3, type, normalized, 0, 0);
    };
    attrib(0, positions, gl.FLOAT, false);
    attrib(1, colors, colors instanceof Uint8Array ? gl.UNSIGNED_BYTE : gl.FLOAT, colors instanceof Uint8Array);
    if (indices) {
      const b = gl.createBuffer();
      gl.bindBuffer(gl.ELEMENT_ARRAY_BUFFER, b);
      gl.bufferData(gl.ELEMENT_ARRAY_BUFFER, indices, gl.STATIC_DRAW);
    }
    gl.bindVertexArray(null);
    return { vao, count: indices ? indices.length : positions.length / 3 };
  }
  const meshOf = (m) => buffers(decode(m.v, Float32Array), decode(m.c, Uint8Array), decode(m.f, Uint32Array));
  const objectMesh = meshOf(scene.object.mesh);
  const handMeshes = scene.hand.meshes.map(meshOf);
  const objVerts = decode(scene.object.mesh.v, Float32Array);

  // the object's bounding box: the camera's target and the size of axes and table
  const lo = [Infinity, Infinity, Infinity], hi = [-Infinity, -Infinity, -Infinity];
  for (let i = 0; i < objVerts.length; i += 3) for (let k = 0; k < 3; k++) {
    lo[k] = Math.min(lo[k], objVerts[i + k]); hi[k] = Math.max(hi[k], objVerts[i + k]);
  }
  const centre = [0, 1, 2].map((k) => (lo[k] + hi[k]) / 2);
  const radius = Math.max(0.03, Math.hypot(hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]) / 2);

  function tableMesh() {                  // a square on the demonstration's table plane
    if (!scene.table) return null;
    const n = norm(scene.table.normal), p = scene.table.point;
    const t = dot(sub(centre, p), n), c = [0, 1, 2].map((k) => centre[k] - t * n[k]);
    const a = norm(cross(n, Math.abs(n[2]) < 0.9 ? [0, 0, 1] : [1, 0, 0])), b = cross(n, a);
    const s = radius * 4, pos = [];
    for (const [u, v] of [[-1, -1], [1, -1], [1, 1], [-1, 1]])
      for (let k = 0; k < 3; k++) pos.push(c[k] + s * (u * a[k] + v * b[k]));
    const col = new Float32Array([0.55, 0.6, 0.68, 0.55, 0.6, 0.68, 0.55, 0.6, 0.68, 0.55, 0.6, 0.68]);
    return buffers(new Float32Array(pos), col, new Uint32Array([0, 1, 2, 0, 2, 3]));
  }
  const table = tableMesh();

  function axesLines() {                   // the object frame: x red, y green, z blue
    const L = radius * 1.3, pos = [], col = [];
    [[1, 0, 0], [0, 1, 0], [0, 0, 1]].forEach((e) => {
      pos.push(0, 0, 0, L * e[0], L * e[1], L * e[2]);
      col.push(...e.map((x) => 0.15 + 0.75 * x), ...e.map((x) => 0.15 + 0.75 * x));
    });
    return buffers(new Float32Array(pos), new Float32Array(col));
  }
  const axes = axesLines();

  // ------------------------------------------------------------------------ state and filters
  const state = { selected: -1, visible: [], show: { hand: true, contacts: true, cloud: true,
                  table: true, axes: true }, frames: 0 };
  const camera = { az: -0.9, el: 0.45, dist: radius * 5 + 0.15, target: centre.slice() };
  const verdictSel = document.getElementById("f-verdict");
  const failureSel = document.getElementById("f-failure");
  const fingersSel = document.getElementById("f-fingers");
  const list = document.getElementById("grasp-list");

  function fill(sel, values, all) {
    sel.innerHTML = "";
    for (const [v, label] of [["", all], ...values.map((v) => [v, v])]) {
      const o = document.createElement("option");
      o.value = v; o.textContent = label; sel.appendChild(o);
    }
  }
  const fingerKey = (i) => G.fingers[i].join("+");
  const uniq = (xs) => [...new Set(xs)].sort();
  fill(verdictSel, uniq(G.verdict), "every verdict");
  fill(failureSel, uniq(G.failure.filter((f) => f)), "every failure reason");
  fill(fingersSel, uniq(G.fingers.map((f) => f.join("+"))), "any fingers");

  const fmt = (x, d) => (x === null || x === undefined ? "–" : x.toFixed(d));
  function label(i) {
    const e = G.epsilon[i] !== null ? ` · ε ${fmt(G.epsilon[i], 3)}` : "";
    const why = G.failure[i] ? ` (${G.failure[i]})` : "";
    return `#${i} · ${G.verdict[i]}${why} · ${fingerKey(i) || "no fingers"}${e}`;
  }

  function applyFilters() {
    const v = verdictSel.value, f = failureSel.value, fi = fingersSel.value;
    state.visible = [];
    for (let i = 0; i < G.n; i++)
      if ((!v || G.verdict[i] === v) && (!f || G.failure[i] === f) && (!fi || fingerKey(i) === fi))
        state.visible.push(i);
    list.innerHTML = "";
    for (const i of state.visible) {
      const o = document.createElement("option");
      o.value = String(i); o.textContent = label(i); list.appendChild(o);
    }
    document.getElementById("count").textContent =
      `${state.visible.length} of ${G.n} grasps shown` +
      (scene.grasps_in_table > G.n ? ` (the page holds the first ${G.n} of ${scene.grasps_in_table})` : "");
    rebuildCloud();
    select(state.visible.includes(state.selected) ? state.selected :
           (state.visible.length ? state.visible[0] : -1));
  }

  let cloud = null;
  function rebuildCloud() {                // palms of the grasps shown, coloured by verdict
    const pos = [], col = [];
    for (const i of state.visible) {
      pos.push(palms[3 * i], palms[3 * i + 1], palms[3 * i + 2]);
      col.push(...COLORS[G.verdict[i]]);
    }
    cloud = pos.length ? buffers(new Float32Array(pos), new Float32Array(col)) : null;
  }
  const demoMark = scene.demo ? buffers(new Float32Array(scene.demo.palm),
                                        new Float32Array([0.0, 0.45, 0.95])) : null;

  let contacts = null;
  function rebuildContacts(i) {            // points, and normals 2 cm long pointing out
    contacts = null;
    if (i < 0) return;
    const a = G.contact_offsets[i], b = G.contact_offsets[i + 1];
    if (b <= a) return;
    const pts = [], lines = [], pc = [], lc = [], L = 0.02;
    for (let k = a; k < b; k++) {
      const p = contactPoints.subarray(3 * k, 3 * k + 3), n = contactNormals.subarray(3 * k, 3 * k + 3);
      pts.push(...p); pc.push(0.95, 0.1, 0.55);
      lines.push(...p, p[0] + L * n[0], p[1] + L * n[1], p[2] + L * n[2]);
      lc.push(0.95, 0.1, 0.55, 0.95, 0.1, 0.55);
    }
    contacts = { points: buffers(new Float32Array(pts), new Float32Array(pc)),
                 lines: buffers(new Float32Array(lines), new Float32Array(lc)) };
  }

  function bodyMatrix(i, b) {
    const o = (i * nBodies + b) * 7, P = bodyPose;
    return poseMatrix([P[o], P[o + 1], P[o + 2]], [P[o + 3], P[o + 4], P[o + 5], P[o + 6]]);
  }

  function details(i) {
    const el = document.getElementById("details");
    if (i < 0) { el.textContent = "No grasp matches the filters."; return; }
    const rows = [["row", i], ["verdict", G.verdict[i] + (G.failure[i] ? ` (${G.failure[i]})` : "")],
      ["fingers", G.fingers[i].join(", ") || "–"], ["simulated ε", fmt(G.epsilon[i], 4)],
      ["planned ε (GWS)", fmt(G.gws[i], 4)], ["moved in the lift", fmt(G.displacement_mm[i], 1) + " mm"],
      ["turned in the lift", fmt(G.rotation_deg[i], 1) + "°"],
      ["contacts", G.contact_offsets[i + 1] - G.contact_offsets[i]]];
    el.innerHTML = "";
    for (const [k, v] of rows) {
      const tr = document.createElement("tr");
      const th = document.createElement("th"), td = document.createElement("td");
      th.textContent = k; td.textContent = String(v); tr.append(th, td); el.appendChild(tr);
    }
  }

  function select(i) {
    state.selected = i;
    if (i >= 0) list.value = String(i);
    rebuildContacts(i);
    details(i);
    redraw();
  }

  // ------------------------------------------------------------------------------- drawing
  let pending = false;
  function redraw() {
    if (!pending) { pending = true; requestAnimationFrame(draw); }
  }
  function resize() {
    const dpr = window.devicePixelRatio || 1, w = canvas.clientWidth, h = canvas.clientHeight;
    if (canvas.width !== Math.round(w * dpr) || canvas.height !== Math.round(h * dpr)) {
      canvas.width = Math.round(w * dpr); canvas.height = Math.round(h * dpr);
    }
  }
  // "Up" is the table's normal when the demonstration had a table (the scene stands as it
  // stood), else the object frame's z; the camera orbits about it.
  const UP = scene.table ? norm(scene.table.normal) : [0, 0, 1];
  const E1 = norm(cross(UP, Math.abs(UP[2]) < 0.9 ? [0, 0, 1] : [1, 0, 0])), E2 = cross(UP, E1);
  function eye() {
    const c = Math.cos(camera.el), s = Math.sin(camera.el), t = camera.target, d = camera.dist;
    const ca = Math.cos(camera.az), sa = Math.sin(camera.az);
    return [0, 1, 2].map((k) => t[k] + d * (c * (ca * E1[k] + sa * E2[k]) + s * UP[k]));
  }
  function draw() {
    pending = false;
    resize();
    gl.viewport(0, 0, canvas.width, canvas.height);
    gl.clearColor(0.96, 0.965, 0.975, 1);
    gl.clear(gl.COLOR_BUFFER_BIT | gl.DEPTH_BUFFER_BIT);
    gl.enable(gl.DEPTH_TEST);
    const e = eye();
    const viewProj = mul(perspective(0.7, canvas.width / Math.max(1, canvas.height),
                                     camera.dist / 100, camera.dist * 20),
                         lookAt(e, camera.target, UP));
    gl.useProgram(meshProg.p);
    gl.uniformMatrix4fv(meshProg.u.uViewProj, false, viewProj);
    gl.uniform3fv(meshProg.u.uEye, e);
    gl.uniform1f(meshProg.u.uAlpha, 1);
    const drawMesh = (m, model) => {
      gl.uniformMatrix4fv(meshProg.u.uModel, false, model);
      gl.bindVertexArray(m.vao);
      gl.drawElements(gl.TRIANGLES, m.count, gl.UNSIGNED_INT, 0);
    };
    drawMesh(objectMesh, IDENTITY);
    if (state.show.hand && state.selected >= 0)
      handMeshes.forEach((m, b) => drawMesh(m, bodyMatrix(state.selected, b)));
    gl.useProgram(lineProg.p);
    gl.uniformMatrix4fv(lineProg.u.uViewProj, false, viewProj);
    const drawLines = (m, mode, size) => {
      gl.uniform1f(lineProg.u.uPointSize, size);
      gl.uniform1i(lineProg.u.uRound, mode === gl.POINTS ? 1 : 0);
      gl.bindVertexArray(m.vao);
      gl.drawArrays(mode, 0, m.count);
    };
    if (state.show.axes) drawLines(axes, gl.LINES, 1);
    if (state.show.cloud && cloud) drawLines(cloud, gl.POINTS, 6);
    if (state.show.cloud && demoMark) drawLines(demoMark, gl.POINTS, 14);
    if (state.show.contacts && contacts) {  // on top: a contact sits on the finger's surface
      gl.disable(gl.DEPTH_TEST);
      drawLines(contacts.lines, gl.LINES, 1);
      drawLines(contacts.points, gl.POINTS, 8);
      gl.enable(gl.DEPTH_TEST);
    }
    if (state.show.table && table) {       // last, see-through
      gl.enable(gl.BLEND);
      gl.blendFunc(gl.SRC_ALPHA, gl.ONE_MINUS_SRC_ALPHA);
      gl.depthMask(false);
      gl.useProgram(meshProg.p);
      gl.uniform1f(meshProg.u.uAlpha, 0.5);
      drawMesh(table, IDENTITY);
      gl.depthMask(true);
      gl.disable(gl.BLEND);
    }
    gl.bindVertexArray(null);
    state.frames += 1;
  }

  // --------------------------------------------------------------------------------- input
  let drag = null;
  canvas.addEventListener("pointerdown", (ev) => {
    drag = { x: ev.clientX, y: ev.clientY, pan: ev.button === 2 || ev.shiftKey };
    canvas.setPointerCapture(ev.pointerId);
  });
  canvas.addEventListener("pointermove", (ev) => {
    if (!drag) return;
    const dx = ev.clientX - drag.x, dy = ev.clientY - drag.y;
    drag.x = ev.clientX; drag.y = ev.clientY;
    if (drag.pan) {                         // move the target in the view plane
      const e = eye(), f = norm(sub(camera.target, e)), s = norm(cross(f, UP)), u = cross(s, f);
      const k = camera.dist * 0.0015;
      for (let j = 0; j < 3; j++) camera.target[j] += k * (-dx * s[j] + dy * u[j]);
    } else {
      camera.az -= dx * 0.008;
      camera.el = Math.max(-1.5, Math.min(1.5, camera.el + dy * 0.008));
    }
    redraw();
  });
  canvas.addEventListener("pointerup", () => { drag = null; });
  canvas.addEventListener("contextmenu", (ev) => ev.preventDefault());
  canvas.addEventListener("wheel", (ev) => {
    ev.preventDefault();
    camera.dist = Math.max(0.02, Math.min(5, camera.dist * Math.exp(ev.deltaY * 0.001)));
    redraw();
  }, { passive: false });
  function step(k) {
    const at = state.visible.indexOf(state.selected);
    if (state.visible.length) select(state.visible[(at + k + state.visible.length) % state.visible.length]);
  }
  document.addEventListener("keydown", (ev) => {
    if (ev.target === list) return;        // the list moves itself
    if (ev.key === "ArrowRight" || ev.key === "n") step(1);
    if (ev.key === "ArrowLeft" || ev.key === "p") step(-1);
  });
  document.getElementById("prev").addEventListener("click", () => step(-1));
  document.getElementById("next").addEventListener("click", () => step(1));
  list.addEventListener("change", () => select(Number(list.value)));
  for (const sel of [verdictSel, failureSel, fingersSel]) sel.addEventListener("change", applyFilters);
  for (const key of Object.keys(state.show)) {
    const box = document.getElementById("show-" + key);
    if (!box) continue;
    box.checked = state.show[key];
    box.addEventListener("change", () => { state.show[key] = box.checked; redraw(); });
  }
  if (!table) document.getElementById("show-table").parentElement.style.display = "none";
  if (!scene.demo) document.getElementById("demo-legend").style.display = "none";
  window.addEventListener("resize", redraw);

  document.getElementById("title").textContent = scene.title;
  document.title = "dexaug viewer: " + scene.title;
  applyFilters();
  document.getElementById("status").textContent = "";

  window.dexaugViewer = {
    ready: true, total: G.n, bodies: scene.hand.bodies,
    visible: () => state.visible.slice(), selected: () => state.selected, select,
    setFilter(name, value) {
      const sel = { verdict: verdictSel, failure: failureSel, fingers: fingersSel }[name];
      sel.value = value; applyFilters();
    },
    bodyMatrix: (i, b) => Array.from(bodyMatrix(i, b)),
    frames: () => state.frames,
  };
})();
