"""Hand-tracking ingest: headsets, streamer apps and files → :class:`teleop.messages.HandFrame`.

What it holds: live ingest from a headset browser (:mod:`~teleop.input.web_ingest`, the WebXR
page over HTTPS and its WebSocket; :mod:`~teleop.input.web_protocol`, :mod:`~teleop.input.tls`,
:mod:`~teleop.input.background_server`, :mod:`~teleop.input.access`) and from native streamer
apps over UDP/TCP (:mod:`~teleop.input.stream_ingest`); the one boundary between conventions
(:mod:`~teleop.input.webxr`, :mod:`~teleop.input.frames`: WebXR +Y up, xyzw → MuJoCo +Z up,
wxyz); offline inputs — IWER captures (:mod:`~teleop.input.iwer`, with
:mod:`~teleop.input.js_literal`), keypoint trajectories (:mod:`~teleop.input.keypoints`,
:mod:`~teleop.input.trajectory`).

What to import: ``from teleop.input.web_ingest import WebIngest`` (or ``stream_ingest``) to serve
a headset, ``from teleop.input.trajectory import load_trajectory, import_trajectory`` for files,
and the conversions from :mod:`~teleop.input.webxr`. Frames leave here in MuJoCo's conventions.
"""
