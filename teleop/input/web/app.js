// dexaug headset page: WebXR hand tracking → WebSocket → bridge; bridge /view → panel in VR.
//
// Why one small module without a framework: it runs in the Quest Browser (and in headless
// Chromium with IWER for the tests); everything it needs is WebXR, WebGL2 and a WebSocket.
// The binary hand-frame layout is documented in teleop/input/web_protocol.py (magic "DXW1").

const JOINTS = [
  'wrist',
  'thumb-metacarpal', 'thumb-phalanx-proximal', 'thumb-phalanx-distal', 'thumb-tip',
  'index-finger-metacarpal', 'index-finger-phalanx-proximal', 'index-finger-phalanx-intermediate',
  'index-finger-phalanx-distal', 'index-finger-tip',
  'middle-finger-metacarpal', 'middle-finger-phalanx-proximal',
  'middle-finger-phalanx-intermediate', 'middle-finger-phalanx-distal', 'middle-finger-tip',
  'ring-finger-metacarpal', 'ring-finger-phalanx-proximal', 'ring-finger-phalanx-intermediate',
  'ring-finger-phalanx-distal', 'ring-finger-tip',
  'pinky-finger-metacarpal', 'pinky-finger-phalanx-proximal', 'pinky-finger-phalanx-intermediate',
  'pinky-finger-phalanx-distal', 'pinky-finger-tip',
];
const THUMB_TIP = 4, INDEX_TIP = 9, MIDDLE_TIP = 14;
const HEADER_BYTES = 48, HAND_FLOATS = 25 * 8;
const PINCH_ON_M = 0.015, PINCH_OFF_M = 0.03, PINCH_HOLD_S = 0.7;
const MAX_BUFFERED_BYTES = 64 * 1024;   // skip a frame rather than queue stale ones
const NO_HANDS_AFTER_S = 3.0;

const params = new URLSearchParams(location.search);
// this start's access token from the printed URL: sent on the WebSocket handshake and with every
// control message (the bridge requires it off loopback; on loopback it lets this page take the
// rig over from a client without it)
const token = params.get('token') || '';
const $ = (id) => document.getElementById(id);

// ------------------------------------------------------------------------------ page state

export const stats = {
  framesSent: 0, framesSkipped: 0, framesWithHands: 0, viewsReceived: 0, viewBytes: 0,
  lastViewSize: null, connects: 0, refused: null, state: null, status: null, messages: [],
  xrFrames: 0, sessionActive: false, handTracking: null,
};
window.dexaug = { stats };

let message = { text: '', level: '' };
let blocking = null;  // a problem that stays on screen whatever the link does (no WebXR, no hands)
function block(text) { blocking = text; say(text, 'error'); }
function say(text, level = '') {
  message = { text, level };
  const el = $('message');
  el.textContent = text;
  el.className = level;
  stats.messages.push({ t: performance.now(), text, level });
  if (stats.messages.length > 50) stats.messages.shift();
  panel.dirty = true;
}

// The bridge's grasp cue (teleop.bridge.grasp_assist): stable enough to mark, and the assist.
function gripCue(st) {
  if (!st || !st.grasp_held_s) return 'grip: –';
  const assist = st.assist ? ` · assist ${Math.round(100 * st.assist)} %` : '';
  return st.grasp_stable ? `grip: stable, mark it${assist}`
    : `grip: hold… ${st.grasp_held_s.toFixed(1)} s${assist}`;
}

function updateHud() {
  const st = stats.state, status = stats.status;
  $('link').textContent = `link: ${link.state}`;
  const rec = status && status.recording;
  $('recording').textContent = rec ? `● REC ${rec.split('/').pop()}` : 'not recording';
  $('record').textContent = rec ? 'Stop recording' : 'Start recording';
  $('record').className = rec ? 'rec' : '';
  const fingers = st && st.contact_fingers && st.contact_fingers.length
    ? st.contact_fingers.join(', ') : 'none';
  $('contacts').textContent = `contacts: ${fingers}${st && st.held ? ' (hand held)' : ''}`;
  $('grip').textContent = gripCue(st);
  $('grip').className = st && st.grasp_stable ? 'stable' : '';
  $('counters').textContent = `sent ${stats.framesSent} · views ${stats.viewsReceived}`;
  const usable = link.state === 'connected';
  $('record').disabled = !usable;
  $('mark').disabled = !usable;
  $('rest').disabled = !usable;
  panel.dirty = true;
}

