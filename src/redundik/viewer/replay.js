// redundik offline replay: a small WebGL renderer for the data embedded in the page (no network, no libraries).
// URL parameters (query or hash): run=NAME, t=SECONDS (shows that instant, paused), play=1, speed=X,
// az=DEG, el=DEG (camera), robot=0 (hide the robot), paths=0 (hide paths), capsules=1 (show the collision shapes).
(function () {
  "use strict";
  const D = JSON.parse(document.getElementById("replay-data").textContent);
  const P = new URLSearchParams(location.search);
  new URLSearchParams(location.hash.replace(/^#/, "")).forEach((v, k) => P.set(k, v));
  const body = document.body;

  function bytes(b64) {
    const s = atob(b64);
    const u = new Uint8Array(s.length);
    for (let i = 0; i < s.length; i++) u[i] = s.charCodeAt(i);
    return u.buffer;
  }
  const f32 = (b) => new Float32Array(bytes(b));

  // ---------------------------------------------------------------- 4x4 matrices, column-major
  function mul(a, b) {
    const o = new Float32Array(16);
    for (let c = 0; c < 4; c++)
      for (let r = 0; r < 4; r++) {
        let s = 0;
        for (let k = 0; k < 4; k++) s += a[k * 4 + r] * b[c * 4 + k];
        o[c * 4 + r] = s;
      }
    return o;
  }
  function perspective(fovy, aspect, near, far) {
    const f = 1 / Math.tan(fovy / 2), nf = 1 / (near - far);
    return new Float32Array([f / aspect, 0, 0, 0, 0, f, 0, 0, 0, 0, (far + near) * nf, -1, 0, 0, 2 * far * near * nf, 0]);
  }
  const sub = (a, b) => [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
  const cross = (a, b) => [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]];
  const dot = (a, b) => a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
  const norm = (a) => { const l = Math.hypot(a[0], a[1], a[2]) || 1; return [a[0] / l, a[1] / l, a[2] / l]; };
  function lookAt(eye, target, up) {
    const z = norm(sub(eye, target)), x = norm(cross(up, z)), y = cross(z, x);
    return new Float32Array([x[0], y[0], z[0], 0, x[1], y[1], z[1], 0, x[2], y[2], z[2], 0,
      -dot(x, eye), -dot(y, eye), -dot(z, eye), 1]);
  }
  function affine(a, o) { // 3x4 row-major at offset o -> 4x4 column-major
    return new Float32Array([a[o], a[o + 4], a[o + 8], 0, a[o + 1], a[o + 5], a[o + 9], 0,
      a[o + 2], a[o + 6], a[o + 10], 0, a[o + 3], a[o + 7], a[o + 11], 1]);
  }
  const IDENT = new Float32Array([1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1]);

  // ---------------------------------------------------------------- WebGL set-up
  const canvas = document.getElementById("view");
  const gl = canvas.getContext("webgl", { antialias: true, preserveDrawingBuffer: true });
  if (!gl) {
    body.dataset.status = "no-webgl";
    document.getElementById("info").textContent = "WebGL is not available in this browser";
    return;
  }
  const deriv = gl.getExtension("OES_standard_derivatives");
  const uint32 = gl.getExtension("OES_element_index_uint");
  const VS = "attribute vec3 pos; uniform mat4 uModel, uViewProj; uniform float uPoint; varying vec3 vW;" +
    "void main(){ vec4 w = uModel * vec4(pos, 1.0); vW = w.xyz; gl_Position = uViewProj * w; gl_PointSize = uPoint; }";
  const FS = (deriv ? "#extension GL_OES_standard_derivatives : enable\n" : "") +
    "precision highp float; uniform vec3 uColor, uLight, uEye; uniform float uLit, uAlpha; varying vec3 vW;" +
    "void main(){ vec3 c = uColor;" +
    (deriv ? " if (uLit > 0.5) { vec3 n = normalize(cross(dFdx(vW), dFdy(vW))); if (dot(n, uEye - vW) < 0.0) n = -n;" +
      " float d = max(dot(n, uLight), 0.0); c = uColor * (0.38 + 0.5 * d + 0.17 * (0.5 + 0.5 * n.z)); }" : "") +
    " gl_FragColor = vec4(min(c, vec3(1.0)), uAlpha); }";
  function shader(type, src) {
    const s = gl.createShader(type);
    gl.shaderSource(s, src);
    gl.compileShader(s);
    if (!gl.getShaderParameter(s, gl.COMPILE_STATUS)) throw new Error(gl.getShaderInfoLog(s));
    return s;
  }
  const prog = gl.createProgram();
  gl.attachShader(prog, shader(gl.VERTEX_SHADER, VS));
  gl.attachShader(prog, shader(gl.FRAGMENT_SHADER, FS));
  gl.linkProgram(prog);
  gl.useProgram(prog);
  const aPos = gl.getAttribLocation(prog, "pos");
  const U = {};
  for (const n of ["uModel", "uViewProj", "uPoint", "uColor", "uLight", "uEye", "uLit", "uAlpha"]) U[n] = gl.getUniformLocation(prog, n);
  gl.enableVertexAttribArray(aPos);
  gl.enable(gl.DEPTH_TEST);
  gl.uniform1f(U.uAlpha, 1);

  function meshBuffers(m) {
    const vb = gl.createBuffer();
    gl.bindBuffer(gl.ARRAY_BUFFER, vb);
    gl.bufferData(gl.ARRAY_BUFFER, f32(m.vertices), gl.STATIC_DRAW);
    const ib = gl.createBuffer();
    gl.bindBuffer(gl.ELEMENT_ARRAY_BUFFER, ib);
    const wide = m.index_type === "uint32";
    if (wide && !uint32) throw new Error("mesh needs 32-bit indices");
    const idx = wide ? new Uint32Array(bytes(m.triangles)) : new Uint16Array(bytes(m.triangles));
    gl.bufferData(gl.ELEMENT_ARRAY_BUFFER, idx, gl.STATIC_DRAW);
    return { vb, ib, count: idx.length, type: wide ? gl.UNSIGNED_INT : gl.UNSIGNED_SHORT };
  }
  const parts = D.parts.map((p) => Object.assign(meshBuffers(p), { color: p.color }));
  const obstacles = D.obstacles.map((o) => Object.assign(meshBuffers(o), { color: o.color, model: affine(f32(o.pose), 0) }));
  const W = D.world || { obstacles: [], shapes: [], pair_names: [] };
  const worldObs = W.obstacles.map((o) => Object.assign(meshBuffers(o), { color: o.color, model: affine(f32(o.pose), 0) }));
  const shapes = W.shapes.map((o) => Object.assign(meshBuffers(o), { color: o.color }));
  const lineBuf = gl.createBuffer();

  function drawLines(points, color, mode, size) {
    if (points.length < 3) return;
    gl.bindBuffer(gl.ARRAY_BUFFER, lineBuf);
    gl.bufferData(gl.ARRAY_BUFFER, points instanceof Float32Array ? points : new Float32Array(points), gl.DYNAMIC_DRAW);
    gl.vertexAttribPointer(aPos, 3, gl.FLOAT, false, 0, 0);
    gl.uniformMatrix4fv(U.uModel, false, IDENT);
    gl.uniform3fv(U.uColor, color);
    gl.uniform1f(U.uLit, 0);
    gl.uniform1f(U.uPoint, size || 1);
    gl.drawArrays(mode, 0, points.length / 3);
  }
  function drawMesh(m, model, color) {
    gl.bindBuffer(gl.ARRAY_BUFFER, m.vb);
    gl.vertexAttribPointer(aPos, 3, gl.FLOAT, false, 0, 0);
    gl.bindBuffer(gl.ELEMENT_ARRAY_BUFFER, m.ib);
    gl.uniformMatrix4fv(U.uModel, false, model);
    gl.uniform3fv(U.uColor, color);
    gl.uniform1f(U.uLit, 1);
    gl.drawElements(gl.TRIANGLES, m.count, m.type, 0);
  }

  // ---------------------------------------------------------------- runs
  const runs = D.runs.map((r) => ({
    name: r.name, t: r.t, info: r.info, poses: f32(r.poses), prox: f32(r.proximity),
    paths: r.paths.map((p) => ({ name: p.name, desired: f32(p.desired), actual: f32(p.actual), t: r.path_t })),
    frames: r.task_frames.map((f) => ({ name: f.name, actual: f32(f.actual), desired: f32(f.desired) })),
    world: r.world && {
      obPoses: f32(r.world.obstacle_poses), shPoses: f32(r.world.shape_poses), d: r.world.distance,
      p1: f32(r.world.p1), p2: f32(r.world.p2), pair: r.world.pair,
    },
  }));
  const sel = document.getElementById("run");
  runs.forEach((r, i) => { const o = document.createElement("option"); o.value = i; o.textContent = r.name; sel.appendChild(o); });
  let run = Math.max(0, runs.findIndex((r) => r.name === P.get("run")));
  sel.value = run;
  const slider = document.getElementById("slider");
  let frame = 0, playing = !P.has("t") || P.get("play") === "1", clock = 0, last = null;
  const speed = parseFloat(P.get("speed") || "1");
  const showRobot = P.get("robot") !== "0", showPaths = P.get("paths") !== "0";
  let showShapes = P.get("capsules") === "1";
  const capsBtn = document.getElementById("capsules");
  if (shapes.length) {
    capsBtn.hidden = false;
    capsBtn.addEventListener("click", () => { showShapes = !showShapes; render(); });
  }
  if (worldObs.length || runs.some((r) => r.world)) document.getElementById("legend-world").hidden = false;
  const UNIT = D.length_unit || "m";
  const fmtDist = (d) => (UNIT === "m" ? `${(d * 1000).toFixed(1)} mm` : `${d.toPrecision(3)} ${UNIT}`);

  const ORANGE = [0.96, 0.6, 0.12], RED = [0.9, 0.12, 0.1];
  const smooth = (a, b, x) => { const u = Math.min(1, Math.max(0, (x - a) / (b - a))); return u * u * (3 - 2 * u); };
  const mix = (a, b, u) => [a[0] + (b[0] - a[0]) * u, a[1] + (b[1] - a[1]) * u, a[2] + (b[2] - a[2]) * u];
  function partColor(base, p) { return mix(mix(base, ORANGE, smooth(0.6, 0.85, p)), RED, smooth(0.85, 1.0, p)); }

  function nearestFrame(r, t) {
    let best = 0;
    for (let i = 0; i < r.t.length; i++) if (Math.abs(r.t[i] - t) < Math.abs(r.t[best] - t)) best = i;
    return best;
  }

  // ---------------------------------------------------------------- camera
  const C = D.view.center, R = D.view.radius;
  let az = (parseFloat(P.get("az") || "40") * Math.PI) / 180, el = (parseFloat(P.get("el") || "22") * Math.PI) / 180;
  let dist = (R / Math.sin((45 * Math.PI) / 360)) * parseFloat(P.get("zoom") || "0.85");
  function grid() {
    const pts = [], z = D.view.floor, step = D.view.grid, n = Math.ceil((1.4 * R) / step);
    for (let i = -n; i <= n; i++) {
      pts.push(C[0] + i * step, C[1] - n * step, z, C[0] + i * step, C[1] + n * step, z);
      pts.push(C[0] - n * step, C[1] + i * step, z, C[0] + n * step, C[1] + i * step, z);
    }
    return new Float32Array(pts);
  }
  const GRID = grid();

  function triad(a, o, len) {
    const p = [a[o + 3], a[o + 7], a[o + 11]], out = [];
    for (let k = 0; k < 3; k++) out.push(p[0], p[1], p[2], p[0] + len * a[o + k], p[1] + len * a[o + 4 + k], p[2] + len * a[o + 8 + k]);
    return out;
  }
  const AXC = [[0.85, 0.1, 0.1], [0.1, 0.65, 0.1], [0.1, 0.25, 0.9]];

  function render() {
    const dpr = window.devicePixelRatio || 1;
    const w = Math.max(1, Math.floor(canvas.clientWidth * dpr)), h = Math.max(1, Math.floor(canvas.clientHeight * dpr));
    if (canvas.width !== w || canvas.height !== h) { canvas.width = w; canvas.height = h; }
    gl.viewport(0, 0, w, h);
    gl.clearColor(0.965, 0.969, 0.976, 1);
    gl.clear(gl.COLOR_BUFFER_BIT | gl.DEPTH_BUFFER_BIT);
    const eye = [C[0] + dist * Math.cos(el) * Math.cos(az), C[1] + dist * Math.cos(el) * Math.sin(az), C[2] + dist * Math.sin(el)];
    const vp = mul(perspective((45 * Math.PI) / 180, w / h, dist / 100, dist * 10), lookAt(eye, C, [0, 0, 1]));
    gl.uniformMatrix4fv(U.uViewProj, false, vp);
    gl.uniform3fv(U.uEye, eye);
    gl.uniform3fv(U.uLight, norm([eye[0] - C[0], eye[1] - C[1], eye[2] - C[2] + dist]));
    drawLines(GRID, [0.84, 0.85, 0.87], gl.LINES);
    const r = runs[run], np = parts.length;
    if (showRobot)
      for (let p = 0; p < np; p++)
        drawMesh(parts[p], affine(r.poses, (frame * np + p) * 12), partColor(parts[p].color, r.prox[frame * np + p]));
    for (const o of obstacles) drawMesh(o, o.model, o.color);
    const rw = r.world, nob = worldObs.length, nsh = shapes.length;
    for (let i = 0; i < nob; i++) drawMesh(worldObs[i], rw ? affine(rw.obPoses, (frame * nob + i) * 12) : worldObs[i].model, worldObs[i].color);
    if (showShapes && rw && nsh) { // translucent, after the opaque scene, not writing depth
      gl.enable(gl.BLEND);
      gl.blendFunc(gl.SRC_ALPHA, gl.ONE_MINUS_SRC_ALPHA);
      gl.depthMask(false);
      gl.uniform1f(U.uAlpha, 0.35);
      for (let i = 0; i < nsh; i++) drawMesh(shapes[i], affine(rw.shPoses, (frame * nsh + i) * 12), shapes[i].color);
      gl.uniform1f(U.uAlpha, 1);
      gl.depthMask(true);
      gl.disable(gl.BLEND);
    }
    let closest = "";
    if (rw && rw.d[frame] !== null && rw.pair[frame] >= 0) {
      const a = rw.p1.subarray(3 * frame, 3 * frame + 3), b = rw.p2.subarray(3 * frame, 3 * frame + 3), d = rw.d[frame];
      const col = d < 0 ? [0.9, 0.1, 0.1] : [0.76, 0.12, 0.76];
      gl.disable(gl.DEPTH_TEST);
      drawLines([a[0], a[1], a[2], b[0], b[1], b[2]], col, gl.LINES);
      drawLines([a[0], a[1], a[2], b[0], b[1], b[2]], col, gl.POINTS, 7);
      gl.enable(gl.DEPTH_TEST);
      closest = `${W.pair_names[rw.pair[frame]]} ${fmtDist(d)}${d < 0 ? " (penetration)" : ""}`;
    }
    if (showPaths) {
      const tNow = r.t[frame];
      for (const path of r.paths) {
        drawLines(path.desired, [0.1, 0.6, 0.25], gl.LINE_STRIP);
        let n = 0;
        while (n < path.t.length && path.t[n] <= tNow + 1e-9) n++;
        drawLines(path.actual.subarray(0, 3 * n), [0.15, 0.35, 0.9], gl.LINE_STRIP);
      }
      gl.disable(gl.DEPTH_TEST);
      for (const f of r.frames) {
        const len = 0.12 * R, a = triad(f.actual, frame * 12, len), d = triad(f.desired, frame * 12, 0.7 * len);
        for (let k = 0; k < 3; k++) {
          drawLines(a.slice(6 * k, 6 * k + 6), AXC[k], gl.LINES);
          drawLines(d.slice(6 * k, 6 * k + 6), mix(AXC[k], [1, 1, 1], 0.45), gl.LINES);
        }
        drawLines([f.desired[frame * 12 + 3], f.desired[frame * 12 + 7], f.desired[frame * 12 + 11]], [0.1, 0.6, 0.25], gl.POINTS, 9);
      }
      gl.enable(gl.DEPTH_TEST);
    }
    slider.value = frame;
    document.getElementById("time").textContent = `t = ${r.t[frame].toFixed(3)} s`;
    const info = Object.entries(r.info).map(([k, v]) => `${k}: ${typeof v === "number" ? v.toPrecision(3) : v}`);
    if (closest) info.unshift(`closest: ${closest}`);
    document.getElementById("info").textContent = info.join(" · ");
    capsBtn.textContent = showShapes ? "hide capsules" : "capsules";
    body.dataset.capsules = showShapes && nsh ? "shown" : "hidden";
    body.dataset.closest = closest;
    body.dataset.status = "drawn";
    body.dataset.frame = frame;
    body.dataset.run = r.name;
  }

  function selectRun(i) {
    const t = runs[run].t[frame];
    run = i;
    slider.max = runs[run].t.length - 1;
    frame = nearestFrame(runs[run], t);
    render();
  }
  sel.addEventListener("change", () => selectRun(parseInt(sel.value, 10)));
  slider.addEventListener("input", () => { frame = parseInt(slider.value, 10); playing = false; render(); });
  const playBtn = document.getElementById("play");
  function setPlaying(p) { playing = p; playBtn.textContent = p ? "pause" : "play"; last = null; if (p) requestAnimationFrame(tick); }
  playBtn.addEventListener("click", () => setPlaying(!playing));
  function tick(ts) {
    if (!playing) return;
    const r = runs[run], T = r.t[r.t.length - 1];
    if (last !== null) clock = (clock + ((ts - last) / 1000) * speed) % (T > 0 ? T : 1);
    last = ts;
    frame = nearestFrame(r, clock);
    render();
    requestAnimationFrame(tick);
  }
  let drag = null;
  canvas.addEventListener("mousedown", (e) => { drag = [e.clientX, e.clientY]; });
  window.addEventListener("mouseup", () => { drag = null; });
  window.addEventListener("mousemove", (e) => {
    if (!drag) return;
    az -= (e.clientX - drag[0]) * 0.01;
    el = Math.max(-1.5, Math.min(1.5, el + (e.clientY - drag[1]) * 0.01));
    drag = [e.clientX, e.clientY];
    render();
  });
  canvas.addEventListener("wheel", (e) => { e.preventDefault(); dist *= Math.exp(e.deltaY * 0.001); render(); }, { passive: false });
  window.addEventListener("resize", render);

  slider.max = runs[run].t.length - 1;
  if (P.has("t")) { frame = nearestFrame(runs[run], parseFloat(P.get("t"))); clock = runs[run].t[frame]; }
  render();
  setPlaying(playing);
})();
