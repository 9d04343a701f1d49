"""The main job's teleop half, headset-free: a synthetic operator's session of the default
object, recorded through the real bridge, and the demo extracted from that recording.

``dexaug demo`` (no ``--session``) runs it, then augments the demo it returns: one chain from a
teleop recording to a dataset. Each stage reports one line through ``say``.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from sim.demo import Demo, DemoError

#: the object of the embedded default, and its seed. The screwdriver, not the soup can: the
#: synthetic operator's can and sugar-box sessions record as 5- and 4-finger wraps with the
#: object 8–13 mm from the palm box, where FSG rejects 92 % of its candidates at the palm and
#: finds no grasp in 40 s (measured 2026-12-06); the screwdriver's is a thumb–two-finger grasp
#: that augments (9 of 10 passed lift-drop)
DEMO_OBJECT = "043_phillips_screwdriver"
DEMO_SEED = 0


def session_name(object_name: str = DEMO_OBJECT) -> str:
    """The synthetic operator's raw session, in the output folder."""
    return f"synth_{object_name}.mcap"


def recording_name(object_name: str = DEMO_OBJECT) -> str:
    """The bridge's recording of that session, in the output folder (the demo's source)."""
    return f"demo_{object_name}.mcap"


@dataclass(frozen=True)
class ChainDemo:
    """What the teleop half made: the raw session, the bridge's recording (its topic counts)
    and the demo extracted from the recording (the first, when it holds several)."""

    session: Path
    recording: Path
    counts: dict[str, int]
    demo: Demo


def record_demo(folder: Path, hand: str, *, object_name: str = DEMO_OBJECT,
                seed: int = DEMO_SEED, say: Callable[[str], None] = print) -> ChainDemo:
    """Synthesize a session of ``object_name`` for ``hand`` (seed ``seed``) into ``folder``,
    record it through the bridge (object in demo mode), extract its demo; files in ``folder``
    of an earlier run are replaced.

    Raises:
        sim.demo.DemoError: the recording holds no usable grasp.
        DexaugError subclasses: the object or hand is not installed, the bridge failed.
    """
    from teleop.bridge.rerecord import rerecord
    from teleop.record.demos import extract_demos
    from teleop.record.session import open_session
    from teleop.synthetic.synthesize import synthesize
    from teleop.synthetic.writer import write_session

    start = time.perf_counter()
    episode = synthesize(object_name, hand=hand, seed=seed)
    session = write_session(episode, folder / session_name(object_name), overwrite=True)
    say(f"1. session:   {session} — synthetic operator, {len(episode.frames)} hand frames "
        f"({int(episode.tracked.sum())} tracked), seed {seed}, imitating "
        f"{episode.reference_grasp or 'a generic side grasp'} "
        f"({time.perf_counter() - start:.1f} s)")
    start = time.perf_counter()
    recording = rerecord(session, folder / recording_name(object_name), object_mode="demo")
    counts = dict(open_session(recording).counts)
    say(f"2. recording: {recording} — through the bridge: {counts.get('/hands', 0)} hand frames "
        f"→ {counts.get('/state', 0)} states, {counts.get('/contacts', 0)} contact records "
        f"({time.perf_counter() - start:.1f} s)")
    demos = extract_demos(recording)
    if not demos:   # extract_demos raises with the reason; never silently nothing
        raise DemoError(f"{recording}: no demo extracted")
    demo = demos[0]
    more = f" (first of {len(demos)})" if len(demos) > 1 else ""
    flags = f", flagged: {'; '.join(demo.flags)}" if demo.flags else ""
    say(f"3. demo:      {demo.id}{more} — fingers {', '.join(demo.fingers)}, by {demo.how}, "
        f"held {demo.duration_s:.2f} s{flags}")
    return ChainDemo(session, recording, counts, demo)
