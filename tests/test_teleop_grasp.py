"""Teleop a person can grasp with (teleop.bridge.grasp_assist, teleop.retarget.snap's press, the
bridge's servo gains, teleop.synthetic.preshape).

- the press of the grasp assist: snapped targets go behind the surface, the mapping stays
  continuous and monotonic, and fingers outside the snap range never move for it;
- the assist and the cue as state machines on the simulation's clock;
- the bridge's servos are what its config says, read back from the compiled model;
- the synthetic operator reaches as a person does: fingers off the table it sees (the old
  reach went 2.7 cm into it) and thumb and fingers touching together;
- closed loop at natural speed (0.3 s closure, lift 0.15 s later) through the real bridge in
  free mode: the assist engages, the cue turns stable, and the apple is lifted — and with the
  apple 6 cm from where the hand closes, none of that happens.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

from teleop.bridge.grasp_assist import AssistSettings, GraspAssist, GraspCue
from teleop.retarget.snap import snap_distances
from tests.conftest import needs_menagerie, needs_ycb

pytestmark = pytest.mark.slow

# --- press -----------------------------------------------------------------------------------


def test_press_goes_behind_the_surface_and_stays_smooth() -> None:
    snap, press = 0.015, 0.01
    d = np.linspace(-0.02, 0.03, 5001)
    f0, fp = snap_distances(d, snap), snap_distances(d, snap, press)
    assert np.allclose(fp[d <= snap / 2], -press)             # the inner half: pressed in
    assert np.allclose(fp[d >= snap], d[d >= snap])           # outside snap range: untouched
    assert np.allclose(f0[d <= snap / 2], 0.0)                # no press: onto the surface
    assert (np.diff(fp) >= -1e-12).all()                      # monotonic: closing moves closer
    assert np.abs(np.diff(fp)).max() < 3 * (d[1] - d[0]) * 25 / 9   # no jump anywhere
    per_finger = snap_distances(np.array([0.0, 0.0]), snap, np.array([0.0, press]))
    assert per_finger.tolist() == pytest.approx([0.0, -press])


def _plane_surface():
    """A flat 20 cm square at z = 0, normal +z, sampled every 2 mm."""
    from teleop.retarget.surface import ObjectSurface

    g = np.linspace(-0.1, 0.1, 101)
    xy = np.array(np.meshgrid(g, g)).reshape(2, -1).T
    pts = np.column_stack([xy, np.zeros(len(xy))])
    return ObjectSurface(pts, np.tile([0.0, 0.0, 1.0], (len(pts), 1)))


def test_the_operators_pad_pulls_its_robot_target_onto_the_object() -> None:
    """A robot target the scaling left 12 mm off the surface while the person's own pad is 5 mm
    from it goes onto it, the touch depth in; with the person's pad 30 mm away, or the robot
    finger 40 mm away (elsewhere), it stays where its own distance puts it; and along a
    closing motion of both, the target only ever moves closer, without a jump."""
    from teleop.retarget.snap import snap_pad_targets

    surface, snap, op_snap, depth = _plane_surface(), 0.015, 0.02, 0.003
    base = (np.zeros(3), np.array([1.0, 0.0, 0.0, 0.0]))

    def snapped_z(target_z: float, pad_z: float) -> float:
        out, _ = snap_pad_targets(surface, np.array([[0.0, 0.0, target_z]]), base, snap,
                                  operator_pads_m=np.array([[0.0, 0.0, pad_z]]),
                                  operator_snap_m=op_snap, operator_depth_m=depth)
        return float(out[0, 2])

    assert snapped_z(0.012, 0.005) == pytest.approx(-depth, abs=1e-6)
    assert snapped_z(0.012, 0.030) == pytest.approx(float(snap_distances(0.012, snap)), abs=1e-9)
    assert snapped_z(0.040, 0.005) == pytest.approx(0.040, abs=1e-9)
    without, _ = snap_pad_targets(surface, np.array([[0.0, 0.0, 0.012]]), base, snap)
    assert without[0, 2] == pytest.approx(float(snap_distances(0.012, snap)), abs=1e-9)
    closing = np.linspace(1.0, 0.0, 2001)
    z = np.array([snapped_z(0.005 + 0.045 * c, 0.045 * c) for c in closing])
    assert (np.diff(z) <= 1e-12).all()                        # monotonic as the hand closes
    assert np.abs(np.diff(z)).max() < 0.001                   # no jump at any threshold


# --- assist and cue --------------------------------------------------------------------------


def test_assist_engages_ramps_and_lets_go() -> None:
    a = GraspAssist(AssistSettings(press_m=0.01, engage_s=0.05, ramp_s=0.1, release_s=0.2))
    assert a.update(0.0, 0.0) == 0.0
    assert a.update(0.02, 0.03) == 0.0 and not a.engaged      # not held long enough yet
    a.update(0.06, 0.06)
    assert a.engaged
    presses = [a.update(0.06 + k * 0.01, 0.1 + k * 0.01) for k in range(1, 15)]
    assert presses[4] == pytest.approx(0.005, abs=1e-9)       # half way after half the ramp
    assert presses[-1] == pytest.approx(0.01)
    assert a.update(0.30, 0.0) == pytest.approx(0.01)         # the grasp gone: not yet
    a.update(0.52, 0.0)
    assert not a.engaged
    assert a.update(0.70, 0.0) == 0.0
    off = GraspAssist(AssistSettings(press_m=0.0))
    assert off.update(1.0, 5.0) == 0.0


def test_cue_follows_the_demo_rule_and_forgives_short_gaps() -> None:
    cue = GraspCue("thumb")
    assert cue.update(0.0, {"forefinger"}) == (False, 0.0)    # no thumb: no grasp
    assert cue.update(0.1, {"thumb", "forefinger"})[1] == 0.0
    assert cue.update(0.2, {"thumb", "forefinger"}) == (False, pytest.approx(0.1))
    assert cue.update(0.3, set()) == (False, pytest.approx(0.1))   # a 0.1 s gap: not counted
    assert cue.update(0.35, {"thumb", "ring"}) == (False, pytest.approx(0.1))   # nor ended
    stable, held = cue.update(0.5, {"thumb", "middle"})
    assert not stable and held == pytest.approx(0.25)
    stable, held = cue.update(0.6, {"thumb", "middle"})
    assert stable and held == pytest.approx(0.35)
    assert cue.grasp_s == pytest.approx(0.5)   # what the assist engages on: since it began
    assert cue.update(1.0, set()) == (False, 0.0)             # gone longer than max_gap_s


def test_a_flickering_touch_is_not_a_stable_grasp() -> None:
    """Thumb and finger in contact 0.03 s of every 0.23 s for 1.5 s (a touch that flickers,
    never a grasp): the cue must not call it stable, nor the assist engage for long — counted
    through the gaps (the old rule) it read 1.4 s held and "stable" at 0.3 s."""
    cue, dt = GraspCue("thumb"), 0.004
    held_max, stable_any = 0.0, False
    for k in range(int(1.5 / dt)):
        t = k * dt
        touching = {"thumb", "forefinger"} if (t % 0.23) < 0.03 else set()
        stable, held = cue.update(t, touching)
        stable_any |= stable
        held_max = max(held_max, held)
    assert not stable_any
    assert held_max < 0.3, held_max
    steady = GraspCue("thumb")
    n = int(0.31 / dt)
    results = [steady.update(k * dt, {"thumb", "middle"}) for k in range(n + 1)]
    assert results[-1][0] and results[-1][1] == pytest.approx(n * dt)   # every step counted


# --- the bridge's servos ---------------------------------------------------------------------


@needs_menagerie
def test_bridge_servos_are_the_configured_gain(shadow, tmp_path: Path) -> None:
    from sim.world.scene import Scene
    from teleop.bridge.config import load_bridge_config

    cfg = load_bridge_config()
    assert cfg.servos.kp_scale == 5.0
    scene = Scene(shadow, None, servos=cfg.servos)
    own = Scene(shadow, None)
    acts = scene.hand_act
    kp, kp0 = scene.model.actuator_gainprm[acts, 0], own.model.actuator_gainprm[acts, 0]
    assert np.allclose(kp, 5.0 * kp0) and np.allclose(scene.model.actuator_biasprm[acts, 1],
                                                      -5.0 * kp0)
    bad = tmp_path / "teleop.toml"
    bad.write_text("[bridge]\nservo_kp_scale = -1\nassist_press_m = 0.01\n")
    from sim.errors import ConfigError
    with pytest.raises(ConfigError, match="servo_kp_scale"):
        load_bridge_config(bad)


# --- the synthetic operator's reach ----------------------------------------------------------


def _tip_heights_and_touch(ep, obj: str):
    """Per tracked frame up to the grasp: lowest hand joint above the table (minus radius) and,
    per finger, the first time its pad is within 3 mm of the object."""
    from sim.transforms import quat_to_mat
    from sim.world.objects import load_object
    from teleop.messages import FINGERTIPS
    from teleop.synthetic.surface import surface_distance_m

    mesh = load_object(obj).surface_mesh()
    rot = quat_to_mat(ep.object_quat_wxyz)
    table_z = float(ep.object_pos_m[2] + (np.asarray(mesh.vertices) @ rot.T)[:, 2].min())
    low, first = [], {}
    for f in ep.frames:
        h = f.right
        if h is None or not h.tracked or f.device_time_s > ep.grasp_time_s:
            continue
        low.append(float((h.positions[:, 2] - h.radii).min() - table_z))
        tips = h.positions[list(FINGERTIPS)]
        dist = surface_distance_m(mesh, (tips - ep.object_pos_m) @ rot) - h.radii[list(FINGERTIPS)]
        for k in np.flatnonzero(dist < 0.003):
            first.setdefault(int(k), f.device_time_s)
    return np.array(low), first


@needs_menagerie
@needs_ycb
def test_the_operator_keeps_off_the_table_and_closes_together(shadow, monkeypatch) -> None:
    import teleop.synthetic.episode as episode_mod
    from teleop.synthetic.config import SynthConfig
    from teleop.synthetic.episode import GraspMotion
    from teleop.synthetic.synthesize import synthesize

    quiet = SynthConfig(position_noise_m=0.0, orientation_noise_deg=0.0, dropout_fraction=0.0,
                        close_s=0.3, settle_s=0.15)
    can = "005_tomato_soup_can"   # its reference grasp points the fingers down at the table
    ep = synthesize(can, hand=shadow, seed=0, config=quiet)
    low, _ = _tip_heights_and_touch(ep, can)
    assert low.min() > -0.002, f"a finger {-low.min() * 1e3:.1f} mm into the table"
    plan = GraspMotion.plan
    try:   # the old reach: relaxed open hand along the palm normal (no human, no obstacles)
        GraspMotion.plan = classmethod(lambda cls, *a, human=None, obstacles=None,
                                       pressed=False: plan.__func__(cls, *a))
        old = synthesize(can, hand=shadow, seed=0, config=quiet)
    finally:
        GraspMotion.plan = plan
    low_old, _ = _tip_heights_and_touch(old, can)
    assert low_old.min() < -0.02              # the check can fail: the old reach went into it

    apple = "013_apple"           # a generic grasp of all five fingers
    ep = synthesize(apple, hand=shadow, seed=0, config=quiet)
    _, first = _tip_heights_and_touch(ep, apple)
    assert len(first) >= 4, first
    spread = max(first.values()) - min(first.values())
    assert spread <= 0.06, f"fingers touched {spread:.3f} s apart"
    monkeypatch.setattr(episode_mod, "contact_progress", lambda *a, **k: {})   # no synchrony
    _, first_old = _tip_heights_and_touch(synthesize(apple, hand=shadow, seed=0, config=quiet),
                                          apple)
    assert max(first_old.values()) - min(first_old.values()) > 2 * spread + 0.02, first_old


# --- closed loop at natural speed ------------------------------------------------------------


def _lifted_m(path: Path, ep) -> tuple[float, dict]:
    """How high the object is over the hold phase (median, metres above where it rested) and
    what the grasp cue and assist did."""
    from teleop.record.session import open_session

    s = open_session(path)
    states = [m for _, m in s.json_messages("/state")]
    # the operator's clock: each state names the frame (seq) it answers; simulated time runs
    # at steps_per_frame × timestep per frame, not the frames' pace
    device_s = {f.seq: f.device_time_s for f in ep.frames}
    t = np.array([device_s.get(m["seq"], np.nan) for m in states])
    z = np.array([m["object_pos_m"][2] for m in states])
    hold = (t >= ep.phases["hold"][0]) & (t <= ep.phases["hold"][1])
    extra = [m["extra"] for m in states]
    return float(np.median(z[hold]) - np.median(z[t < ep.phases["approach"][0]])), {
        "assist": max(e.get("assist", 0.0) for e in extra),
        "stable": any(e.get("grasp_stable") for e in extra)}


@needs_menagerie
@needs_ycb
def test_natural_speed_grasp_lifts_and_the_assist_engages(shadow, tmp_path: Path) -> None:
    import teleop.bridge.rerecord as rerecord_mod
    from teleop.synthetic.config import load_synth_config
    from teleop.synthetic.synthesize import synthesize
    from teleop.synthetic.writer import write_session

    cfg = dataclasses.replace(load_synth_config(), close_s=0.3, settle_s=0.15,
                              object_pos_m=(0.477, -0.036, 0.8), object_rpy_deg=(0.0, 0.0, 1.0))
    # four operator seeds, not one: in three of them the reaching little finger tips the free
    # apple 2-3 cm up before the closure, so any single episode is a coin toss (seed 1 lifted
    # before the operator-pad snap and not after; seeds 0 and 2 the other way round); the
    # retargeter before the operator-pad snap lifted 2 of these 4
    lifted = []
    for seed in range(4):
        ep = synthesize("013_apple", hand=shadow, seed=seed, config=cfg)
        raw = write_session(ep, tmp_path / f"raw{seed}.mcap")
        full = rerecord_mod.rerecord(raw, tmp_path / f"free{seed}.mcap", object_mode="free")
        lift, grasp = _lifted_m(full, ep)
        if lift > 0.6 * cfg.lift_height_m:
            lifted.append(grasp)
    assert len(lifted) >= 3, lifted
    assert all(g["assist"] == pytest.approx(1.0) for g in lifted), lifted
    assert any(g["stable"] for g in lifted), lifted

    # the check can fail: the same hand with the apple 6 cm away from where it reaches
    elsewhere = dataclasses.replace(ep, metadata={**ep.metadata, "object_pos_m": [
        ep.object_pos_m[0] + 0.06, *ep.object_pos_m[1:]]})
    raw = write_session(elsewhere, tmp_path / "raw_elsewhere.mcap")
    full = rerecord_mod.rerecord(raw, tmp_path / "missed.mcap", object_mode="free")
    lift_missed, grasp_missed = _lifted_m(full, ep)
    assert lift_missed < 0.02 and not grasp_missed["stable"], (lift_missed, grasp_missed)
