"""A real recorder process killed with SIGKILL mid-session, for the tests that read or repair
what such a kill leaves (``test_recorder``, ``test_recording_repair``)."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

from tests.conftest import SOON_S

REPO = Path(__file__).resolve().parents[1]

#: records /hands and /state at 200 Hz to argv[1]; before each frame it prints "frames-started
#: frames-flushed" (a kill can land inside a write whose flush already reached the disk, so the
#: frame under way counts as started); argv[2], when given, is the flush interval in seconds
_CHILD = textwrap.dedent("""
    import sys, time
    import numpy as np
    from teleop.messages import HandFrame, HandState, NUM_JOINTS
    from teleop.record.recorder import SessionRecorder

    extra = {"flush_interval_s": float(sys.argv[2])} if len(sys.argv) > 2 else {}
    rec = SessionRecorder(sys.argv[1], metadata={"hand": "shadow_right",
                                                 "joint_names": [f"j{i}" for i in range(24)]},
                          **extra)
    q = np.tile([1.0, 0.0, 0.0, 0.0], (NUM_JOINTS, 1))
    hand = HandState(np.zeros((NUM_JOINTS, 3)), q, np.full(NUM_JOINTS, 0.01),
                     np.ones(NUM_JOINTS, bool))
    i, t_next = 0, time.monotonic()
    while True:
        print(i + 1, rec.stats.flushed["/hands"], flush=True)
        rec.write_hands(HandFrame(i, i / 200, i / 200, [0.0, 0.0, 1.6], [1.0, 0.0, 0.0, 0.0],
                                  right=hand, source="child"))
        rec.write_state(np.full(24, 0.01 * i), [0, 0, 1], [1, 0, 0, 0], [0.5, 0, 0.8],
                        [1, 0, 0, 0], seq=i)
        i += 1
        t_next += 0.005
        time.sleep(max(0.0, t_next - time.monotonic()))
""")


def record_then_kill(path: Path, run_s: float | None = None,
                     flush_interval_s: float | None = None, *, frames: int | None = None
                     ) -> tuple[int, int]:
    """Record to ``path`` in a child process for ``run_s`` seconds after its first frame, or
    (``frames``) until it reports that many frames started — an event, however slowly a loaded
    machine runs it — kill it with SIGKILL, and return (frames started, frames flushed) as it
    last reported them: the file holds at least the flushed frames and at most the started
    ones."""
    args = [sys.executable, "-c", _CHILD, str(path)]
    if flush_interval_s is not None:
        args.append(str(flush_interval_s))
    child = subprocess.Popen(args, cwd=REPO, env={**os.environ, "PYTHONPATH": str(REPO)},
                             stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        first = line = child.stdout.readline()   # the recording has started
        assert first, child.stderr.read()
        if frames is None:
            time.sleep(run_s)
        while frames is not None and int(line.split()[0]) < frames:
            line = child.stdout.readline()
            assert line, child.stderr.read()
            first += line
    finally:
        child.send_signal(signal.SIGKILL)
        out, _ = child.communicate(timeout=SOON_S)   # SIGKILL: gone, its pipe at EOF
    assert child.returncode == -signal.SIGKILL
    lines = [ln.split() for ln in (first + out).splitlines() if len(ln.split()) == 2]
    started, flushed = map(int, lines[-1])
    return started, flushed
