"""Roll a grasp out as an episode, by the validator that judges it.

:func:`rollout` places the grasp with :meth:`sim.validate.validator.Validator.start` (the
validator's scene, placement, penetration check and targets) and carries out the lift-drop
program it returns with a :class:`sim.episodes.cursor.ProgramCursor`, one physics step at a
time, recording every step. Nothing of the protocol is written here: the run *is* the
validation, so the episode's verdict is the validator's for that grasp (``validate`` gives the
same result bit for bit: ``mj_step`` N times is ``mj_step(nstep=N)``). A grasp the validator
rejects before simulating (penetration, no hand body near the object) gives an episode of no
steps with that failure. An optional approach (:mod:`sim.episodes.approach`) is recorded
before the program starts; the program then runs from where it left the hand.

Stage names come from where the program stands when a request starts: before it measured the
contacts, a control ramp is ``close`` and the rest ``settle``; then ``lift`` until the
result has its lift phase, ``hold`` until it has its hold phase, then ``release``
(:mod:`sim.validate.lift_drop` fills them in that order). An ``Advance`` that carried its
stage's name (a field of :class:`sim.validate.program.Advance`) would make this reading
unnecessary.
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Sequence

import mujoco
import numpy as np

from sim.episodes.approach import approach_path, back_off, touching
from sim.episodes.cursor import ProgramCursor
from sim.episodes.episode import Episode, EpisodeSet
from sim.episodes.observe import STATE_KEYS, fingertip_bodies, read_state
from sim.grasp import Grasp
from sim.validate.program import STATE_SPEC, Advance, Program, save_state
from sim.validate.result import ValidationResult
from sim.validate.validator import Validator
from sim.world.render import frame_points
from sim.world.scene import Scene

__all__ = ["APPROACH_SETTLE_S", "CAMERA", "PROTOCOL", "rollout", "rollout_all", "stage_of"]

log = logging.getLogger(__name__)

#: the protocol episodes are rolled out by (its program ends in a verdict on a held object)
PROTOCOL = "lift-drop"
#: how long the approach holds the base target at the grasp before the closing (seconds): the
#: weld's 10 ms time constant brings the base to rest on it well within
APPROACH_SETTLE_S = 0.1
#: the scene camera the environment's image observation is rendered from (sim.world.scene:
#: aimed at the object from 0.74 m, the whole table scene in view)
CAMERA = "overview"
#: the episode camera's direction (degrees; as sim.world.render.render_scene's default view)
VIEW_AZIMUTH_DEG, VIEW_ELEVATION_DEG = 135.0, -25.0


def stage_of(request: Advance, result: ValidationResult) -> str:
    """The stage (:data:`sim.episodes.episode.STAGES`) of a lift-drop request that starts
    now, from what ``result`` holds so far (module docstring)."""
    if not result.phases and not len(result.contact_pos_obj) and result.n_contacts == 0:
        return "close" if request.ctrl_from is not None else "settle"
    if "lift" not in result.phases:
        return "lift"
    if "hold" not in result.phases:
        return "hold"
    return "release"


class _Recorder:
    """Rows of one episode as the steps come; with ``renderer``, an image with every
    ``every``-th state row from a camera that stands still for the episode, framed at its
    start on the object, the palm and the fingertips where they are and ``rise_m`` above
    (the lift; :func:`_framed_camera`).

    Why not the scene's overview camera: it shows the table scene from 0.74 m, where a hand
    fills a few dozen pixels of a small image (a 17 mm die: one or two). Shadows are off: the
    shadow map (4096² by default, whatever the image size) took 70 of the 76 ms of a 64×64
    frame with software EGL, measured."""

    def __init__(self, scene: Scene, renderer: mujoco.Renderer | None = None,
                 every: int = 1, rise_m: float = 0.0) -> None:
        self.scene = scene
        self.tips = fingertip_bodies(scene)
        self.renderer, self.every, self.rise_m = renderer, every, rise_m
        self.camera = mujoco.MjvCamera()
        if renderer is not None:
            renderer.scene.flags[mujoco.mjtRndFlag.mjRND_SHADOW] = False
        self.restart()

    def restart(self) -> None:
        """Forget what was recorded; the scene as it stands is row 0."""
        self.frames: list[np.ndarray] = []
        self.frame_rows: list[int] = []
        self.rows: dict[str, list[np.ndarray]] = {k: [] for k in STATE_KEYS}
        self.steps: dict[str, list[object]] = {k: [] for k in (
            "time_s", "stage", "ctrl", "base_target_pos", "base_target_quat", "gravity",
            "object_force", "pin_pose")}
        self.initial = save_state(self.scene)
        self.camera = _framed_camera(self.scene, self.tips, self.rise_m)
        self.state()

    def state(self) -> None:
        for k, v in read_state(self.scene, self.tips).items():
            self.rows[k].append(v)
        row = len(self.rows["hand_qpos"]) - 1
        if self.renderer is not None and row % self.every == 0:
            self.renderer.update_scene(self.scene.data, camera=self.camera)
            self.frames.append(self.renderer.render().copy())
            self.frame_rows.append(row)

    def action(self, stage: str, pin: tuple[np.ndarray, np.ndarray] | None) -> None:
        m, d, s = self.scene.model, self.scene.data, self.scene
        got = self.steps
        got["time_s"].append(float(d.time))
        got["stage"].append(stage)
        got["ctrl"].append(d.ctrl[s.hand_act].copy())
        got["base_target_pos"].append(d.mocap_pos[s.mocap_id].copy())
        got["base_target_quat"].append(d.mocap_quat[s.mocap_id].copy())
        got["gravity"].append(m.opt.gravity.copy())
        got["object_force"].append(d.xfrc_applied[s.obj_body, :3].copy())
        got["pin_pose"].append(np.full(7, np.nan) if pin is None else np.concatenate(pin))

    def arrays(self) -> tuple[dict[str, np.ndarray], dict[str, np.ndarray]]:
        s = self.scene
        widths = {"ctrl": len(s.hand_act), "base_target_pos": 3, "base_target_quat": 4,
                  "gravity": 3, "object_force": 3, "pin_pose": 7}
        steps = {k: (np.array(v, dtype=float).reshape(-1, widths[k]) if k in widths
                     else np.array(v, dtype=str if k == "stage" else float))
                 for k, v in self.steps.items()}
        if self.frames:
            steps["frames"], steps["frame_rows"] = np.array(self.frames), np.array(self.frame_rows)
        return steps, {k: np.array(v) for k, v in self.rows.items()}


def _framed_camera(scene: Scene, tips: np.ndarray, rise_m: float) -> mujoco.MjvCamera:
    """A free camera from (:data:`VIEW_AZIMUTH_DEG`, :data:`VIEW_ELEVATION_DEG`) that holds the
    object, the palm and the fingertips as they are now and ``rise_m`` (m) higher in view,
    with a margin (:func:`sim.world.render.frame_points` at the model's field of view)."""
    d = scene.data
    now = np.vstack([d.xpos[tips], d.xpos[scene.palm_body], scene.object_pose()[0]])
    points = np.vstack([now, now + np.array([0.0, 0.0, rise_m])])
    lookat, distance_m = frame_points(points, fovy_deg=float(scene.model.vis.global_.fovy))
    cam = mujoco.MjvCamera()
    cam.type = mujoco.mjtCamera.mjCAMERA_FREE
    cam.lookat[:] = lookat
    cam.distance, cam.azimuth, cam.elevation = distance_m, VIEW_AZIMUTH_DEG, VIEW_ELEVATION_DEG
    return cam


def rollout(validator: Validator, grasp: Grasp, *, index: int = 0,
            camera: tuple[int, int] | None = None, camera_every: int = 1,
            approach_m: float = 0.0, approach_s: float = 0.5) -> Episode:
    """``grasp`` validated by lift-drop on ``validator``'s scene, every step recorded
    (module docstring); ``index``: its row in the caller's list; ``camera``: (height, width)
    of RGB images (uint8) of the hand and object (``_Recorder``), one every ``camera_every``
    state rows (``Episode.frames``; needs offscreen rendering, ``MUJOCO_GL``; about 5 ms a
    small frame with software EGL).

    ``approach_m`` > 0 starts the episode with the hand that far out along its palm normal,
    moving in to the placed grasp over ``approach_s`` (stage ``approach``,
    :mod:`sim.episodes.approach`); the protocol then runs from where the approach left the
    hand, so the verdict is the protocol's on that run (it agreed with the validator's on
    every grasp of ``benchmarks/bench_episodes.py``). An approach on which the hand touches
    the object is dropped (``Episode.approach_m`` 0) and the episode starts at the pregrasp."""
    if camera_every < 1:
        raise ValueError(f"camera_every: expected ≥ 1 state rows, got {camera_every}")
    result, program = validator.start(grasp, PROTOCOL)
    scene = validator.scene(PROTOCOL)
    if camera is None:
        return _record(validator, scene, result, program, index, None, 1, approach_m, approach_s)
    with mujoco.Renderer(scene.model, *camera) as renderer:
        return _record(validator, scene, result, program, index, renderer, camera_every,
                       approach_m, approach_s)


def _approached(scene: Scene, rec: _Recorder, distance_m: float, duration_s: float) -> bool:
    """Record the approach (:mod:`sim.episodes.approach`) into ``rec``; False (the scene's
    state then undefined) when the hand touched the object on the way."""
    d = scene.data
    path = approach_path(scene, distance_m, duration_s, APPROACH_SETTLE_S)
    back_off(scene, distance_m)
    rec.restart()
    for target in path:
        d.mocap_pos[scene.mocap_id] = target
        rec.action("approach", None)
        mujoco.mj_step(scene.model, d)
        rec.state()
        if touching(scene):
            return False
    return True


def _record(validator: Validator, scene: Scene, result: ValidationResult,
            program: Program | None, index: int, renderer: mujoco.Renderer | None,
            camera_every: int, approach_m: float, approach_s: float) -> Episode:
    """Carry out the approach (when asked) and ``program`` on ``scene`` step by step and make
    the episode of them."""
    m, d = scene.model, scene.data
    placed, gravity0 = save_state(scene), m.opt.gravity.copy()
    rec = _Recorder(scene, renderer, camera_every, validator.config.lift_drop.lift_height_m)
    if program is None or approach_m <= 0.0:
        approach_m = 0.0
    elif not _approached(scene, rec, approach_m, approach_s):
        log.info("grasp %d: the hand touches the object on its %.3f m approach; the episode "
                 "starts at the pregrasp", index, approach_m)
        approach_m = 0.0
        mujoco.mj_setState(m, d, placed, STATE_SPEC)
        mujoco.mj_forward(m, d)
        rec.restart()
    initial = rec.initial
    cursor = ProgramCursor(scene, program)
    seen, stage = 0, ""
    while (req := cursor.request) is not None:
        if cursor.n_requests != seen:
            seen, stage = cursor.n_requests, stage_of(req, result)
        cursor.before_step()
        rec.action(stage, req.pin)
        mujoco.mj_step(m, d)
        cursor.after_step()
        rec.state()
    steps, states = rec.arrays()
    hand = validator.hand
    names = tuple(m.actuator(int(a)).name for a in scene.hand_act)
    return Episode(hand=hand.name, object=validator.obj.name, protocol=PROTOCOL,
                   grasp_index=index, success=bool(result.passed),
                   failure=None if result.failure is None else str(result.failure),
                   timestep_s=float(m.opt.timestep),
                   joint_names=tuple(hand.joint_names[i] for i in scene.hand_joint_kept),
                   actuator_names=names,
                   finger_names=tuple(f.name for f in hand.config.fingers),
                   initial_state=initial, initial_gravity=gravity0, states=states,
                   result=result.summary(), approach_m=approach_m, **steps)


def rollout_all(validator: Validator, grasps: Sequence[Grasp],
                progress: Callable[[int], None] | None = None) -> EpisodeSet:
    """Every grasp of ``grasps`` rolled out (:func:`rollout`), the failed ones kept apart;
    ``progress(n_done)`` after each."""
    out = EpisodeSet()
    for i, g in enumerate(grasps):
        out.add(rollout(validator, g, index=i))
        if progress is not None:
            progress(i + 1)
    log.info("rolled out %d grasps: %d succeeded, failures %s", len(grasps), len(out.succeeded),
             out.failure_counts())
    return out