// ------------------------------------------------------------------------------ WebSocket

let clientId = sessionStorage.getItem('dexaug-client-id');
if (!clientId) {
  clientId = (crypto.randomUUID ? crypto.randomUUID() : String(Math.random()).slice(2));
  sessionStorage.setItem('dexaug-client-id', clientId);
}

const link = { ws: null, state: 'connecting', attempt: 0, refused: false, replaced: false, nextId: 1 };

function wsUrl() {
  const override = params.get('ws');
  if (override) return override;  // development only; the token goes to this page's host only
  const query = token ? `?token=${encodeURIComponent(token)}` : '';
  return `${location.protocol === 'https:' ? 'wss' : 'ws'}://${location.host}/ws${query}`;
}

function connect() {
  let ws;
  try {
    ws = new WebSocket(wsUrl());
  } catch (err) {
    scheduleReconnect(`cannot open the WebSocket: ${err}`);
    return;
  }
  ws.binaryType = 'blob';
  link.ws = ws;
  link.state = 'connecting';
  ws.onopen = () => {
    ws.send(JSON.stringify({ type: 'hello', client_id: clientId, user_agent: navigator.userAgent }));
  };
  ws.onmessage = (ev) => {
    if (typeof ev.data === 'string') onText(JSON.parse(ev.data));
    else onView(ev.data);
  };
  ws.onclose = (ev) => {
    if (link.ws !== ws) return;
    link.ws = null;
    if (link.replaced) {
      // a headset with the token took the rig over: retrying would only be refused or, with the
      // token, fight it; a reload (from the printed URL) takes it back
      link.state = 'replaced';
      updateHud();
      return;
    }
    if (link.refused) {
      link.state = 'refused';
      updateHud();
      // keep trying slowly: when the other headset leaves, this one gets the rig
      setTimeout(connect, 5000);
      return;
    }
    scheduleReconnect(`connection to the bridge lost (code ${ev.code})`);
  };
}

function scheduleReconnect(why) {
  link.attempt += 1;
  link.state = 'disconnected';
  const delayS = Math.min(5, 0.5 * 2 ** Math.min(link.attempt - 1, 4));
  say(`Disconnected, reconnecting… (${why}; attempt ${link.attempt}, next in ${delayS.toFixed(1)} s)`,
      'warn');
  updateHud();
  setTimeout(connect, delayS * 1000);
}

function onText(msg) {
  switch (msg.type) {
    case 'welcome':
      link.state = 'connected';
      link.attempt = 0;
      link.refused = false;
      stats.connects += 1;
      stats.refused = null;
      for (const n of pendingNotices.splice(0)) send(n);
      if (blocking) say(`Connected to the bridge (rig ${msg.rig}), but: ${blocking}`, 'error');
      else say(stats.sessionActive ? 'Connected to the bridge; streaming hands.'
        : `Connected to the bridge (rig ${msg.rig}). Press "Enter VR".`, 'ok');
      break;
    case 'refused':
      link.refused = true;
      stats.refused = msg.reason;
      say(`Refused by the bridge: ${msg.reason}. Retrying every 5 s.`, 'error');
      break;
    case 'replaced':
      link.replaced = true;
      stats.refused = msg.reason;
      say(`Disconnected: ${msg.reason}. Reload the page to connect again.`, 'error');
      break;
    case 'state':
      stats.state = msg;
      break;
    case 'status':
      stats.status = msg;
      if (!msg.bridge && link.state === 'connected' && !blocking) say(`The bridge does not answer: ${msg.error}`, 'warn');
      break;
    case 'event':
      if (msg.event && msg.event.type === 'grasp_mark') {
        say(`Grasp marked (fingers: ${(msg.event.fingers || []).join(', ') || 'none'})`, 'ok');
      }
      break;
    case 'control_reply':
      if (!msg.result.ok) say(`${msg.command} failed: ${msg.result.error}`, 'error');
      else if (msg.command === 'start_recording') say(`Recording to ${msg.result.path}`, 'ok');
      else if (msg.command === 'stop_recording') say(`Saved ${msg.result.path}`, 'ok');
      break;
    default:
      break;
  }
  updateHud();
}

