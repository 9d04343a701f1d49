// Development and test only: emulate a Meta Quest 3 in a desktop browser with IWER (the
// Immersive Web Emulation Runtime, npm package "iwer") and optionally replay a recorded Quest
// session (an IWER ActionRecorder capture) through it, so the page runs exactly as on a headset.
//
// Loaded by app.js only when the URL has ?emulate=quest3 (or quest3-nohands: a Quest 3 whose
// runtime offers no hand tracking). The IWER ES module bundle comes from ?iwer=URL (default
// /dev/iwer/iwer.module.js, which the server maps only when started with a dev_static "iwer"
// folder). Replay: ?capture=URL of a capture module (`export {capture}`), &from=&to= frame
// range, played one recorded frame per XR frame (ActionPlayer.stepFrames, no interpolation), so
// every frame the page sends is one recorded frame exactly.

export const replay = { started: false, done: false, log: [], from: 0, to: 0, error: null };
let device = null;
let player = null;
let P_PLAYER = null;  // IWER's private-state symbol of ActionPlayer

export async function install(kind, params) {
  const iwer = await import(params.get('iwer') || '/dev/iwer/iwer.module.js');
  P_PLAYER = iwer.P_ACTION_PLAYER;
  const config = { ...iwer.metaQuest3 };
  if (kind === 'quest3-nohands') {
    config.supportedFeatures = config.supportedFeatures.filter((f) => f !== 'hand-tracking');
  } else if (kind !== 'quest3') {
    throw new Error(`unknown emulation ${kind}; use quest3 or quest3-nohands`);
  }
  device = new iwer.XRDevice(config);
  device.installRuntime({ forceInstall: true });  // Chromium has a (headset-less) navigator.xr
  if (kind === 'quest3') device.primaryInputMode = 'hand';
  window.dexaug.emulation = { kind, device, replay };
}

export async function afterSessionStart(session, refSpace, params) {
  const url = params.get('capture');
  if (!url) return;
  try {
    const { capture } = await import(url);
    const from = Math.max(0, parseInt(params.get('from') || '0', 10));
    const to = Math.min(capture.frames.length - 1, parseInt(params.get('to') || `${capture.frames.length - 1}`, 10));
    replay.from = from;
    replay.to = to;
    player = device.createActionPlayer(refSpace, { schema: capture.schema, frames: capture.frames.slice(from, to + 1) });
    player.play();
    player.playFrame = () => player.stepFrames(1);
    replay.started = true;
  } catch (err) {
    replay.error = String(err.message || err);
    throw err;
  }
}

// called by app.js once per XR frame with the sequence number it sends: which capture row the
// frame showed (the player advanced in this frame's onFrameStart)
export function onXRFrame(seq) {
  if (!player || replay.done) return;
  if (!player.playing) { replay.done = true; return; }
  replay.log.push([seq, replay.from + player[P_PLAYER].recordedFramePointer]);
}