function send(obj) {
  if (link.ws && link.ws.readyState === WebSocket.OPEN) {
    link.ws.send(JSON.stringify(obj));
    return true;
  }
  return false;
}

function control(command) {
  if (!send({ type: 'control', command, id: link.nextId++, token })) {
    say(`${command}: not connected to the bridge`, 'warn');
  }
}

const pendingNotices = [];
function notice(what, text) {
  // the bridge logs these; kept until the link is up so a problem at load time is logged too
  const msg = { type: 'notice', what, message: text };
  if (link.state !== 'connected' || !send(msg)) pendingNotices.push(msg);
}

// ------------------------------------------------------------------------------ view frames

const viewImg = $('view');
let viewUrl = null;
async function onView(blob) {
  stats.viewsReceived += 1;
  stats.viewBytes += blob.size;
  if (viewUrl) URL.revokeObjectURL(viewUrl);
  viewUrl = URL.createObjectURL(blob);
  viewImg.src = viewUrl;
  if (stats.sessionActive) {
    try {
      panel.image = await createImageBitmap(blob);
      stats.lastViewSize = [panel.image.width, panel.image.height];
      panel.dirty = true;
    } catch (err) {
      // a truncated JPEG: the next one replaces it
    }
  }
  if (stats.viewsReceived % 15 === 1) updateHud();
}

// ------------------------------------------------------------------------------ hand frames

const frameBuf = new ArrayBuffer(HEADER_BYTES + 2 * HAND_FLOATS * 4);
const frameView = new DataView(frameBuf);
const handScratch = { left: new Float32Array(HAND_FLOATS), right: new Float32Array(HAND_FLOATS) };

function readHand(frame, hand, refSpace, out) {
  // 25 × (p3, q4 xyzw, radius) relative to the reference space; NaN for a missing joint
  let any = false;
  for (let i = 0; i < 25; i++) {
    const space = hand.get(JOINTS[i]);
    const pose = space ? frame.getJointPose(space, refSpace) : null;
    const o = i * 8;
    if (!pose) {
      out.fill(NaN, o, o + 8);
      continue;
    }
    any = true;
    const p = pose.transform.position, q = pose.transform.orientation;
    out[o] = p.x; out[o + 1] = p.y; out[o + 2] = p.z;
    out[o + 3] = q.x; out[o + 4] = q.y; out[o + 5] = q.z; out[o + 6] = q.w;
    out[o + 7] = pose.radius ?? NaN;
  }
  return any;
}

function packFrame(seq, tMs, head, hands) {
  const v = frameView;
  v.setUint8(0, 0x44); v.setUint8(1, 0x58); v.setUint8(2, 0x57); v.setUint8(3, 0x31); // DXW1
  v.setUint32(4, seq >>> 0, true);
  v.setFloat64(8, tMs, true);
  v.setUint8(16, (hands.left ? 1 : 0) | (hands.right ? 2 : 0));
  const p = head.position, q = head.orientation;
  [p.x, p.y, p.z, q.x, q.y, q.z, q.w].forEach((x, k) => v.setFloat32(20 + 4 * k, x, true));
  let off = HEADER_BYTES;
  for (const side of ['left', 'right']) {
    if (!hands[side]) continue;
    new Float32Array(frameBuf, off, HAND_FLOATS).set(hands[side]);
    off += HAND_FLOATS * 4;
  }
  return new Uint8Array(frameBuf, 0, off);
}

// ------------------------------------------------------------------------------ gestures

class PinchHold {
  // fires once when thumb and a finger stay pinched PINCH_HOLD_S; re-arms after release
  constructor(finger, action) { this.finger = finger; this.action = action; this.since = null; this.fired = false; }
  update(joints, tS) {
    const a = THUMB_TIP * 8, b = this.finger * 8;
    const d = Math.hypot(joints[a] - joints[b], joints[a + 1] - joints[b + 1], joints[a + 2] - joints[b + 2]);
    if (!(d < PINCH_OFF_M)) { this.since = null; this.fired = false; return; }
    if (d < PINCH_ON_M && this.since === null) this.since = tS;
    if (this.since !== null && !this.fired && tS - this.since >= PINCH_HOLD_S) {
      this.fired = true;
      this.action();
    }
  }
}

function toggleRecording() {
  control(stats.status && stats.status.recording ? 'stop_recording' : 'start_recording');
}

const gestures = [new PinchHold(INDEX_TIP, toggleRecording), new PinchHold(MIDDLE_TIP, () => control('mark_grasp'))];

// ------------------------------------------------------------------------------ the VR panel

const panel = { image: null, dirty: true, canvas: null, ctx2d: null, tex: null, pose: null };
const PANEL_W_M = 0.64, PANEL_H_M = 0.56, PANEL_DIST_M = 0.9;

function drawPanelCanvas() {
  if (!panel.canvas) {
    panel.canvas = document.createElement('canvas');
    panel.canvas.width = 640; panel.canvas.height = 560;
    panel.ctx2d = panel.canvas.getContext('2d');
  }
  const c = panel.ctx2d;
  c.fillStyle = '#111'; c.fillRect(0, 0, 640, 560);
  if (panel.image) c.drawImage(panel.image, 0, 0, 640, 480);
  else { c.fillStyle = '#888'; c.font = '28px sans-serif'; c.fillText('waiting for the bridge view…', 120, 240); }
  const rec = stats.status && stats.status.recording;
  c.fillStyle = rec ? '#c23b3b' : '#333'; c.fillRect(0, 480, 640, 80);
  c.fillStyle = '#fff'; c.font = 'bold 26px sans-serif';
  c.fillText(rec ? '● REC' : 'not recording', 12, 512);
  const st = stats.state;
  const fingers = st && st.contact_fingers && st.contact_fingers.length ? st.contact_fingers.join(' ') : '–';
  c.font = '22px sans-serif';
  c.fillText(`contacts: ${fingers}`, 200, 512);
  c.fillStyle = st && st.grasp_stable ? '#7dff9a' : '#ddd';
  c.fillText(gripCue(st), 420, 512);
  c.fillStyle = message.level === 'error' ? '#ffb0b0' : message.level === 'warn' ? '#ffe0a0' : '#ddd';
  c.fillText(message.text.slice(0, 60), 12, 546);
}

const VS = `#version 300 es
in vec2 a_uv; uniform mat4 u_mvp; uniform vec2 u_size; out vec2 v_uv;
void main() { v_uv = a_uv; gl_Position = u_mvp * vec4((a_uv.x - 0.5) * u_size.x, (0.5 - a_uv.y) * u_size.y, 0.0, 1.0); }`;
const FS = `#version 300 es
precision mediump float; in vec2 v_uv; uniform sampler2D u_tex; out vec4 color;
void main() { color = texture(u_tex, v_uv); }`;

function makeProgram(gl) {
  const sh = (type, src) => {
    const s = gl.createShader(type); gl.shaderSource(s, src); gl.compileShader(s);
    if (!gl.getShaderParameter(s, gl.COMPILE_STATUS)) throw new Error(gl.getShaderInfoLog(s));
    return s;
  };
  const prog = gl.createProgram();
  gl.attachShader(prog, sh(gl.VERTEX_SHADER, VS));
  gl.attachShader(prog, sh(gl.FRAGMENT_SHADER, FS));
  gl.linkProgram(prog);
  if (!gl.getProgramParameter(prog, gl.LINK_STATUS)) throw new Error(gl.getProgramInfoLog(prog));
  const buf = gl.createBuffer();
  gl.bindBuffer(gl.ARRAY_BUFFER, buf);
  gl.bufferData(gl.ARRAY_BUFFER, new Float32Array([0, 0, 0, 1, 1, 0, 1, 1]), gl.STATIC_DRAW);
  const vao = gl.createVertexArray();
  gl.bindVertexArray(vao);
  const loc = gl.getAttribLocation(prog, 'a_uv');
  gl.enableVertexAttribArray(loc);
  gl.vertexAttribPointer(loc, 2, gl.FLOAT, false, 0, 0);
  panel.tex = gl.createTexture();
  gl.bindTexture(gl.TEXTURE_2D, panel.tex);
  gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_MIN_FILTER, gl.LINEAR);
  gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_WRAP_S, gl.CLAMP_TO_EDGE);
  gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_WRAP_T, gl.CLAMP_TO_EDGE);
  return { prog, vao, mvp: gl.getUniformLocation(prog, 'u_mvp'), size: gl.getUniformLocation(prog, 'u_size') };
}

function mul4(a, b) {  // column-major 4×4 product a·b
  const o = new Float32Array(16);
  for (let c = 0; c < 4; c++) for (let r = 0; r < 4; r++) {
    let s = 0;
    for (let k = 0; k < 4; k++) s += a[k * 4 + r] * b[c * 4 + k];
    o[c * 4 + r] = s;
  }
  return o;
}

function placePanel(viewerTransform) {
  // world-fixed, in front of where the user looked when the session started, facing them
  const m = viewerTransform.matrix, p = viewerTransform.position;
  let fx = -m[8], fz = -m[10];
  const n = Math.hypot(fx, fz) || 1; fx /= n; fz /= n;
  const yaw = Math.atan2(-fx, -fz);   // rotation about +Y taking −Z to (fx, fz)
  const c = Math.cos(yaw), s = Math.sin(yaw);
  panel.pose = new Float32Array([c, 0, -s, 0, 0, 1, 0, 0, s, 0, c, 0,
    p.x + fx * PANEL_DIST_M, p.y - 0.15, p.z + fz * PANEL_DIST_M, 1]);
}

function drawPanel(gl, glp, views, layer) {
  if (panel.dirty) {
    drawPanelCanvas();
    gl.bindTexture(gl.TEXTURE_2D, panel.tex);
    gl.texImage2D(gl.TEXTURE_2D, 0, gl.RGBA, gl.RGBA, gl.UNSIGNED_BYTE, panel.canvas);
    panel.dirty = false;
  }
  gl.bindFramebuffer(gl.FRAMEBUFFER, layer.framebuffer);
  gl.clearColor(0.08, 0.09, 0.1, 1); gl.enable(gl.DEPTH_TEST);
  gl.clear(gl.COLOR_BUFFER_BIT | gl.DEPTH_BUFFER_BIT);
  gl.useProgram(glp.prog); gl.bindVertexArray(glp.vao);
  gl.bindTexture(gl.TEXTURE_2D, panel.tex);
  gl.uniform2f(glp.size, PANEL_W_M, PANEL_H_M);
  for (const view of views) {
    const vp = layer.getViewport(view);
    gl.viewport(vp.x, vp.y, vp.width, vp.height);
    const mvp = mul4(view.projectionMatrix, mul4(view.transform.inverse.matrix, panel.pose));
    gl.uniformMatrix4fv(glp.mvp, false, mvp);
    gl.drawArrays(gl.TRIANGLE_STRIP, 0, 4);
  }
}

// ------------------------------------------------------------------------------ XR session

let emulation = null;

async function enterVR() {
  if (!navigator.xr) { say('This browser has no WebXR: open the page in the Quest Browser.', 'error'); return; }
  let session;
  try {
    session = await navigator.xr.requestSession('immersive-vr', {
      requiredFeatures: ['local-floor'], optionalFeatures: ['hand-tracking'],
    });
  } catch (err) {
    say(`Could not start VR: ${err.message || err}`, 'error');
    notice('session_failed', `requestSession failed: ${err.message || err}`);
    return;
  }
  const canvas = document.createElement('canvas');
  const gl = canvas.getContext('webgl2', { xrCompatible: true, antialias: false });
  if (!gl) { say('WebGL 2 is unavailable; cannot show the panel.', 'error'); await session.end(); return; }
  let glp;
  try { glp = makeProgram(gl); } catch (err) { say(`WebGL error: ${err.message}`, 'error'); await session.end(); return; }
  session.updateRenderState({ baseLayer: new XRWebGLLayer(session, gl) });
  const refSpace = await session.requestReferenceSpace('local-floor');
  stats.sessionActive = true;
  window.dexaug.session = session;
  $('enter').disabled = true;
  const features = session.enabledFeatures;
  stats.handTracking = features ? features.includes('hand-tracking') : null;
  if (stats.handTracking === false) {
    const text = 'Hand tracking is not available in this session: enable it in the headset ' +
      '(Settings → Movement tracking → Hand tracking) and reload. Controllers are not streamed.';
    block(text);
    notice('no_hand_tracking', text);
  } else {
    say('In VR: streaming hands to the bridge.', 'ok');
  }
  session.addEventListener('end', () => {
    stats.sessionActive = false; $('enter').disabled = false; say('Left VR.', '');
  });
  if (emulation) await emulation.afterSessionStart(session, refSpace, params);

  const t0 = performance.now();
  let warnedNoHands = false;
  const onFrame = (time, frame) => {
    session.requestAnimationFrame(onFrame);
    stats.xrFrames += 1;
    if (emulation) emulation.onXRFrame(stats.xrFrames);
    const viewer = frame.getViewerPose(refSpace);
    if (!viewer) return;
    if (!panel.pose) placePanel(viewer.transform);
    const hands = {};
    for (const src of session.inputSources) {
      if (src.hand && (src.handedness === 'left' || src.handedness === 'right') && !hands[src.handedness]) {
        if (readHand(frame, src.hand, refSpace, handScratch[src.handedness])) hands[src.handedness] = handScratch[src.handedness];
      }
    }
    const tS = time / 1000;
    if (hands.left) for (const g of gestures) g.update(hands.left, tS);
    if (hands.left || hands.right) {
      stats.framesWithHands += 1;
      if (warnedNoHands && blocking) { blocking = null; warnedNoHands = false; say('Hands tracked; streaming.', 'ok'); }
    }
    else if (!warnedNoHands && stats.handTracking !== false && (performance.now() - t0) / 1000 > NO_HANDS_AFTER_S && stats.framesWithHands === 0) {
      warnedNoHands = true;
      const text = 'No hands tracked yet: put the controllers down and hold your hands in view ' +
        '(hand tracking must be on in the headset settings).';
      block(text);
      notice('no_hands_tracked', text);
    }
    const ws = link.ws;
    if (ws && link.state === 'connected' && ws.readyState === WebSocket.OPEN) {
      if (ws.bufferedAmount > MAX_BUFFERED_BYTES) stats.framesSkipped += 1;
      else {
        ws.send(packFrame(stats.xrFrames, performance.timeOrigin + time, viewer.transform, hands));
        stats.framesSent += 1;
      }
    }
    drawPanel(gl, glp, viewer.views, session.renderState.baseLayer);
  };
  session.requestAnimationFrame(onFrame);
}

// ------------------------------------------------------------------------------ start

async function main() {
  $('record').onclick = toggleRecording;
  $('mark').onclick = () => control('mark_grasp');
  $('rest').onclick = () => control('next_object_rest');
  $('enter').onclick = enterVR;
  setInterval(updateHud, 500);
  const emulate = params.get('emulate');
  if (emulate) {
    try {
      emulation = await import('/static/emulate.js');
      await emulation.install(emulate, params);
    } catch (err) {
      say(`Emulation ${emulate} failed: ${err.message || err}`, 'error');
      return;
    }
  }
  connect();
  if (!navigator.xr) {
    block('This browser has no WebXR: open this page in the Quest Browser on the headset.');
    notice('no_webxr', `browser without WebXR: ${navigator.userAgent}`);
    return;
  }
  let supported = false;
  try { supported = await navigator.xr.isSessionSupported('immersive-vr'); } catch (err) { supported = false; }
  if (!supported) {
    block('This browser cannot start an immersive VR session (no headset?).');
    notice('no_immersive_vr', `immersive-vr unsupported: ${navigator.userAgent}`);
    return;
  }
  $('enter').disabled = false;
  if (link.state !== 'connected') say('Ready. Connecting to the bridge…');
}

main();
